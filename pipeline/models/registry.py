"""Registry of candidate models: name in ``params.yaml`` -> scikit-learn estimator class.

Every entry is a scikit-learn estimator taking X, a DataFrame of shape (n, m) of temperature
rises (K) indexed by (``campaign_id``, ``elapsed_s``), and y of shape (n,), the thermal error
(um); see :mod:`pipeline.models.series` for the time-series conventions. Entries flagged
``needs_error_feedback`` also use the measured error's own history
(:mod:`pipeline.models.feedback`). One parametrised test runs the same contract over every entry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sklearn.base import RegressorMixin
from sklearn.linear_model import LinearRegression

from pipeline.models.ar_reduced import ReducedOrderAR
from pipeline.models.ardl import AutoregressiveDistributedLag
from pipeline.models.arma import ARMAErrorModel
from pipeline.models.distributed_lag import DistributedLagRegressor
from pipeline.models.neural import BackPropagationRegressor
from pipeline.models.pcdl import PrincipalComponentDistributedLag
from pipeline.models.penalised_dl import PLSDistributedLag, RidgeDistributedLag, RidgeRegression
from pipeline.models.reference import NoCompensation
from pipeline.models.svr import EmbeddedSVR
from pipeline.models.ts_bp import TimeSeriesBPHybrid
from pipeline.models.tv_ar import TimeVaryingAR


@dataclass(frozen=True)
class ModelEntry:
    """A registered model.

    Attributes
    ----------
    estimator : type
        scikit-learn estimator class; ``estimator(**params)`` is unfitted.
    uses_temperatures : bool
        False for models on the error series alone and for ``none`` (they run on selection
        ``none``).
    source : str
        Where the method comes from.
    """

    estimator: type
    uses_temperatures: bool
    source: str


MODELS: dict[str, ModelEntry] = {
    "none": ModelEntry(NoCompensation, False, "no compensation: the reference of every score"),
    "mlr": ModelEntry(LinearRegression, True, "the patent (step 4), the PCDL paper's baseline"),
    "dl": ModelEntry(DistributedLagRegressor, True, "the PCDL paper, eq. 1"),
    "pcdl": ModelEntry(PrincipalComponentDistributedLag, True, "the PCDL paper, section 2.2"),
    "ridge": ModelEntry(RidgeRegression, True, "ridge regression, no lags (PCDL paper 2.2)"),
    "ridge_dl": ModelEntry(RidgeDistributedLag, True, "the PCDL paper, section 2.2 (ridge)"),
    "pls_dl": ModelEntry(PLSDistributedLag, True, "the PCDL paper, section 2.2 (other)"),
    "bp": ModelEntry(BackPropagationRegressor, True, "the TS-BP paper, BP network"),
    "adl": ModelEntry(AutoregressiveDistributedLag, True, "the PCDL paper, refs 5-6 (ADL)"),
    "arma": ModelEntry(ARMAErrorModel, False, "the TS-BP paper, ARMA(4,3)"),
    "ar_reduced": ModelEntry(ReducedOrderAR, False, "the AR paper, AR(64) -> AR(9)"),
    "tv_ar": ModelEntry(TimeVaryingAR, False, "the AR paper, time-varying parameters"),
    "svr": ModelEntry(EmbeddedSVR, False, "the SVR paper"),
    "ts_bp": ModelEntry(TimeSeriesBPHybrid, True, "the TS-BP paper, hybrid"),
}


def make_model(name: str, **params: Any) -> RegressorMixin:
    """Return a new unfitted estimator registered under ``name``.

    Raises
    ------
    KeyError
        If no model has that name; the message lists the registered ones.
    TypeError
        If a hyper-parameter is not one of the estimator's, naming it.
    """
    if name not in MODELS:
        raise KeyError(
            f"unknown model '{name}' in params.yaml evaluate; registered: {sorted(MODELS)}"
        )
    estimator = MODELS[name].estimator
    valid = estimator().get_params()
    unknown = sorted(set(params) - set(valid))
    if unknown:
        raise TypeError(
            f"params.yaml evaluate.model_params.{name}: unknown hyper-parameter(s) {unknown}; "
            f"{name} accepts {sorted(valid)}"
        )
    return estimator(**params)

"""TS-BP hybrid: fixed-weight combination of an ARMA error model and a BP network.

Source: Li Xingda, Gu Qunying, Li Zihan and Yang Jianguo, "Modeling for thermal error based on
time series-neural network", Modular Machine Tool & Automatic Manufacturing Technique 2015(9),
13-16 (section 1.3, equations 10-13)::

    y_hat_t = k_TS * y_TS,t + k_BP * y_BP,t,   k_TS + k_BP = 1, 0 <= k <= 1

The time-series (TS) module predicts from the error's own history
(:class:`pipeline.models.arma.ARMAErrorModel`), the BP module from the temperatures
(:class:`pipeline.models.neural.BackPropagationRegressor`, 6 sigmoid hidden neurons, rate
0.01, at most 6000 epochs). The weights do not change with time (the paper's fixed-weight
model) and come from each sub-model's prediction validity on the training data. The capture
lost equations 11-13; their standard form, as the text describes them:

    A_t = 1 - |(y_t - y_hat_t) / y_t|, clipped to [0, 1]   (relative precision at t, eq. 11)
    S = mean(A) * (1 - std(A))                             (prediction validity, eq. 12)
    k_i = S_i / (S_TS + S_BP)                              (normalised weights, eq. 13)

Guards the paper does not need (its error never passes through 0): the thermal error is 0 at
each cold start, where A_t is undefined, so samples with |y_t| below ``min_level_fraction`` of
the largest training |y| are left out of A; std is the population standard deviation; if both
validities are 0 the weights are 1/2 each. The TS module's validity is taken from its
one-step-ahead predictions with the measured history (how the paper's TS module predicts); at
prediction time the TS module runs one-step-ahead when ``y_history`` is given, otherwise in
free run, with the same fixed weights.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from pipeline.models.arma import ARMAErrorModel
from pipeline.models.base import FeedbackModel
from pipeline.models.neural import BackPropagationRegressor

logger = logging.getLogger(__name__)


def relative_precision(
    y: np.ndarray, y_hat: np.ndarray, min_level_fraction: float = 0.05
) -> np.ndarray:
    """A_t = 1 - |(y_t - y_hat_t) / y_t| clipped to [0, 1], where |y_t| is large enough.

    Parameters
    ----------
    y, y_hat : numpy.ndarray of shape (n,)
        Measured and predicted thermal error (um).
    min_level_fraction : float, default 0.05
        Samples with |y_t| < this fraction of max |y| are left out (A undefined near 0).

    Returns
    -------
    numpy.ndarray of shape (k,)
        A_t of the k samples kept (dimensionless).

    Raises
    ------
    ValueError
        If the measured error is 0 everywhere (no sample has a defined precision).
    """
    measured = np.asarray(y, dtype=float)
    level = np.max(np.abs(measured)) if len(measured) else 0.0
    if level <= 0.0:
        raise ValueError(
            "the measured thermal error is 0 at every sample, so the relative precision of "
            "the sub-models is undefined; check the error column"
        )
    keep = np.abs(measured) >= min_level_fraction * level
    ratio = (measured[keep] - np.asarray(y_hat, dtype=float)[keep]) / measured[keep]
    return np.clip(1.0 - np.abs(ratio), 0.0, 1.0)


def prediction_validity(precision: np.ndarray) -> float:
    """S = mean(A) * (1 - std(A)) of a relative-precision series (the paper's eq. 12)."""
    return float(np.mean(precision) * (1.0 - np.std(precision)))


def hybrid_weights(validity_ts: float, validity_bp: float) -> tuple[float, float]:
    """(k_TS, k_BP) = validities normalised to sum 1; 1/2 each if both are 0."""
    total = validity_ts + validity_bp
    if total <= 0.0:
        logger.warning("both TS-BP sub-models have validity 0; weighting them equally")
        return 0.5, 0.5
    return validity_ts / total, validity_bp / total


class TimeSeriesBPHybrid(FeedbackModel):
    """Fixed-weight TS-BP hybrid of the TS-BP paper.

    Parameters
    ----------
    max_p, max_q : int, default 6, 4
        Largest ARMA orders of the TS module.
    ic : {"bic", "aic"}, default "bic"
        Criterion fixing the ARMA order.
    hidden_units : int, default 6
        Hidden sigmoid neurons of the BP module.
    learning_rate : float, default 0.01
        BP gradient-descent rate.
    max_epochs : int, default 6000
        Most BP training epochs.
    random_state : int or None, default 0
        Seed of the BP module's initial weights.
    min_level_fraction : float, default 0.05
        Samples with |y| below this fraction of the largest training |y| are left out of the
        relative precision.

    Attributes
    ----------
    ts_ : ARMAErrorModel
        Fitted TS module.
    bp_ : BackPropagationRegressor
        Fitted BP module.
    k_ts_, k_bp_ : float
        Weights (sum 1).
    validity_ts_, validity_bp_ : float
        Prediction validities S on the training data.
    chosen_params_ : dict
        k_TS, k_BP, validity_TS, validity_BP, arma_p, arma_d, arma_q, bp_epochs.
    """

    def __init__(
        self,
        max_p: int = 6,
        max_q: int = 4,
        ic: str = "bic",
        hidden_units: int = 6,
        learning_rate: float = 0.01,
        max_epochs: int = 6000,
        random_state: int | None = 0,
        min_level_fraction: float = 0.05,
    ):
        self.max_p = max_p
        self.max_q = max_q
        self.ic = ic
        self.hidden_units = hidden_units
        self.learning_rate = learning_rate
        self.max_epochs = max_epochs
        self.random_state = random_state
        self.min_level_fraction = min_level_fraction

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Fit both modules and fix their weights from their validity on the training data."""
        self.ts_ = ARMAErrorModel(max_p=self.max_p, max_q=self.max_q, ic=self.ic).fit(X, target)
        self.bp_ = BackPropagationRegressor(
            hidden_units=self.hidden_units,
            learning_rate=self.learning_rate,
            max_epochs=self.max_epochs,
            random_state=self.random_state,
        ).fit(X, target)
        ts_fit = self.ts_.predict(X, y_history=target)
        bp_fit = self.bp_.predict(X)
        self.validity_ts_ = prediction_validity(
            relative_precision(target, ts_fit, self.min_level_fraction)
        )
        self.validity_bp_ = prediction_validity(
            relative_precision(target, bp_fit, self.min_level_fraction)
        )
        self.k_ts_, self.k_bp_ = hybrid_weights(self.validity_ts_, self.validity_bp_)
        p, d, q = self.ts_.order_
        self.chosen_params_ = {
            "k_TS": self.k_ts_,
            "k_BP": self.k_bp_,
            "validity_TS": self.validity_ts_,
            "validity_BP": self.validity_bp_,
            "arma_p": p,
            "arma_d": d,
            "arma_q": q,
            "bp_epochs": int(self.bp_.n_epochs_),
        }
        logger.debug("TS-BP weights k_TS = %.3f, k_BP = %.3f", self.k_ts_, self.k_bp_)

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """k_TS * y_TS + k_BP * y_BP; TS one-step-ahead on ``measured``, else in free run."""
        return self.k_ts_ * self.ts_.predict(X, measured) + self.k_bp_ * self.bp_.predict(X)

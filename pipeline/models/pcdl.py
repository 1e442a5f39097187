"""Principal-component distributed lag (PCDL): the DL design regressed on leading PCs.

Source: the PCDL paper (Miao Enming, Liu Yi, Dong Yunfei and Chen Weikang, 2016, "Improvement of
forecasting robustness of time series model for thermal error on CNC machine tool", Optics and
Precision Engineering 24(10), 2480-2489), sections 2.2-2.3 and 4.2. Its equations (2)-(5) are
missing from the web capture; the steps its text names are implemented in the standard
principal-component-regression form:

1. build the DL design (current and lagged temperatures, equation (1));
2. standardise it (z-scores) and take the eigenvectors u_1..u_p of the correlation matrix of the
   standardised data X*, ordered by eigenvalue; the components F_k = X* u_k are uncorrelated
   with Var F_1 >= ... >= Var F_p;
3. keep the first m components whose cumulative variance contribution exceeds 85 %;
4. regress y on F_1..F_m by least squares and map the coefficients back to the original
   (unstandardised) lagged temperatures, so the model has the DL form (paper's equation (7)).
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from pipeline.models.distributed_lag import LaggedLinearModel, lag_order
from pipeline.models.series import lagged_values

logger = logging.getLogger(__name__)

_ZERO_VARIANCE = 1e-12


def leading_components(correlation: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Return the leading eigenvectors of a correlation matrix and all variance ratios.

    Parameters
    ----------
    correlation : numpy.ndarray, shape (p, p)
        Correlation matrix of the standardised design.
    threshold : float
        Cumulative variance contribution (0-1) the kept components must exceed (strictly).

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray)
        Eigenvectors of the kept components, shape (p, m), columns in decreasing eigenvalue
        order; variance ratios of all p components, shape (p,), decreasing.
    """
    eigenvalues, eigenvectors = np.linalg.eigh(correlation)
    order = np.argsort(eigenvalues)[::-1]
    eigenvalues = np.clip(eigenvalues[order], 0.0, None)
    ratios = eigenvalues / eigenvalues.sum()
    above = np.flatnonzero(np.cumsum(ratios) > threshold)
    n_keep = int(above[0]) + 1 if len(above) else len(ratios)
    return eigenvectors[:, order[:n_keep]], ratios


class PrincipalComponentDistributedLag(LaggedLinearModel):
    """PCDL: distributed-lag model estimated by principal-component regression (PCDL paper).

    Parameters
    ----------
    lag : int or None, default None
        Lag order (samples). None chooses it by the expedient method on the OLS DL model
        (:func:`pipeline.models.distributed_lag.expedient_lag_order`), as the paper did
        ("the expedient method gives order 2 for the PCDL model"); the t-tests it needs exist
        only for OLS, so the rule is applied to the DL fit, then PCR is run at that order.
    max_lag : int, default 6
        Highest order the expedient search tries.
    variance_threshold : float, default 0.85
        Keep the first m components with cumulative variance contribution above this (0-1).
    alpha_significance : float, default 0.05
        Significance level of the expedient search's t-tests.

    Attributes
    ----------
    components_ : numpy.ndarray, shape (p, m)
        Kept eigenvectors of the correlation matrix (p = non-constant lagged columns).
    explained_variance_ratio_ : numpy.ndarray, shape (p,)
        Variance contribution of every component, decreasing.
    chosen_params_ : dict
        ``lag_order``, ``lag_rule``, ``n_components`` (m) and ``explained_variance`` (cumulative
        contribution of the kept components, 0-1).
    See :class:`pipeline.models.distributed_lag.LaggedLinearModel` for ``coef_`` (mapped back to
    the unstandardised lagged temperatures, um/K) and ``intercept_`` (um). Lagged columns that
    are constant in the training data get coefficient 0 (they carry no information).
    """

    def __init__(
        self,
        lag: int | None = None,
        max_lag: int = 6,
        variance_threshold: float = 0.85,
        alpha_significance: float = 0.05,
    ):
        self.lag = lag
        self.max_lag = max_lag
        self.variance_threshold = variance_threshold
        self.alpha_significance = alpha_significance

    def _check_params(self) -> None:
        """Raise ValueError unless ``variance_threshold`` is in (0, 1)."""
        if not 0.0 < self.variance_threshold < 1.0:
            raise ValueError(f"variance_threshold must be in (0, 1), got {self.variance_threshold}")

    def _fit(self, frame: pd.DataFrame, target: np.ndarray) -> None:
        """Fit the PCDL model.

        Raises
        ------
        ValueError
            If there are fewer than 3 samples, if every lagged column is constant, or
            (lag=None) too few samples for the search.
        """
        if len(target) < 3:
            raise ValueError(
                f"too few samples ({len(target)}) for principal-component regression; "
                "it needs at least 3"
            )
        lag, rule = lag_order(frame, target, self.lag, self.max_lag, self.alpha_significance)
        design = lagged_values(frame, lag)
        mean = design.mean(axis=0)
        scale = design.std(axis=0, ddof=1)
        varying = scale > _ZERO_VARIANCE * np.maximum(1.0, np.abs(mean))
        if not varying.any():
            raise ValueError(
                "every lagged temperature column is constant in the training data; "
                "PCR needs temperatures that change"
            )
        if not varying.all():
            logger.debug("PCDL: %d constant lagged columns get coefficient 0", (~varying).sum())
        standardised = (design[:, varying] - mean[varying]) / scale[varying]
        correlation = standardised.T @ standardised / (len(target) - 1)
        components, ratios = leading_components(correlation, self.variance_threshold)
        scores = standardised @ components
        regressors = np.column_stack([np.ones(len(target)), scores])
        solution = np.linalg.lstsq(regressors, target, rcond=None)[0]
        coef = np.zeros(design.shape[1])
        coef[varying] = components @ solution[1:] / scale[varying]
        intercept = solution[0] - coef @ mean
        self._set_coefficients(list(frame.columns), coef, intercept)
        self.components_ = components
        self.explained_variance_ratio_ = ratios
        n_components = components.shape[1]
        self.chosen_params_ = {
            "lag_order": lag,
            "lag_rule": rule,
            "n_components": n_components,
            "explained_variance": float(ratios[:n_components].sum()),
        }
        logger.debug("PCDL fit: %s", self.chosen_params_)

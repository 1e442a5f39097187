"""Distributed-lag (DL) regression of the thermal error on current and lagged temperatures.

Source: Miao Enming, Liu Yi, Dong Yunfei and Chen Weikang, "Improvement of forecasting robustness of
time series model for thermal error on CNC machine tool", Optics and Precision Engineering 24(10),
2480-2489, 2016 ("the PCDL paper"), section 2.1. Its equation (1) is missing from the web capture;
the standard DL form its text describes is used::

    y_t = a0 + sum_{j=1..u} sum_{i=0..n} b_{j,i} x_{j,t-i}

with ``u`` sensors, maximum lag ``n`` (samples), fitted by ordinary least squares.

This module also holds the pieces the other lagged linear models share: the expedient
lag-order rule and :class:`LaggedLinearModel`, whose prediction is ``lagged(X) @ coef + a0``.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
from statsmodels.regression.linear_model import OLS, RegressionResults
from statsmodels.tools.tools import add_constant

from pipeline.models.base import TemperatureModel
from pipeline.models.series import lagged_values

logger = logging.getLogger(__name__)


def max_feasible_lag(n_samples: int, n_sensors: int) -> int:
    """Return the highest lag order whose OLS fit keeps at least one residual degree of freedom.

    A DL model of order ``n`` on ``m`` sensors has ``1 + m (n + 1)`` coefficients; t-tests need
    ``n_samples > 1 + m (n + 1)``. Returns -1 if even the static model (n = 0) does not fit.
    """
    return (n_samples - 2) // n_sensors - 1


def check_lag_feasible(n_samples: int, n_sensors: int, lag: int) -> None:
    """Raise if ``n_samples`` are too few for an OLS DL fit of order ``lag`` on ``n_sensors``.

    Raises
    ------
    ValueError
        Saying how many samples the order needs and what to lower.
    """
    n_params = 1 + n_sensors * (lag + 1)
    if n_samples <= n_params:
        raise ValueError(
            f"too few samples ({n_samples}) for lag order {lag} with {n_sensors} sensors: "
            f"the DL model has {n_params} coefficients and needs more than {n_params} samples; "
            "lower the lag order or select fewer sensors"
        )


def ols_fit(design: np.ndarray, y: np.ndarray) -> RegressionResults:
    """Fit ``y = a0 + design @ b`` by OLS with statsmodels (classical t-tests).

    Parameters
    ----------
    design : numpy.ndarray, shape (n, p)
        Regressors (lagged temperatures) without a constant column.
    y : numpy.ndarray, shape (n,)
        Thermal error (um).

    Returns
    -------
    statsmodels RegressionResults
        ``params[0]`` is the intercept (um), ``params[1:]`` the slopes (um/K).
    """
    return OLS(y, add_constant(design, has_constant="add")).fit()


def lag_stop_reason(
    sensors: list[str], coef: np.ndarray, new_pvalues: np.ndarray, alpha: float
) -> str | None:
    """Apply the expedient stopping rule to one DL fit of order ``n >= 1``.

    The rule (PCDL paper section 2.1, "when the regression coefficients of the lagged variables
    begin to become statistically insignificant, or the coefficient of one of the variables
    changes sign, i - 1 is the final lag order"), read as follows:

    - insignificant: any coefficient of the newly added lag ``n`` has a two-sided t-test
      p-value above ``alpha`` (or undefined, NaN, as in a rank-deficient design);
    - sign change: for some sensor ``j`` the new coefficient ``b_{j,n}`` has the opposite sign
      of ``b_{j,n-1}`` in the same fit, i.e. the sensor's lag distribution changes sign at the
      new lag. This is the reading that reproduces the textbook example of this "ad hoc"
      (Alt-Tinbergen) procedure (Gujarati, Basic Econometrics, ch. 17): Alt rejects the fit
      ``0.109 x_t + 0.071 x_{t-1} - 0.055 x_{t-2}`` and keeps order 1.

    Parameters
    ----------
    sensors : list of str, length m
        Sensor names, for the message.
    coef : numpy.ndarray, shape (m, n + 1)
        Slopes b_{j,i} of the order-n fit, rows = sensors, columns = lags 0..n.
    new_pvalues : numpy.ndarray, shape (m,)
        p-values of the lag-n coefficients.
    alpha : float
        Significance level of the t-tests.

    Returns
    -------
    str or None
        Why the rule stops at this order (every offending sensor), or None to go on.
    """
    n = coef.shape[1] - 1
    reasons = [
        f"{sensor}_lag{n} insignificant (p = {p:.3g} > {alpha:g})"
        for sensor, p in zip(sensors, new_pvalues, strict=True)
        if not p <= alpha
    ]
    reasons += [
        f"{sensor} coefficient changes sign from lag {n - 1} ({row[n - 1]:.3g}) "
        f"to lag {n} ({row[n]:.3g})"
        for sensor, row in zip(sensors, coef, strict=True)
        if row[n] * row[n - 1] < 0
    ]
    return "; ".join(reasons) or None


def expedient_lag_order(
    X: pd.DataFrame, y: np.ndarray, max_lag: int, alpha: float
) -> tuple[int, str]:
    """Choose the DL lag order by the PCDL paper's expedient method.

    Fits the DL model by OLS for n = 1, 2, ..., max_lag and stops at the first n where
    :func:`lag_stop_reason` fires; the order is then n - 1 (0 = static multiple regression).
    Orders that would leave no residual degree of freedom are not tried (logged).

    Parameters
    ----------
    X : pandas.DataFrame, shape (n_samples, m)
        Temperatures, index as in :func:`pipeline.models.series.segments`.
    y : numpy.ndarray, shape (n_samples,)
        Thermal error (um).
    max_lag : int
        Highest order tried (samples).
    alpha : float
        Significance level of the coefficient t-tests.

    Returns
    -------
    tuple of (int, str)
        Chosen lag order and the reason the search stopped (for MLflow params).

    Raises
    ------
    ValueError
        If there are too few samples even for the static model.
    """
    sensors = list(X.columns)
    check_lag_feasible(len(y), len(sensors), 0)
    top = min(max_lag, max_feasible_lag(len(y), len(sensors)))
    if top < max_lag:
        logger.debug(
            "expedient lag search capped at order %d (max_lag=%d) by %d samples / %d sensors",
            top,
            max_lag,
            len(y),
            len(sensors),
        )
    for n in range(1, top + 1):
        result = ols_fit(lagged_values(X, n), y)
        coef = np.asarray(result.params)[1:].reshape(len(sensors), n + 1)
        pvalues = np.asarray(result.pvalues)[1:].reshape(len(sensors), n + 1)
        reason = lag_stop_reason(sensors, coef, pvalues[:, n], alpha)
        if reason is not None:
            return n - 1, f"expedient: stopped at lag {n}: {reason}"
    return top, f"expedient: no stop up to lag {top} (max_lag={max_lag})"


def lag_order(
    X: pd.DataFrame, y: np.ndarray, lag: int | None, max_lag: int, alpha: float
) -> tuple[int, str]:
    """Return the fixed lag order ``lag``, or the expedient one when ``lag`` is None.

    Returns
    -------
    tuple of (int, str)
        Lag order (samples) and its rule for MLflow params: "fixed", or why the expedient search
        (:func:`expedient_lag_order`, on X, y, ``max_lag`` and ``alpha``) stopped.
    """
    if lag is None:
        return expedient_lag_order(X, y, max_lag, alpha)
    return int(lag), "fixed"


class LaggedLinearModel(TemperatureModel):
    """Base of the linear distributed-lag models: ``y_t = a0 + sum_j sum_i b_{j,i} x_{j,t-i}``.

    Subclasses implement ``_fit``, which ends with :meth:`_set_coefficients`; prediction builds
    the lagged design per campaign (:func:`pipeline.models.series.lagged`) and applies the
    coefficients, so one campaign's predictions never depend on another campaign's rows.

    Attributes
    ----------
    coef_ : pandas.DataFrame, shape (m, lag_order_ + 1)
        b_{j,i} in um per unit of X (um/K); index = sensor, columns = lag (samples).
    intercept_ : float
        a0 (um).
    lag_order_ : int
        Maximum lag n (samples).
    feature_names_in_ : numpy.ndarray of str, shape (m,)
        Sensor columns, selected by name at predict time.
    n_features_in_ : int
        m.
    chosen_params_ : dict
        What the fit decided (for MLflow params).
    """

    def _set_coefficients(self, sensors: list[str], coef: np.ndarray, intercept: float) -> None:
        """Store sensor-major coefficients of shape (m * (lag + 1),) and the intercept."""
        lag = len(coef) // len(sensors) - 1
        self.coef_ = pd.DataFrame(
            np.reshape(coef, (len(sensors), lag + 1)),
            index=pd.Index(sensors, name="sensor"),
            columns=pd.RangeIndex(lag + 1, name="lag"),
        )
        self.intercept_ = float(intercept)
        self.lag_order_ = lag
        self.feature_names_in_ = np.asarray(sensors, dtype=object)
        self.n_features_in_ = len(sensors)

    def _predict(self, frame: pd.DataFrame) -> np.ndarray:
        """Apply the coefficients to the per-campaign lagged design, um."""
        design = lagged_values(frame, self.lag_order_)
        return design @ self.coef_.to_numpy().ravel() + self.intercept_


class DistributedLagRegressor(LaggedLinearModel):
    """Distributed-lag (DL) model by OLS with the expedient lag order (the PCDL paper, 2.1).

    ``y_t = a0 + sum_j sum_{i=0..n} b_{j,i} x_{j,t-i}``, coefficients by ordinary least squares
    (statsmodels OLS). Lags restart at every campaign; values before a campaign's first sample
    equal its first sample (see :func:`pipeline.models.series.lagged`).

    Parameters
    ----------
    max_lag : int, default 6
        Highest order (samples) the expedient search tries.
    lag : int or None, default None
        Fixed lag order (samples); None chooses it by :func:`expedient_lag_order` (raise n =
        1, 2, ...; stop when a new-lag coefficient is insignificant or a sensor's coefficient
        changes sign between lags n - 1 and n; use n - 1). 0 is static multiple regression.
    alpha_significance : float, default 0.05
        Significance level of the t-tests in the expedient search.

    Attributes
    ----------
    chosen_params_ : dict
        ``lag_order`` (int) and ``lag_rule`` (str: fixed, or why the expedient search stopped).
    pvalues_ : pandas.DataFrame, shape (m, lag_order_ + 1)
        Two-sided t-test p-values of ``coef_`` in the final fit.
    See :class:`LaggedLinearModel` for ``coef_``, ``intercept_``, ``lag_order_``.
    """

    def __init__(self, max_lag: int = 6, lag: int | None = None, alpha_significance: float = 0.05):
        self.max_lag = max_lag
        self.lag = lag
        self.alpha_significance = alpha_significance

    def _fit(self, frame: pd.DataFrame, target: np.ndarray) -> None:
        """Fit the DL model by OLS at the fixed or expedient lag order.

        Raises
        ------
        ValueError
            If there are too few samples for the lag order (message says what to lower).
        """
        lag, rule = lag_order(frame, target, self.lag, self.max_lag, self.alpha_significance)
        check_lag_feasible(len(target), frame.shape[1], lag)
        result = ols_fit(lagged_values(frame, lag), target)
        params = np.asarray(result.params)
        sensors = list(frame.columns)
        self._set_coefficients(sensors, params[1:], params[0])
        self.pvalues_ = pd.DataFrame(
            np.asarray(result.pvalues)[1:].reshape(self.coef_.shape),
            index=self.coef_.index,
            columns=self.coef_.columns,
        )
        self.chosen_params_ = {"lag_order": lag, "lag_rule": rule}
        logger.debug("DL fit: lag order %d (%s)", lag, rule)

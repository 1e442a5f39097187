"""Time-varying-parameter AR model tracked by recursive least squares with forgetting.

Source: the transmission-chain error paper ("the AR paper": a Chinese study of AR models of a
machine tool's transmission-chain error, of which sections 4-5 are known, without authors, year or
venue; end of section 4): a fixed-parameter AR(9) compensated poorly because the system is
time-varying (cutting conditions change the model's parameters, even its order), and "a time-varying
system should be described by a time-varying parameter model". The paper names no estimator; this
module uses the standard one, recursive least squares with exponential forgetting (Ljung, *System
Identification*, 11.2)::

    y_t = z_t' theta_t + e_t,   z_t = [1, y_{t-1}, ..., y_{t-p}]
    k_t = P_{t-1} z_t / (lambda + z_t' P_{t-1} z_t)
    theta_t = theta_{t-1} + k_t (y_t - z_t' theta_{t-1})
    P_t = (P_{t-1} - k_t z_t' P_{t-1}) / lambda

with forgetting factor lambda (memory about 1 / (1 - lambda) samples).

- Fit: the order p is given or chosen by AIC on the stacked per-campaign OLS fits (as in
  :mod:`pipeline.models.ar_reduced`); theta_0 is the OLS estimate over all training campaigns
  and P_0 the inverse of the information matrix scaled to one memory length,
  P_0 = (Z'Z * memory / N)^-1, so the prior weighs as much as the RLS's own window of data.
- One-step-ahead (measured error given): every campaign starts from (theta_0, P_0); the
  prediction at t uses theta_{t-1}, then the measured y_t updates the parameters. This is the
  model's point: it follows a machine whose behaviour drifts.
- Free run: with no measured error nothing can update the parameters, so the model keeps the
  parameters it starts every campaign from (theta_0) and feeds back its own predictions.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from pipeline.models.ar_reduced import aic_curve, ar_least_squares, feasible_order
from pipeline.models.base import FeedbackModel
from pipeline.models.feedback import linear_feedback_predict
from pipeline.models.series import history, segments

logger = logging.getLogger(__name__)


class TimeVaryingAR(FeedbackModel):
    """AR(p) whose parameters are tracked on line by recursive least squares with forgetting.

    Uses no temperatures: X's columns are ignored, its index gives the campaigns.

    Parameters
    ----------
    order : int or None, default None
        AR order p; None chooses it by AIC among 1..``max_order``.
    max_order : int, default 10
        Largest order considered when ``order`` is None (capped by the data length).
    forgetting : float, default 0.98
        Forgetting factor lambda in (0, 1]; 1 is ordinary recursive least squares.

    Attributes
    ----------
    order_ : int
        p.
    theta_ : numpy.ndarray of shape (p + 1,)
        Starting parameters [c (um), a_1..a_p] (stacked OLS over the training campaigns).
    covariance_ : numpy.ndarray of shape (p + 1, p + 1)
        P_0 (um^-2 scale of the information matrix inverse).
    chosen_params_ : dict
        order, forgetting, memory_samples.
    """

    min_columns = 0

    def __init__(self, order: int | None = None, max_order: int = 10, forgetting: float = 0.98):
        self.order = order
        self.max_order = max_order
        self.forgetting = forgetting

    def _check_params(self) -> None:
        """Raise ValueError unless ``forgetting`` is in (0, 1] and the order is >= 1."""
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"forgetting must be in (0, 1], got {self.forgetting}")
        if int(self._requested_order()) < 1:
            raise ValueError(f"the AR order must be >= 1, got {self._requested_order()}")

    def _requested_order(self) -> int:
        """``order``, or ``max_order`` when the order is chosen by AIC."""
        return self.max_order if self.order is None else self.order

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Choose the order and the starting parameters of the recursion."""
        segs = segments(X)
        max_order = feasible_order(int(self._requested_order()), segs)
        fits = ar_least_squares(target, segs, max_order)
        order = int(aic_curve(fits, len(target)).idxmin()) if self.order is None else max_order
        if self.order is not None and max_order < self.order:
            logger.warning("AR order %d capped at %d by the data length", self.order, max_order)
        intercept, ar, _ = fits[order - 1]
        self.order_ = order
        self.theta_ = np.r_[intercept, ar]
        design = _regressors(history(target, segs, order))
        memory = 1.0 / (1.0 - self.forgetting) if self.forgetting < 1.0 else len(target)
        information = design.T @ design * (min(memory, len(target)) / len(target))
        self.covariance_ = np.linalg.pinv(information)
        self.chosen_params_ = {
            "order": order,
            "forgetting": float(self.forgetting),
            "memory_samples": round(float(min(memory, len(target))), 3),
        }

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Predict one-step-ahead, updating the parameters by the measured error, or run free."""
        if measured is None:
            base = np.full(len(X), self.theta_[0])
            return linear_feedback_predict(base, self.theta_[1:], segments(X), None)
        return self._track(X, measured)[0]

    def tracked_parameters(self, X: pd.DataFrame, y_history: np.ndarray) -> pd.DataFrame:
        """Parameters after the update with each measured error (one-step-ahead mode).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n, m)
            Feature table; only its index (campaigns) is used.
        y_history : array-like of shape (n,)
            Measured thermal error (um) aligned with X's rows.

        Returns
        -------
        pandas.DataFrame of shape (n, p + 1)
            Columns ``intercept_um``, ``a1``..``ap``; index of X. Row t holds theta_t.
        """
        X, measured = self._prediction_inputs(X, y_history)
        if measured is None:
            raise ValueError("tracked_parameters needs the measured error y_history")
        columns = ["intercept_um"] + [f"a{i + 1}" for i in range(self.order_)]
        return pd.DataFrame(self._track(X, measured)[1], index=X.index, columns=columns)

    def _track(self, X: pd.DataFrame, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run the RLS recursion campaign by campaign: (predictions (n,), theta_t (n, p + 1))."""
        segs = segments(X)
        design = _regressors(history(measured, segs, self.order_))
        predictions = np.empty(len(X), dtype=float)
        thetas = np.empty((len(X), self.order_ + 1), dtype=float)
        lam = self.forgetting
        for rows in segs:
            theta, cov = self.theta_.copy(), self.covariance_.copy()
            for row in rows:
                z = design[row]
                predictions[row] = z @ theta
                gain = cov @ z / (lam + z @ cov @ z)
                theta = theta + gain * (measured[row] - predictions[row])
                cov = (cov - np.outer(gain, z @ cov)) / lam
                cov = 0.5 * (cov + cov.T)
                thetas[row] = theta
        return predictions, thetas


def _regressors(lags: np.ndarray) -> np.ndarray:
    """[1, y_{t-1}, ..., y_{t-p}] rows from the (n, p) error history."""
    return np.column_stack([np.ones(len(lags)), lags])

"""Models on the thermal error's own history: the feedback flag and the prediction loops.

A model that uses past measured errors (ARMA, ARDL, SVR on the error series, TS-BP, ...) can
only compensate a machine that measures its error online. Such a model sets the class attribute
``needs_error_feedback = True`` and accepts ``predict(X, y_history=None)``:

- one-step-ahead (``y_history`` given, the measured error aligned with X's rows): the
  prediction at sample t uses the measured error up to t-1 (and X up to t);
- free run (``y_history=None``): the model's own predictions are fed back as its history.

In both modes the history restarts at every campaign with pre-sample error 0 um: the thermal
error is 0 at the cold reference state a campaign starts from.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
from scipy.signal import lfilter

from pipeline.models.series import history

logger = logging.getLogger(__name__)

#: ``step(rows, lags) -> predictions``: rows is an int array (k,) of row positions, lags an
#: array (k, n_lags) of the error history, column i - 1 holding y_{t-i} (um); returns (k,) um.
Step = Callable[[np.ndarray, np.ndarray], np.ndarray]


def uses_error_feedback(estimator: object) -> bool:
    """Return whether ``estimator`` predicts from the error's own history.

    Estimators without the attribute (e.g. scikit-learn's LinearRegression) are static.
    """
    return bool(getattr(estimator, "needs_error_feedback", False))


def check_history(y_history: np.ndarray | None, n_rows: int) -> np.ndarray | None:
    """Validate a measured error history for one-step-ahead prediction.

    Parameters
    ----------
    y_history : array-like of shape (n,), um, or None
        Measured thermal error aligned with X's rows; None selects free run.
    n_rows : int
        Number of rows of X.

    Returns
    -------
    numpy.ndarray of shape (n,) or None
        A float copy of ``y_history``, or None for free run.

    Raises
    ------
    ValueError
        If the history does not have one finite value per row of X.
    """
    if y_history is None:
        return None
    values = np.asarray(y_history, dtype=float).ravel()
    if len(values) != n_rows:
        raise ValueError(
            f"y_history has {len(values)} values but X has {n_rows} rows; pass the measured "
            "error aligned with X's rows, or y_history=None for free run"
        )
    if not np.isfinite(values).all():
        raise ValueError(
            "y_history holds NaN or infinite values; one-step-ahead prediction needs the "
            "measured error at every row (use y_history=None for free run)"
        )
    return values


def feedback_predict(
    step: Step,
    segments: Sequence[np.ndarray],
    n_lags: int,
    y_history: np.ndarray | None = None,
) -> np.ndarray:
    """Run a model on the error history one-step-ahead or in free run.

    Parameters
    ----------
    step : callable
        ``step(rows, lags) -> ndarray (k,)``, the prediction (um) at row positions ``rows``
        (int array (k,)) from the error history ``lags`` (array (k, n_lags), column i - 1 =
        y_{t-i}, um). It may use anything else it knows about those rows (e.g. temperatures).
    segments : sequence of numpy.ndarray
        Row positions of each campaign (:func:`pipeline.models.series.segments`).
    n_lags : int
        Length of the history the step needs, >= 0.
    y_history : numpy.ndarray of shape (n,), um, optional
        Measured error (already checked by :func:`check_history`). Given: one-step-ahead, the
        history is the measured error and ``step`` is called once for all rows. None: free run,
        the history is the model's own predictions, one row at a time.

    Returns
    -------
    numpy.ndarray of shape (n,)
        Predicted thermal error (um). Pre-sample history is 0 um at every campaign start.
    """
    n_rows = sum(len(rows) for rows in segments)
    all_rows = np.arange(n_rows)
    if y_history is not None:
        return np.asarray(step(all_rows, history(y_history, list(segments), n_lags)), dtype=float)
    predictions = np.empty(n_rows, dtype=float)
    for rows in segments:
        past = np.zeros((1, n_lags), dtype=float)
        for row in rows:
            value = float(step(np.array([row]), past)[0])
            predictions[row] = value
            if n_lags:
                past = np.concatenate([[[value]], past[:, :-1]], axis=1)
    return predictions


def linear_feedback_predict(
    base: np.ndarray,
    ar_coef: np.ndarray,
    segments: Sequence[np.ndarray],
    y_history: np.ndarray | None = None,
) -> np.ndarray:
    """Predict y_t = base_t + sum_i a_i y_{t-i} one-step-ahead or in free run.

    Parameters
    ----------
    base : numpy.ndarray of shape (n,), um
        The part of the prediction that does not depend on the error history (intercept plus
        distributed-lag temperature terms).
    ar_coef : numpy.ndarray of shape (p,)
        Autoregressive coefficients a_1..a_p (dimensionless).
    segments : sequence of numpy.ndarray
        Row positions of each campaign.
    y_history : numpy.ndarray of shape (n,), um, optional
        Measured error for one-step-ahead prediction; None for free run.

    Returns
    -------
    numpy.ndarray of shape (n,)
        Predicted thermal error (um).
    """
    coef = np.asarray(ar_coef, dtype=float)
    if y_history is not None:
        return base + history(y_history, list(segments), len(coef)) @ coef
    # Free run is the recursive filter y = base / (1 - sum_i a_i B^i) started at rest (pre-sample
    # error 0), campaign by campaign.
    predictions = np.empty(len(base), dtype=float)
    for rows in segments:
        predictions[rows] = lfilter([1.0], np.r_[1.0, -coef], base[rows])
    return predictions

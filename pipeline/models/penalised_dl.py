"""Ridge and partial-least-squares distributed-lag models, tuned by campaign-wise CV.

Source: the PCDL paper (Miao Enming, Liu Yi, Dong Yunfei and Chen Weikang, 2016, "Improvement of
forecasting robustness of time series model for thermal error on CNC machine tool", Optics and
Precision Engineering 24(10), 2480-2489), section 2.2, names ridge regression (its ref. 14) next to
principal-component regression as algorithms that suppress the collinearity the temperature lags
bring into the distributed-lag design, and its ref. 13 applies partial least squares (PLS) for the
same purpose. The paper gives no details for either; the standard estimators are used on the DL
design of :mod:`pipeline.models.distributed_lag` at a fixed lag order (default 2, the order the
paper found for PCDL):

- ridge: standardised lagged temperatures, ``min ||y - y_mean - Z b||^2 + alpha ||b||^2``;
- PLS: PLS1 regression (scikit-learn ``PLSRegression``, standardised X and y).

The penalty ``alpha`` / the number of PLS components is chosen by cross-validation that never
splits a time series at random (:func:`cv_folds`): leave-one-campaign-out when X holds two or
more campaigns, otherwise contiguous blocks in time order. The choice minimises the mean
squared error over all held-out rows (ties: the first, i.e. smallest alpha / fewest
components). Coefficients are mapped back to the unstandardised lagged temperatures.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from functools import partial

import numpy as np
import pandas as pd
from sklearn.cross_decomposition import PLSRegression

from pipeline.models.distributed_lag import LaggedLinearModel
from pipeline.models.series import lagged_values, segments

logger = logging.getLogger(__name__)

DEFAULT_ALPHAS = tuple(float(a) for a in np.logspace(-3, 4, 15))
N_TIME_BLOCKS = 5

Fold = tuple[np.ndarray, np.ndarray]


def cv_folds(X: pd.DataFrame) -> tuple[list[Fold], str]:
    """Return cross-validation folds that respect the campaigns and the time order.

    Parameters
    ----------
    X : pandas.DataFrame, shape (n, m)
        Feature table, index as in :func:`pipeline.models.series.segments`.

    Returns
    -------
    tuple of (list of (train_rows, test_rows), str)
        Integer row positions per fold, and the scheme for MLflow params: each campaign held out
        in turn when there are >= 2 campaigns ("leave-one-campaign-out (k folds)"), otherwise
        the single series cut into up to 5 contiguous blocks in time order, each held out in
        turn ("blocked time order (k contiguous folds, one campaign)"). Never shuffled.

    Raises
    ------
    ValueError
        If a single series has fewer than 4 samples (no two blocks of two rows).
    """
    segs = segments(X)
    everything = np.arange(len(X))
    if len(segs) >= 2:
        blocks, scheme = segs, f"leave-one-campaign-out ({len(segs)} folds)"
    else:
        n_blocks = min(N_TIME_BLOCKS, len(X) // 2)
        if n_blocks < 2:
            raise ValueError(
                f"too few samples ({len(X)}) for blocked cross-validation of one campaign; "
                "it needs at least 4"
            )
        blocks = np.array_split(everything, n_blocks)
        scheme = f"blocked time order ({n_blocks} contiguous folds, one campaign)"
    folds = [(np.setdiff1d(everything, test), test) for test in blocks]
    return folds, scheme


def _standardise(design: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (z-scores, column means, column scales); constant columns get scale 1."""
    mean = design.mean(axis=0)
    scale = design.std(axis=0)
    scale = np.where(scale > 0.0, scale, 1.0)
    return (design - mean) / scale, mean, scale


def ridge_path(design: np.ndarray, y: np.ndarray, alphas: np.ndarray) -> np.ndarray:
    """Ridge slopes on the standardised design for every alpha, via one SVD.

    Parameters
    ----------
    design : numpy.ndarray, shape (n, p)
        Lagged temperatures.
    y : numpy.ndarray, shape (n,)
        Thermal error (um).
    alphas : numpy.ndarray, shape (k,)
        Penalties (>= 0) on the standardised slopes.

    Returns
    -------
    numpy.ndarray, shape (k, p + 1)
        Per alpha: intercept (um) then slopes mapped back to the unstandardised columns.
    """
    z, mean, scale = _standardise(design)
    y_mean = y.mean()
    u, s, vt = np.linalg.svd(z, full_matrices=False)
    shrink = s[None, :] / (s[None, :] ** 2 + alphas[:, None])
    slopes = (shrink * (u.T @ (y - y_mean))[None, :]) @ vt / scale[None, :]
    intercepts = y_mean - slopes @ mean
    return np.column_stack([intercepts, slopes])


def _pls_coefficients(design: np.ndarray, y: np.ndarray, n_components: int) -> np.ndarray:
    """PLS1 fit; returns intercept (um) then slopes on the unstandardised columns, (p + 1,)."""
    pls = PLSRegression(n_components=n_components, scale=True).fit(design, y)
    slopes = np.asarray(pls.coef_).ravel()
    return np.r_[y.mean() - slopes @ design.mean(axis=0), slopes]


def _held_out_mse(
    design: np.ndarray,
    y: np.ndarray,
    folds: list[Fold],
    fit_path: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> np.ndarray:
    """Mean squared error (um^2) over all held-out rows, per candidate.

    Parameters
    ----------
    design, y : numpy.ndarray, shapes (n, p) and (n,)
        Lagged temperatures and thermal error (um), as for :func:`ridge_path`.
    folds : list of (train_rows, test_rows)
        From :func:`cv_folds`.
    fit_path : callable
        ``fit_path(design, y) -> (k, p + 1)``: per candidate, intercept (um) then slopes.

    Returns
    -------
    numpy.ndarray, shape (k,)
        Held-out MSE of every candidate.
    """
    errors = []
    for train, test in folds:
        path = fit_path(design[train], y[train])
        errors.append(path[:, :1].T + design[test] @ path[:, 1:].T - y[test][:, None])
    return np.mean(np.concatenate(errors) ** 2, axis=0)


class RidgeDistributedLag(LaggedLinearModel):
    """Ridge-regression distributed-lag model, penalty chosen by campaign-wise CV.

    Parameters
    ----------
    lag : int, default 2
        Lag order (samples), the order the PCDL paper found.
    alphas : tuple of float, default 15 values log-spaced from 1e-3 to 1e4
        Candidate penalties on the standardised slopes.

    Attributes
    ----------
    cv_mse_ : pandas.Series
        Held-out mean squared error (um^2) per alpha.
    chosen_params_ : dict
        ``lag_order``, ``alpha`` and ``cv_scheme``.
    See :class:`pipeline.models.distributed_lag.LaggedLinearModel` for ``coef_`` (um/K) and
    ``intercept_`` (um).
    """

    def __init__(self, lag: int = 2, alphas: tuple[float, ...] = DEFAULT_ALPHAS):
        self.lag = lag
        self.alphas = alphas

    def _check_params(self) -> None:
        """Raise ValueError unless ``alphas`` is a non-empty sequence of values >= 0."""
        alphas = np.asarray(self.alphas, dtype=float)
        if alphas.size == 0 or (alphas < 0).any():
            raise ValueError(f"alphas must be a non-empty sequence of values >= 0, got {alphas}")

    def _fit(self, frame: pd.DataFrame, target: np.ndarray) -> None:
        """Choose alpha by campaign-wise CV (:func:`cv_folds`), then fit on all rows."""
        alphas = np.asarray(self.alphas, dtype=float)
        design = lagged_values(frame, int(self.lag))
        folds, scheme = cv_folds(frame)
        mse = _held_out_mse(design, target, folds, partial(ridge_path, alphas=alphas))
        best = int(np.argmin(mse))
        solution = ridge_path(design, target, alphas[best : best + 1])[0]
        self._set_coefficients(list(frame.columns), solution[1:], solution[0])
        self.cv_mse_ = pd.Series(mse, index=pd.Index(alphas, name="alpha"), name="cv_mse_um2")
        self.chosen_params_ = {
            "lag_order": int(self.lag),
            "alpha": float(alphas[best]),
            "cv_scheme": scheme,
        }
        logger.debug("ridge DL fit: %s", self.chosen_params_)


RIDGE_ALPHAS = tuple(float(a) for a in np.logspace(-2, 6, 17))


class RidgeRegression(RidgeDistributedLag):
    """Ridge regression on the current inputs only (no lags), penalty chosen by campaign-wise CV.

    The static member of :class:`RidgeDistributedLag` (lag order 0): ``y = a0 + X b`` with
    ``min ||y - y_mean - Z b||^2 + alpha ||b||^2`` on the standardised inputs Z, alpha chosen
    by leave-one-campaign-out cross-validation (:func:`cv_folds`). On every temperature it is
    the plain all-sensor ridge baseline; on every temperature and the speed responses
    (selection ``all_speed``) it is the candidate that lets the penalty, not a selection
    method, decide which inputs carry weight. The alpha grid is wider than the lagged model's
    (1e-2 to 1e6), since long records give large Z'Z.

    Parameters
    ----------
    alphas : tuple of float, default 17 values log-spaced from 1e-2 to 1e6
        Candidate penalties on the standardised slopes.
    """

    lag = 0

    def __init__(self, alphas: tuple[float, ...] = RIDGE_ALPHAS):
        self.alphas = alphas


class PLSDistributedLag(LaggedLinearModel):
    """Partial-least-squares distributed-lag model, components chosen by campaign-wise CV.

    Parameters
    ----------
    lag : int, default 2
        Lag order (samples), the order the PCDL paper found.
    max_components : int, default 8
        Most PLS components tried (1..max_components, capped by the number of lagged columns
        and by the smallest training fold minus one).

    Attributes
    ----------
    cv_mse_ : pandas.Series
        Held-out mean squared error (um^2) per number of components.
    chosen_params_ : dict
        ``lag_order``, ``n_components`` and ``cv_scheme``.
    See :class:`pipeline.models.distributed_lag.LaggedLinearModel` for ``coef_`` (um/K) and
    ``intercept_`` (um).
    """

    def __init__(self, lag: int = 2, max_components: int = 8):
        self.lag = lag
        self.max_components = max_components

    def _check_params(self) -> None:
        """Raise ValueError unless ``max_components`` >= 1."""
        if self.max_components < 1:
            raise ValueError(f"max_components must be >= 1, got {self.max_components}")

    def _fit(self, frame: pd.DataFrame, target: np.ndarray) -> None:
        """Choose the components by campaign-wise CV (:func:`cv_folds`), then fit on all rows."""
        design = lagged_values(frame, int(self.lag))
        folds, scheme = cv_folds(frame)
        smallest_train = min(len(train) for train, _ in folds)
        candidates = np.arange(1, min(self.max_components, design.shape[1], smallest_train - 1) + 1)

        def path(train_design: np.ndarray, train_y: np.ndarray) -> np.ndarray:
            return np.array([_pls_coefficients(train_design, train_y, k) for k in candidates])

        mse = _held_out_mse(design, target, folds, path)
        best = int(candidates[np.argmin(mse)])
        solution = _pls_coefficients(design, target, best)
        self._set_coefficients(list(frame.columns), solution[1:], solution[0])
        self.cv_mse_ = pd.Series(
            mse, index=pd.Index(candidates, name="n_components"), name="cv_mse_um2"
        )
        self.chosen_params_ = {
            "lag_order": int(self.lag),
            "n_components": best,
            "cv_scheme": scheme,
        }
        logger.debug("PLS DL fit: %s", self.chosen_params_)

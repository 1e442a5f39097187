"""Grey relational degree (Deng's grey relational analysis) of sensors to the thermal error.

Used by the PCDL paper (Miao et al. 2016, section 4.1 and table 4) to rank temperature variables
by their "influence weight" on the thermal deformation; its equations are missing from the
capture, so this is the standard form (Deng 1982):

1. Normalise the reference series x0 (the error) and every comparison series xi (a sensor).
2. Differences d_i(k) = |x0(k) - xi(k)|, with the two-level extremes d_min = min_i min_k d_i(k)
   and d_max = max_i max_k d_i(k) over all compared sensors.
3. Relational coefficients xi_i(k) = (d_min + rho * d_max) / (d_i(k) + rho * d_max), with the
   resolution coefficient rho = 0.5.
4. Relational degree gamma_i = mean_k xi_i(k), in (0, 1]; larger means more alike in shape.

Normalisation. Deng's usual initial-value normalisation x(k) / x(1) divides by zero here:
temperature rises and the thermal error are 0 at each campaign's first sample. Range
normalisation (x - min) / (max - min) is used instead: it maps every series onto [0, 1], so
sensors with rises of different size compare by shape only, and it is defined for any
non-constant series (constant sensors are ignored upstream). A sensor that is negatively
correlated with the error is compared through its mirror image 1 - x: the sign of a thermal
error is only an axis convention, and a sensor that drives the error down is as sensitive as one
that drives it up (the grey-theory treatment of negatively related factors). Degrees depend on
the set of sensors compared together through d_min and d_max, as in Deng's method.
"""

from __future__ import annotations

import numpy as np

RESOLUTION_COEFFICIENT = 0.5


def range_normalise(values: np.ndarray) -> np.ndarray:
    """Map each column onto [0, 1] by (x - min) / (max - min).

    Parameters
    ----------
    values : ndarray of shape (n,) or (n, m)
        Series in any unit; every column non-constant.

    Returns
    -------
    ndarray of the same shape
        Dimensionless values in [0, 1].
    """
    low = values.min(axis=0)
    return (values - low) / (values.max(axis=0) - low)


def grey_relational_degree(
    reference: np.ndarray, comparison: np.ndarray, rho: float = RESOLUTION_COEFFICIENT
) -> np.ndarray:
    """Grey relational degree of each comparison series to the reference series.

    Parameters
    ----------
    reference : ndarray of shape (n,)
        Reference series x0 (the thermal error, um); not constant, no NaN.
    comparison : ndarray of shape (n, m)
        Comparison series xi, one per column (temperature rises, K); none constant, no NaN.
    rho : float, default 0.5
        Resolution coefficient, in (0, 1].

    Returns
    -------
    ndarray of shape (m,)
        Relational degrees gamma_i in (0, 1].

    Raises
    ------
    ValueError
        If the shapes disagree, ``rho`` is outside (0, 1], or a series is constant or not finite.
    """
    x0 = np.asarray(reference, dtype=float)
    xi = np.asarray(comparison, dtype=float)
    if xi.ndim != 2 or x0.shape != (xi.shape[0],):
        raise ValueError(
            f"reference must have shape (n,) and comparison (n, m); got {x0.shape} and {xi.shape}"
        )
    if not 0.0 < rho <= 1.0:
        raise ValueError(f"resolution coefficient rho={rho} must lie in (0, 1]; usually 0.5")
    if not (np.isfinite(x0).all() and np.isfinite(xi).all()):
        raise ValueError("grey relational degree needs finite series; drop rows with NaN first")
    if np.ptp(x0) == 0.0 or (np.ptp(xi, axis=0) == 0.0).any():
        raise ValueError("grey relational degree is undefined for a constant series")
    ref = range_normalise(x0)
    comp = range_normalise(xi)
    centred = xi - xi.mean(axis=0)
    negative = (centred.T @ (x0 - x0.mean())) < 0.0
    comp[:, negative] = 1.0 - comp[:, negative]
    delta = np.abs(ref[:, None] - comp)
    d_min, d_max = float(delta.min()), float(delta.max())
    if d_max == 0.0:
        return np.ones(xi.shape[1])
    coefficients = (d_min + rho * d_max) / (delta + rho * d_max)
    return coefficients.mean(axis=0)

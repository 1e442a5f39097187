"""Reverse-arrangement (inverse-order) test of stationarity.

The TS-BP paper (Li Xingda, Gu Qunying, Li Zihan and Yang Jianguo, 2015, "Modeling for thermal
error based on time series-neural network", Modular Machine Tool & Automatic Manufacturing
Technique 2015(9), 13-16; section 1.1, equations 2-4) tests the zero-mean error series for
stationarity before identifying an ARMA model: split the N samples into k consecutive
sub-series of length L (N = kL), take the mean of each, and count the reverse arrangements of
those k means. The capture lost the equations; this module uses the standard form of the test
(Bendat and Piersol, *Random Data*, section 4.5.2):

    h_ij = 1 if x_i > x_j (i < j), else 0;   A = sum_{i<j} h_ij
    E[A] = k (k - 1) / 4;   Var[A] = k (2k^2 + 3k - 5) / 72
    z = (A - E[A]) / sqrt(Var[A])

For independent, identically distributed values A is approximately normal, so a series is
declared non-stationary when |z| exceeds the two-sided normal quantile at level ``alpha``: a
rising trend gives too few reverse arrangements (z << 0), a falling one too many (z >> 0).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

logger = logging.getLogger(__name__)

#: Default number of sub-series: enough for the normal approximation of A (k >= 10).
DEFAULT_SUBSERIES = 20


@dataclass(frozen=True)
class ReverseArrangementResult:
    """Outcome of the reverse-arrangement test.

    Attributes
    ----------
    statistic : int
        A, the number of reverse arrangements (pairs i < j with x_i > x_j) of the sub-series
        means.
    expected : float
        E[A] under stationarity, k (k - 1) / 4.
    variance : float
        Var[A] under stationarity, k (2k^2 + 3k - 5) / 72.
    z : float
        Standardised statistic (A - E[A]) / sqrt(Var[A]).
    p_value : float
        Two-sided p-value of z under the standard normal.
    n_subseries : int
        k, the number of sub-series whose means were compared.
    stationary : bool
        True if stationarity is not rejected at level ``alpha``.
    """

    statistic: int
    expected: float
    variance: float
    z: float
    p_value: float
    n_subseries: int
    stationary: bool


def reverse_arrangements(values: np.ndarray) -> int:
    """Count the reverse arrangements A = #{(i, j): i < j, x_i > x_j} of a sequence.

    Parameters
    ----------
    values : array-like of shape (k,)
        The sequence (any unit); ties do not count.

    Returns
    -------
    int
        A, between 0 (non-decreasing) and k (k - 1) / 2 (strictly decreasing).
    """
    x = np.asarray(values, dtype=float).ravel()
    return int(np.triu(x[:, None] > x[None, :], k=1).sum())


def reverse_arrangement_test(
    series: np.ndarray, n_subseries: int | None = None, alpha: float = 0.05
) -> ReverseArrangementResult:
    """Test a series for stationarity of its mean by the reverse-arrangement test.

    Parameters
    ----------
    series : array-like of shape (N,)
        The series (e.g. thermal error, um).
    n_subseries : int, optional
        k, the number of consecutive sub-series of length L = N // k whose means are compared
        (the TS-BP paper's N = kL); the last N - kL samples are not used. Default
        ``min(N, 20)``; ``N`` compares the samples themselves (L = 1).
    alpha : float, default 0.05
        Significance level of the two-sided test.

    Returns
    -------
    ReverseArrangementResult
        The statistic, its null moments, z, p-value and the decision.

    Raises
    ------
    ValueError
        If the series holds NaN/inf, if k < 3 or k > N, or if alpha is not in (0, 1).
    """
    x = np.asarray(series, dtype=float).ravel()
    if not np.isfinite(x).all():
        raise ValueError("the series holds NaN or infinite values; the test needs finite data")
    k = min(len(x), DEFAULT_SUBSERIES) if n_subseries is None else int(n_subseries)
    if k < 3 or k > len(x):
        raise ValueError(
            f"the reverse-arrangement test needs 3 <= n_subseries <= N = {len(x)}, got {k}; "
            "pass a longer series or fewer sub-series"
        )
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    length = len(x) // k
    means = x[: k * length].reshape(k, length).mean(axis=1)
    statistic = reverse_arrangements(means)
    expected = k * (k - 1) / 4.0
    variance = k * (2.0 * k**2 + 3.0 * k - 5.0) / 72.0
    z = (statistic - expected) / np.sqrt(variance)
    p_value = float(2.0 * norm.sf(abs(z)))
    return ReverseArrangementResult(
        statistic=statistic,
        expected=expected,
        variance=variance,
        z=float(z),
        p_value=p_value,
        n_subseries=k,
        stationary=bool(p_value >= alpha),
    )

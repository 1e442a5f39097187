"""The statistics every fit and score shares: root mean square and information criteria.

One definition each, so that a score or a criterion means the same in every package:

- RMS = sqrt(mean(e^2)) over the finite values of e, in e's unit;
- for a least-squares fit of ``k`` parameters to ``n`` observations with residual sum of
  squares RSS, the Gaussian log-likelihood up to a constant gives
  AIC = n ln(RSS / n) + 2 k (Akaike 1974, "A new look at the statistical model
  identification", IEEE Transactions on Automatic Control 19(6)),
  AICc = AIC + 2 k (k + 1) / (n - k - 1) (Hurvich and Tsai 1989, "Regression and time series
  model selection in small samples", Biometrika 76(2); +inf when n - k - 1 <= 0, where it is
  undefined) and BIC = n ln(RSS / n) + k ln(n) (Schwarz 1978, "Estimating the dimension of a
  model", Annals of Statistics 6(2)).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


def root_mean_square(values: np.ndarray | Iterable[float]) -> float:
    """Root mean square of the finite entries of ``values``, in their unit; NaN if none.

    Parameters
    ----------
    values : array_like
        Any shape; NaN and infinite entries are ignored.
    """
    array = np.asarray(values, dtype=float).ravel()
    finite = array[np.isfinite(array)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")


def information_criteria(
    rss: np.ndarray | float, n: int, k: np.ndarray | int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """AIC, AICc and BIC of least-squares fits (dimensionless; see the module docstring).

    Parameters
    ----------
    rss : float or ndarray
        Residual sum of squares of each fit, in the squared unit of the data. A zero RSS gives
        -inf (a perfect fit); callers that must rank such fits floor it first.
    n : int
        Number of observations.
    k : int or ndarray
        Number of estimated parameters of each fit (broadcast against ``rss``).

    Returns
    -------
    aic, aicc, bic : ndarray
        Same shape as ``np.broadcast(rss, k)``; AICc is +inf where ``n - k - 1 <= 0``.
    """
    rss = np.asarray(rss, dtype=float)
    k = np.asarray(k, dtype=float)
    with np.errstate(divide="ignore"):
        log_likelihood_term = n * np.log(rss / n)
    aic = log_likelihood_term + 2.0 * k
    room = n - k - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        correction = np.where(room > 0, 2.0 * k * (k + 1.0) / np.where(room > 0, room, 1.0), np.inf)
    bic = log_likelihood_term + k * np.log(n)
    return aic, aic + correction, bic

"""Box-Jenkins identification from the autocorrelation (ACF) and partial autocorrelation (PACF).

The TS-BP paper (Li et al. 2015, "Modeling for thermal error based on time series-neural network",
Modular Machine Tool & Automatic Manufacturing Technique 2015(9), 13-16; section 1.1, equations 5-6)
chooses the model family from the sample ACF and PACF of the zero-mean error series: PACF cuts off
and ACF tails -> AR; ACF cuts off and PACF tails -> MA; both tail -> ARMA. The SVR paper (Chen Ziran
et al. 2012, "Time-series prediction for a time-grating CNC rotary table based on support vector
machines") takes the embedding dimension from the lag at which the PACF cuts off (7 there).

The capture lost the paper's equations; the standard estimators are used: the sample
autocovariance c_k = (1/N) sum_t z_t z_{t-k} (z zero-mean), r_k = c_k / c_0, and the PACF from
r by the Durbin-Levinson recursion (statsmodels ``levinson_durbin``). With several campaigns
the products z_t z_{t-k} are summed within each campaign only (no pair straddles a campaign
boundary) and divided by the total N. A value is *inside the band* when |r_k| <= 1.96 /
sqrt(N), the 95 % band of a white-noise correlation.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from statsmodels.tsa.stattools import levinson_durbin

logger = logging.getLogger(__name__)

#: Two-sided 95 % normal quantile of the white-noise band 1.96 / sqrt(N).
BAND_QUANTILE = 1.96
#: A cut-off must be abrupt: the last value outside the band is at least this many band
#: widths from 0 (a geometric decay crossing the band is at most 1 / rho band widths).
ABRUPT_RATIO = 2.0
#: After a cut-off at d, at least this fraction of the remaining lags lie inside the band.
INSIDE_FRACTION = 0.9
#: Information criteria that can fix a model's orders.
CRITERIA = ("aic", "bic")


@dataclass(frozen=True)
class Identification:
    """Model family and candidate orders identified from the ACF and PACF.

    Attributes
    ----------
    kind : str
        "AR", "MA", "ARMA" (both tail), "ambiguous" (both cut off at lags > 0) or
        "white noise" (both cut off at lag 0).
    acf, pacf : numpy.ndarray of shape (n_lags + 1,)
        Sample ACF and PACF at lags 0..n_lags (value 1 at lag 0).
    band : float
        Half-width of the 95 % white-noise band, 1.96 / sqrt(N).
    acf_cutoff, pacf_cutoff : int or None
        Lag after which the ACF / PACF cuts off, None if it tails.
    candidates : list of tuple of int
        (p, q) orders to compare by information criterion.
    """

    kind: str
    acf: np.ndarray
    pacf: np.ndarray
    band: float
    acf_cutoff: int | None
    pacf_cutoff: int | None
    candidates: list[tuple[int, int]]


def check_criterion(ic: str) -> None:
    """Raise ValueError unless ``ic`` is one of :data:`CRITERIA`."""
    if ic not in CRITERIA:
        raise ValueError(f"ic must be one of {CRITERIA}, got {ic!r}")


def pooled_autocorrelation(pieces: Sequence[np.ndarray], n_lags: int) -> np.ndarray:
    """Sample ACF of a series split into independent pieces (one per campaign).

    Parameters
    ----------
    pieces : sequence of numpy.ndarray
        The series of each campaign (any unit); centred by their pooled mean here.
    n_lags : int
        Highest lag, >= 1 and shorter than the longest piece.

    Returns
    -------
    numpy.ndarray of shape (n_lags + 1,)
        r_0 = 1, r_1, ..., r_{n_lags}.

    Raises
    ------
    ValueError
        If the series is constant (no variance to correlate) or ``n_lags`` is out of range.
    """
    arrays = [np.asarray(piece, dtype=float).ravel() for piece in pieces]
    longest = max(len(a) for a in arrays)
    if not 1 <= n_lags < longest:
        raise ValueError(f"n_lags must be in 1..{longest - 1} for these campaigns, got {n_lags}")
    total = sum(len(a) for a in arrays)
    mean = sum(a.sum() for a in arrays) / total
    centred = [a - mean for a in arrays]
    acov = np.array(
        [sum(float(a[k:] @ a[: len(a) - k]) for a in centred) / total for k in range(n_lags + 1)]
    )
    if acov[0] <= np.finfo(float).tiny:
        raise ValueError(
            "the series is constant, so its autocorrelation is undefined; "
            "a time-series model needs a varying error"
        )
    return acov / acov[0]


def partial_autocorrelation(acf: np.ndarray) -> np.ndarray:
    """PACF from an ACF by the Durbin-Levinson recursion (statsmodels ``levinson_durbin``).

    Parameters
    ----------
    acf : numpy.ndarray of shape (n_lags + 1,)
        Autocorrelations at lags 0..n_lags.

    Returns
    -------
    numpy.ndarray of shape (n_lags + 1,)
        Partial autocorrelations at lags 0..n_lags (1 at lag 0).
    """
    n_lags = len(acf) - 1
    return np.asarray(levinson_durbin(acf, nlags=n_lags, isacov=True).pacf, dtype=float)


def white_noise_band(n_samples: int) -> float:
    """Half-width 1.96 / sqrt(N) of the 95 % band of a white-noise correlation."""
    return BAND_QUANTILE / np.sqrt(n_samples)


def first_inside_lag(correlations: np.ndarray, band: float) -> int | None:
    """First lag >= 1 whose correlation lies inside the band (None if none does).

    Parameters
    ----------
    correlations : numpy.ndarray of shape (n_lags + 1,)
        ACF or PACF at lags 0..n_lags.
    band : float
        Half-width of the white-noise band.
    """
    inside = np.flatnonzero(np.abs(correlations[1:]) <= band)
    return int(inside[0]) + 1 if len(inside) else None


def cutoff_lag(correlations: np.ndarray, band: float, max_order: int) -> int | None:
    """Lag d at which a correlation sequence cuts off, or None if it tails.

    The sequence cuts off at d (0 <= d <= ``max_order``) when lags d + 1 and d + 2 are inside the
    band, at least 90 % of lags d + 1..n_lags are inside it, and the drop is abrupt: d = 0 or
    |r_d| >= 2 band widths. The smallest such d is returned. A sequence that only reaches the
    band after ``max_order`` lags, or creeps into it (a geometric decay), tails.

    Parameters
    ----------
    correlations, band : numpy.ndarray of shape (n_lags + 1,), float
        ACF or PACF at lags 0..n_lags, and the band's half-width (:func:`first_inside_lag`).
    max_order : int
        Largest order the cut-off may identify.

    Returns
    -------
    int or None
        The cut-off lag, or None if the sequence tails.
    """
    magnitude = np.abs(np.asarray(correlations, dtype=float))
    n_lags = len(magnitude) - 1
    for d in range(min(max_order, n_lags - 2) + 1):
        after = magnitude[d + 1 :]
        if after[0] > band or after[1] > band:
            continue
        if np.mean(after <= band) < INSIDE_FRACTION:
            continue
        return d if d == 0 or magnitude[d] >= ABRUPT_RATIO * band else None
    return None


def identification_lags(pieces: Sequence[np.ndarray], max_order: int) -> int:
    """Return the ACF/PACF lags to inspect: max(20, 2 max_order + 2), below the shortest piece."""
    shortest = min(len(piece) for piece in pieces)
    return max(2, min(max(20, 2 * max_order + 2), shortest - 1))


def identify(pieces: Sequence[np.ndarray], max_p: int, max_q: int) -> Identification:
    """Identify AR / MA / ARMA and the candidate orders from the ACF and PACF.

    Parameters
    ----------
    pieces : sequence of numpy.ndarray
        The zero-mean (stationary) series of each campaign.
    max_p, max_q : int
        Largest AR and MA orders to consider.

    Returns
    -------
    Identification
        Family and candidate (p, q) orders: AR with PACF cut-off d -> p in d-1..d+1, q = 0;
        MA with ACF cut-off d -> p = 0, q in d-1..d+1; both tailing -> p in 1..max_p and
        q in 1..max_q; both cutting off (ambiguous) -> p in 0..d_pacf, q in 0..d_acf;
        white noise -> (0, 0). Orders never exceed ``max_p`` / ``max_q``.
    """
    n_lags = identification_lags(pieces, max(max_p, max_q))
    acf = pooled_autocorrelation(pieces, n_lags)
    pacf = partial_autocorrelation(acf)
    band = white_noise_band(sum(len(piece) for piece in pieces))
    acf_cut = cutoff_lag(acf, band, max_q)
    pacf_cut = cutoff_lag(pacf, band, max_p)
    if acf_cut is None and pacf_cut is None:
        kind = "ARMA"
        grid = [(p, q) for p in range(1, max_p + 1) for q in range(1, max_q + 1)]
    elif acf_cut is None:
        kind = "AR"
        grid = [(p, 0) for p in _around(pacf_cut, max_p)]
    elif pacf_cut is None:
        kind = "MA"
        grid = [(0, q) for q in _around(acf_cut, max_q)]
    elif acf_cut == 0 and pacf_cut == 0:
        kind = "white noise"
        grid = [(0, 0)]
    else:
        kind = "ambiguous"
        grid = [(p, q) for p in range(pacf_cut + 1) for q in range(acf_cut + 1)]
    logger.debug("identified %s (ACF cut-off %s, PACF cut-off %s)", kind, acf_cut, pacf_cut)
    return Identification(kind, acf, pacf, float(band), acf_cut, pacf_cut, grid)


def _around(order: int, max_order: int) -> range:
    """Orders order-1..order+1 within 1..max_order (at least order 1)."""
    return range(max(1, order - 1), max(1, min(max_order, order + 1)) + 1)

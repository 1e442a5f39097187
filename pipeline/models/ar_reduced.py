"""High-order AR model reduced to the order at the knee of its AIC curve (the AR paper).

Source: the transmission-chain error paper (a Chinese study of AR models of a machine tool's
transmission-chain error, of which sections 4-5 are known, without authors, year or venue;
section 4): an AR(64) model serves diagnosis, but on-line prediction needs a short model. The
paper plots AIC against the order, takes the order where AIC turns from a fast to a slow decrease
("the turning point in the low-order region"), refits, and checks that the reduced model still
shows the main frequencies of the full one (AR(64) -> AR(9), keeping three of the four error
frequencies above 10 % of the error energy; an AR(p) can show at most p / 2 frequencies).

Model, per campaign with pre-sample error 0 um (the cold state)::

    y_t = c + sum_{i=1..p} a_i y_{t-i} + e_t

estimated by ordinary least squares on the per-campaign lagged designs stacked (no lag
reaches into another campaign). Every order uses the same rows, so AIC(p) = N ln(RSS_p / N)
+ 2 (p + 1) compares them fairly.

Deviations, and the rules the paper leaves unstated:

- Initial order: AR(``initial_order``) needs far more samples than a 110-sample campaign has,
  so it is capped at p_max = min(initial_order, N / 4, half the shortest campaign) (Box and
  Jenkins's N / 4 limit on useful lags; every lag then reaches real data in every campaign).
  ``chosen_params_["initial_order"]`` reports the cap used.
- Knee: on orders 1..p_aic (the AIC minimum), both axes scaled to [0, 1], the knee is the
  order farthest below the chord from AIC(1) to AIC(p_aic) (the "Kneedle" rule).
- Frequency check: the AR spectrum S(f) = sigma^2 / |1 - sum_k a_k exp(-i 2 pi f k)|^2
  (f in cycles per sample, 0..0.5) of the full model is split at its troughs into one band per
  peak (peaks at least 6 dB above their troughs: the ripple of a high-order spectrum is no
  frequency); a peak whose band holds at least ``energy_threshold`` of the total power is dominant
  (the paper's "error energy over 10 %"). From the knee upwards, the first order whose spectrum
  has a peak within ``frequency_tolerance`` of every dominant frequency is kept; if none does,
  the order keeping the most dominant frequencies (the lowest such) is kept.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.signal import find_peaks

from pipeline.fit_statistics import information_criteria
from pipeline.models.base import FeedbackModel
from pipeline.models.feedback import linear_feedback_predict
from pipeline.models.series import history, segments

logger = logging.getLogger(__name__)

#: Frequencies (cycles per sample) at which AR spectra are evaluated.
FREQUENCY_GRID = np.linspace(0.0, 0.5, 1001)
#: Least prominence (dB) of a spectral peak: ripples of a high-order AR spectrum are smaller.
PEAK_PROMINENCE_DB = 6.0


class ReducedOrderAR(FeedbackModel):
    """AR model of the thermal error reduced from a high order at the knee of the AIC curve.

    Uses no temperatures: X's columns are ignored, its index gives the campaigns.

    Parameters
    ----------
    initial_order : int, default 64
        Order of the full model (the AR paper's AR(64)), capped by the data length.
    energy_threshold : float, default 0.1
        Share of the full model's spectral power that makes a frequency dominant.
    frequency_tolerance : float, default 0.02
        Largest distance (cycles per sample) between a dominant frequency and a peak of the
        reduced model that still counts as kept.

    Attributes
    ----------
    intercept_ : float
        c (um).
    ar_ : numpy.ndarray of shape (p,)
        a_1..a_p of the kept order.
    aic_ : pandas.Series
        AIC of orders 1..p_max (index: order).
    dominant_frequencies_ : numpy.ndarray
        Dominant frequencies of the full model (cycles per sample).
    kept_frequencies_ : numpy.ndarray
        Those the reduced model reproduces.
    chosen_params_ : dict
        order, initial_order (cap used), knee_order, aic_min_order, n_dominant, n_kept,
        dominant_frequencies and kept_frequencies (comma-separated, cycles per sample).
    """

    min_columns = 0

    def __init__(
        self,
        initial_order: int = 64,
        energy_threshold: float = 0.1,
        frequency_tolerance: float = 0.02,
    ):
        self.initial_order = initial_order
        self.energy_threshold = energy_threshold
        self.frequency_tolerance = frequency_tolerance

    def _check_params(self) -> None:
        """Raise ValueError unless ``initial_order`` >= 1."""
        if int(self.initial_order) < 1:
            raise ValueError(f"initial_order must be >= 1, got {self.initial_order}")

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Fit AR(1..p_max), find the knee of AIC, check the frequencies, keep that order.

        Raises
        ------
        ValueError
            If the data are too short for an AR(1) model.
        """
        segs = segments(X)
        max_order = feasible_order(int(self.initial_order), segs)
        fits = ar_least_squares(target, segs, max_order)
        n = len(target)
        self.aic_ = aic_curve(fits, n)
        aic_min_order = int(self.aic_.idxmin())
        knee = knee_order(self.aic_.loc[:aic_min_order])
        full_frequencies = spectral_peaks(fits[-1][1], fits[-1][2] / n)
        dominant = full_frequencies.loc[
            full_frequencies["energy_share"] >= self.energy_threshold, "frequency"
        ].to_numpy()
        order, kept = self._check_frequencies(fits, knee, dominant, n)
        self.intercept_, self.ar_ = fits[order - 1][0], fits[order - 1][1]
        self.dominant_frequencies_ = dominant
        self.kept_frequencies_ = kept
        self.chosen_params_ = {
            "order": order,
            "initial_order": max_order,
            "knee_order": knee,
            "aic_min_order": aic_min_order,
            "n_dominant": len(dominant),
            "n_kept": len(kept),
            "dominant_frequencies": _join(dominant),
            "kept_frequencies": _join(kept),
        }
        logger.debug(
            "AR(%d) reduced to AR(%d) (knee %d); kept frequencies %s of %s",
            max_order,
            order,
            knee,
            _join(kept),
            _join(dominant),
        )

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Predict c plus the AR terms on the measured (free run: predicted) error, um."""
        base = np.full(len(X), self.intercept_)
        return linear_feedback_predict(base, self.ar_, segments(X), measured)

    def _check_frequencies(
        self,
        fits: Sequence[tuple[float, np.ndarray, float]],
        knee: int,
        dominant: np.ndarray,
        n: int,
    ) -> tuple[int, np.ndarray]:
        """First order >= knee keeping every dominant frequency (else the one keeping most)."""
        best_order, best_kept = knee, np.array([])
        for order in range(knee, len(fits) + 1):
            _, ar, rss = fits[order - 1]
            peaks = spectral_peaks(ar, rss / n)["frequency"].to_numpy()
            kept = np.array(
                [f for f in dominant if np.any(np.abs(peaks - f) <= self.frequency_tolerance)]
            )
            if len(kept) > len(best_kept) or order == knee:
                best_order, best_kept = order, kept
            if len(kept) == len(dominant):
                break
        return best_order, best_kept


def feasible_order(order: int, segs: Sequence[np.ndarray]) -> int:
    """Cap an AR order at N / 4 and at half the shortest campaign.

    Raises
    ------
    ValueError
        If not even AR(1) is feasible.
    """
    n = sum(len(rows) for rows in segs)
    shortest = min(len(rows) for rows in segs)
    capped = min(order, n // 4, shortest // 2)
    if capped < 1:
        raise ValueError(
            f"{n} samples in campaigns as short as {shortest} are too few for an AR model; "
            "fit on at least 4 samples per campaign"
        )
    return capped


def ar_least_squares(
    target: np.ndarray, segs: Sequence[np.ndarray], max_order: int
) -> list[tuple[float, np.ndarray, float]]:
    """Fit y_t = c + sum_{i<=p} a_i y_{t-i} by OLS for p = 1..max_order on the same rows.

    Parameters
    ----------
    target : numpy.ndarray of shape (n,)
        Thermal error (um).
    segs : sequence of numpy.ndarray
        Row positions of each campaign; lags restart in each with pre-sample error 0.
    max_order : int
        Highest order.

    Returns
    -------
    list of tuple
        For each order p: (c in um, a of shape (p,), residual sum of squares in um^2).
    """
    lags = history(target, list(segs), max_order)
    fits = []
    for order in range(1, max_order + 1):
        design = np.column_stack([np.ones(len(target)), lags[:, :order]])
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        residual = target - design @ coef
        fits.append((float(coef[0]), coef[1:], float(residual @ residual)))
    return fits


def aic_curve(fits: Sequence[tuple[float, np.ndarray, float]], n: int) -> pd.Series:
    """AIC(p) = N ln(RSS_p / N) + 2 (p + 1) of :func:`ar_least_squares` fits, indexed by p."""
    rss = np.array([max(fit[2], np.finfo(float).tiny) for fit in fits])
    orders = np.arange(1, len(fits) + 1)
    aic, _, _ = information_criteria(rss, n, orders + 1)
    return pd.Series(aic, index=pd.Index(orders, name="order"))


def knee_order(aic: pd.Series) -> int:
    """Order farthest below the chord of a decreasing AIC curve (both axes scaled to [0, 1]).

    Parameters
    ----------
    aic : pandas.Series
        AIC indexed by order 1..p, p being the AIC minimum.

    Returns
    -------
    int
        The knee order (the first order if the curve has fewer than three points or is flat).
    """
    orders = aic.index.to_numpy(dtype=float)
    values = aic.to_numpy(dtype=float)
    drop = values[0] - values[-1]
    if len(values) < 3 or drop <= 0:
        return int(orders[0])
    x = (orders - orders[0]) / (orders[-1] - orders[0])
    a = (values - values[-1]) / drop
    return int(orders[np.argmax(1.0 - x - a)])


def ar_spectrum(ar: np.ndarray, sigma2: float) -> np.ndarray:
    """AR power spectrum sigma^2 / |1 - sum_k a_k exp(-i 2 pi f k)|^2 on ``FREQUENCY_GRID``.

    Parameters
    ----------
    ar : numpy.ndarray of shape (p,)
        AR coefficients.
    sigma2 : float
        Innovation variance (um^2).

    Returns
    -------
    numpy.ndarray of shape (len(FREQUENCY_GRID),)
        Power spectral density (um^2 per cycle/sample).
    """
    k = np.arange(1, len(ar) + 1)
    transfer = 1.0 - np.exp(-2j * np.pi * np.outer(FREQUENCY_GRID, k)) @ np.asarray(ar)
    return sigma2 / np.abs(transfer) ** 2


def spectral_peaks(ar: np.ndarray, sigma2: float) -> pd.DataFrame:
    """Peaks of an AR spectrum and the share of the total power in each peak's band.

    Peaks are local maxima of the log spectrum standing at least ``PEAK_PROMINENCE_DB`` above
    the surrounding troughs (smaller ripples of a high-order spectrum are not frequencies of
    their own); 0 and 0.5 cycles per sample count when the spectrum falls away from them.
    Neighbouring peaks' bands meet at the lowest point between them.

    Parameters
    ----------
    ar, sigma2 : numpy.ndarray of shape (p,), float
        AR coefficients and innovation variance (um^2) of :func:`ar_spectrum`.

    Returns
    -------
    pandas.DataFrame
        Columns ``frequency`` (cycles per sample) and ``energy_share`` (0..1), by frequency.
    """
    power = ar_spectrum(ar, sigma2)
    # The spectrum is even about 0 and 0.5: extend it by its mirror images so that peaks at
    # the ends get their true prominence, then keep the peaks inside 0..0.5.
    n_grid = len(power)
    extended = np.r_[power[:0:-1], power, power[-2::-1]]
    found = find_peaks(10.0 * np.log10(extended), prominence=PEAK_PROMINENCE_DB)[0]
    peaks = found[(found >= n_grid - 1) & (found < 2 * n_grid - 1)] - (n_grid - 1)
    bounds = [0]
    for left, right in zip(peaks[:-1], peaks[1:], strict=True):
        bounds.append(left + int(np.argmin(power[left : right + 1])))
    bounds.append(len(power))
    total = power.sum()
    shares = [power[bounds[i] : bounds[i + 1]].sum() / total for i in range(len(peaks))]
    return pd.DataFrame({"frequency": FREQUENCY_GRID[peaks], "energy_share": shares})


def _join(frequencies: np.ndarray) -> str:
    """Frequencies as a comma-separated string with 4 decimals (an MLflow param)."""
    return ",".join(f"{f:.4f}" for f in frequencies)

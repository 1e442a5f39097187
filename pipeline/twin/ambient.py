"""Workshop air temperature: a season mean plus a daily cycle, or a measured series.

Any object with ``at(t_s) -> degC`` (t in seconds since the campaign start, may be negative for
the idle pre-roll before the start) can drive the twin: :class:`AmbientProfile` (the synthetic
law) or :class:`AmbientSeries` (e.g. a campaign's own ambient sensor, for the discrepancy
workflow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime
from typing import Protocol

import numpy as np

from schemas.vocabulary import SEASON_OF_MONTH


class Ambient(Protocol):
    """Anything that gives the ambient air temperature at given instants."""

    def at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Air temperature, degC, same shape as ``t_s`` (s since the campaign start)."""
        ...


@dataclass(frozen=True)
class AmbientProfile:
    """``T_amb(t) = mean + drift t + A cos(2 pi (hour(t) - peak_hour) / 24)``.

    Attributes
    ----------
    mean_degc : float
        Daily mean of the workshop air, degC (season dependent).
    daily_amplitude_k : float
        Half peak-to-peak of the daily cycle, K.
    start_hour : float
        Local time of day of the campaign start, hours (8.5 = 08:30).
    peak_hour : float
        Local time of the daily maximum, hours (mid-afternoon in an unconditioned workshop).
    drift_k_per_h : float
        Slow linear drift of the daily mean (weather change), K/h.
    """

    mean_degc: float
    daily_amplitude_k: float = 0.0
    start_hour: float = 8.5
    peak_hour: float = 15.0
    drift_k_per_h: float = 0.0

    def at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Air temperature, degC, same shape as ``t_s`` (s since the campaign start)."""
        t_h = np.asarray(t_s, dtype=float) / 3600.0
        phase = 2.0 * math.pi * (self.start_hour + t_h - self.peak_hour) / 24.0
        return self.mean_degc + self.drift_k_per_h * t_h + self.daily_amplitude_k * np.cos(phase)


@dataclass(frozen=True)
class AmbientSeries:
    """A measured air temperature, linearly interpolated (held constant outside the samples).

    Attributes
    ----------
    elapsed_s : tuple of float
        Sample instants, s since the campaign start, increasing.
    values_degc : tuple of float
        Air temperature at those instants, degC.
    """

    elapsed_s: tuple[float, ...]
    values_degc: tuple[float, ...]

    def at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Air temperature, degC, same shape as ``t_s``."""
        return np.interp(np.asarray(t_s, dtype=float), self.elapsed_s, self.values_degc)


@dataclass(frozen=True)
class Climate:
    """Workshop climate over the year, from which a campaign's :class:`AmbientProfile` is drawn.

    An unconditioned workshop in a humid subtropical climate (the PCDL paper's machine is in
    Hefei; its 12 batches span the four seasons). Values are illustrative, not measured.

    Attributes
    ----------
    monthly_mean_degc : tuple of 12 float
        Mean workshop air per month (January first), degC.
    monthly_amplitude_k : tuple of 12 float
        Daily half-amplitude per month, K.
    peak_hour : float
        Local time of the daily maximum, hours.
    mean_jitter_k : float
        Standard deviation of a campaign day's mean around the month mean, K.
    amplitude_jitter_rel : float
        Relative standard deviation of a day's amplitude.
    peak_jitter_h : float
        Standard deviation of the peak hour, hours.
    drift_sd_k_per_h : float
        Standard deviation of the day's slow drift, K/h.
    """

    monthly_mean_degc: tuple[float, ...] = (
        8.0,
        10.0,
        14.0,
        19.0,
        23.0,
        27.0,
        30.0,
        29.5,
        26.0,
        21.0,
        15.0,
        10.0,
    )
    monthly_amplitude_k: tuple[float, ...] = (
        1.8,
        2.0,
        2.5,
        3.0,
        3.0,
        3.0,
        3.2,
        3.2,
        3.0,
        2.6,
        2.2,
        1.8,
    )
    peak_hour: float = 15.0
    mean_jitter_k: float = 1.0
    amplitude_jitter_rel: float = 0.1
    peak_jitter_h: float = 0.5
    drift_sd_k_per_h: float = 0.1

    def profile(self, start: datetime, rng: np.random.Generator) -> AmbientProfile:
        """Draw the ambient of a campaign starting at ``start`` (local time).

        Parameters
        ----------
        start : datetime
            Local time of the first sample; its month picks the season mean.
        rng : numpy.random.Generator
            The campaign's own generator (4 draws).
        """
        m = start.month - 1
        return AmbientProfile(
            mean_degc=self.monthly_mean_degc[m] + self.mean_jitter_k * rng.standard_normal(),
            daily_amplitude_k=self.monthly_amplitude_k[m]
            * (1.0 + self.amplitude_jitter_rel * rng.standard_normal()),
            start_hour=start.hour + start.minute / 60.0,
            peak_hour=self.peak_hour + self.peak_jitter_h * rng.standard_normal(),
            drift_k_per_h=self.drift_sd_k_per_h * rng.standard_normal(),
        )


def season_of(start: datetime) -> str:
    """Meteorological season of a date (northern hemisphere): Dec-Feb winter, etc."""
    return SEASON_OF_MONTH[start.month]


@dataclass(frozen=True)
class WeatherAmbient:
    """A daily-cycle profile plus a slow weather wander: ``T(t) = profile(t) + w(t)``.

    ``w`` is piecewise linear through its knots (a random walk drawn by
    :func:`draw_weather`) and held constant outside them; it models the day-to-day change of
    the weather an unconditioned workshop follows over a run of several days, which a single
    linear drift (:attr:`AmbientProfile.drift_k_per_h`) cannot do for long.

    Attributes
    ----------
    profile : AmbientProfile
        Season mean and daily cycle (its ``drift_k_per_h`` adds to the wander).
    knots_s : tuple of float
        Knot instants of the wander, s since the start, increasing.
    wander_k : tuple of float
        Wander at the knots, K.
    """

    profile: AmbientProfile
    knots_s: tuple[float, ...]
    wander_k: tuple[float, ...]

    def at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Air temperature, degC, same shape as ``t_s`` (s since the start)."""
        t = np.asarray(t_s, dtype=float)
        return self.profile.at(t) + np.interp(t, self.knots_s, self.wander_k)


def draw_weather(
    profile: AmbientProfile,
    from_s: float,
    to_s: float,
    rng: np.random.Generator,
    *,
    knot_h: float = 6.0,
    sd_k_per_sqrt_h: float = 0.2,
) -> WeatherAmbient:
    """Draw a weather wander over ``[from_s, to_s]`` on top of ``profile``.

    The wander is a Gaussian random walk sampled every ``knot_h`` hours (standard deviation
    ``sd_k_per_sqrt_h * sqrt(knot_h)`` per knot), shifted so that it is 0 at t = 0: the
    profile's mean stays the air's daily mean at the start. With the defaults the daily mean
    wanders by about 1 K (1 sd) over two days, an engineering estimate for an unconditioned
    workshop in spring or autumn (no measurement behind it).

    Parameters
    ----------
    profile : AmbientProfile
    from_s, to_s : float
        Time span to cover, s since the start (from_s < 0 covers the pre-roll).
    rng : numpy.random.Generator
        One normal draw per knot.
    knot_h : float
        Knot spacing, h.
    sd_k_per_sqrt_h : float
        Random-walk intensity, K/sqrt(h).

    Returns
    -------
    WeatherAmbient
    """
    if not to_s > from_s or knot_h <= 0:
        raise ValueError("draw_weather: need to_s > from_s and knot_h > 0")
    step_s = knot_h * 3600.0
    knots = from_s + step_s * np.arange(int(np.ceil((to_s - from_s) / step_s)) + 1)
    walk = np.cumsum(sd_k_per_sqrt_h * np.sqrt(knot_h) * rng.standard_normal(knots.size))
    walk -= np.interp(0.0, knots, walk)
    return WeatherAmbient(profile, tuple(knots.tolist()), tuple(walk.tolist()))

"""Measurement chain of the workshop preset: placed sensors, eddy-current probes, speed log.

The demo's sensors each read one node of the twin (:class:`~pipeline.twin.params.SensorSpec`).
A user's own installation is less tidy: a sensor glued between two parts reads a mix of them,
air sensors sit in a stratified workshop, and the eddy-current probes and their holder on the
table drift with temperature and time. This module models that chain on a regular sampling
grid; every random draw comes from the caller's generator, in a fixed order.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from pipeline.thermal.program import Program

AIR = "ambient"
"""Pseudo-node name of the workshop air the structure sees (column ``ambient_degC``)."""


def first_order_lag(u: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """Output of ``tau dS/dt = u - S`` for an input sampled every ``dt_s``.

    Exact when ``u`` is linear between samples (first-order hold)::

        S[k+1] = a S[k] + b0 u[k+1] + b1 u[k],  a = exp(-dt / tau),
        b0 = 1 - tau (1 - a) / dt,  b1 = tau (1 - a) / dt - a.

    The lag starts in the state it would have after following the initial slope of ``u`` for a
    long time, ``S[0] = u[0] - tau (u[1] - u[0]) / dt`` (exact for a ramp), so a sensor that has
    been tracking the slow daily cycle does not start with a spurious transient.

    Parameters
    ----------
    u : ndarray of shape (n,)
        Input (e.g. temperature, degC), n >= 2.
    tau_s : float
        Time constant, s (> 0).
    dt_s : float
        Sampling interval, s (> 0).

    Returns
    -------
    ndarray of shape (n,)
    """
    u = np.asarray(u, dtype=float)
    if tau_s <= 0 or dt_s <= 0 or u.ndim != 1 or u.size < 2:
        raise ValueError(
            "first_order_lag: need tau_s > 0, dt_s > 0 and a 1-d input of >= 2 samples"
        )
    a = float(np.exp(-dt_s / tau_s))
    b0 = 1.0 - tau_s * (1.0 - a) / dt_s
    b1 = tau_s * (1.0 - a) / dt_s - a
    s0 = u[0] - tau_s * (u[1] - u[0]) / dt_s
    rest, _ = lfilter([b0, b1], [1.0, -a], u[1:], zi=[b1 * u[0] + a * s0])
    return np.concatenate([[s0], rest])


@dataclass(frozen=True)
class PlacedSensor:
    """A temperature sensor where a user put it: on a part, between two parts, or in the air.

    Only ``name``, ``role``, ``location`` (when not None) and ``type`` are written to
    campaign.yaml; the rest is the truth of the simulation.

    Attributes
    ----------
    name : str
        Column name in temperature.csv (``"T1"``...).
    mix : tuple of (str, float)
        Nodes of the network (or ``"ambient"`` for the air) and their weights, summing to 1:
        a sensor on the joint of two parts reads a weighted mean of both.
    tau_s : float
        First-order time constant of the mounting, s (with ``sensor_lag``).
    bias_k : float
        Constant difference to the mix, K (air stratification: cooler near the floor, warmer
        under the roof).
    place : str
        Where it really is, in words (never written).
    role : str
        Contract role written to campaign.yaml.
    type : str
        Sensor model written to campaign.yaml.
    location : str or None
        Location written to campaign.yaml; None = not declared (the user did not say).
    """

    name: str
    mix: tuple[tuple[str, float], ...]
    tau_s: float
    bias_k: float = 0.0
    place: str = ""
    role: str = "other"
    type: str = "DS18B20"
    location: str | None = None

    def __post_init__(self) -> None:
        """Check the weights sum to 1 and the time constant is positive."""
        total = sum(w for _, w in self.mix)
        if not self.mix or abs(total - 1.0) > 1e-9 or min(w for _, w in self.mix) < 0:
            raise ValueError(f"sensor {self.name}: mix weights must be >= 0 and sum to 1")
        if self.tau_s <= 0:
            raise ValueError(f"sensor {self.name}: tau_s must be > 0 s")

    def true_temperature(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """Temperature at the sensor's place (before its mounting lag), degC.

        Parameters
        ----------
        columns : mapping of str to ndarray of shape (n_t,)
            ``node_<name>`` (degC) for every node in the mix and ``ambient_degC``.
        """
        keys = {name: "ambient_degC" if name == AIR else f"node_{name}" for name, _ in self.mix}
        return self.bias_k + sum(w * np.asarray(columns[keys[n]]) for n, w in self.mix)


def sensed_temperatures(
    columns: Mapping[str, np.ndarray],
    sensors: tuple[PlacedSensor, ...],
    dt_s: float,
    lagged: bool,
) -> np.ndarray:
    """Return what each sensing element sees: its place, through its mounting lag, degC.

    Parameters
    ----------
    columns : mapping of str to ndarray of shape (n_t,)
        Node temperatures and air, see :meth:`PlacedSensor.true_temperature`.
    sensors : tuple of PlacedSensor
    dt_s : float
        Sampling interval of the columns, s.
    lagged : bool
        Apply each sensor's first-order lag (the ``sensor_lag`` effect).

    Returns
    -------
    ndarray of shape (n_t, n_sensors), degC (noise-free, no calibration offset)
    """
    values = [s.true_temperature(columns) for s in sensors]
    if lagged:
        values = [first_order_lag(v, s.tau_s, dt_s) for v, s in zip(values, sensors, strict=True)]
    return np.column_stack(values)


@dataclass(frozen=True)
class EddyCurrentProbe:
    """Reading chain of one eddy-current displacement probe and its holder on the table.

    ``reading = quantise(true + offset + c (T_h - T_h(0)) + walk + noise)``, um, with ``T_h``
    the holder temperature: a first-order lag (``holder_tau_s``) of a mix of the bed and the
    air (``holder_bed_share``). Values are engineering estimates for an industrial probe
    (1-2 mm range, 0.1 um display resolution) in a steel holder ~40 mm long (11.5e-6 1/K x
    40 mm = 0.46 um/K) plus the electronics' own temperature coefficient; no data sheet behind
    them.

    Attributes
    ----------
    noise_sd_um : float
        Standard deviation of the white reading noise, um.
    resolution_um : float
        Quantisation step of the reading, um.
    tc_range_um_per_k : tuple of (float, float)
        Range of the magnitude of the temperature coefficient of probe and holder, um/K; each
        probe draws one uniformly. The sign is negative: a warmer holder brings the probe
        closer to the target, which reads as the tool moving towards the probe.
    walk_um_per_sqrt_h : float
        Intensity of the electronics' random-walk drift, um/sqrt(h) (0.15 gives about 1 um,
        1 sd, over 46 h).
    offset_sd_um : float
        Standard deviation of the constant offset of the raw reading (the gap set when
        mounting), um.
    holder_bed_share : float
        Share of the bed in the temperature the holder follows (rest: air), 0..1.
    holder_tau_s : float
        Time constant of the holder (a steel bracket on the table), s.
    """

    noise_sd_um: float = 0.3
    resolution_um: float = 0.1
    tc_range_um_per_k: tuple[float, float] = (0.2, 0.6)
    walk_um_per_sqrt_h: float = 0.15
    offset_sd_um: float = 20.0
    holder_bed_share: float = 0.5
    holder_tau_s: float = 2700.0

    def holder_temperature(
        self, bed_degc: np.ndarray, air_degc: np.ndarray, dt_s: float
    ) -> np.ndarray:
        """Temperature of the probe holder on the table, degC, shape (n_t,)."""
        mix = self.holder_bed_share * np.asarray(bed_degc) + (1.0 - self.holder_bed_share) * (
            np.asarray(air_degc)
        )
        return first_order_lag(mix, self.holder_tau_s, dt_s)

    def read(
        self,
        true_um: np.ndarray,
        holder_degc: np.ndarray,
        dt_s: float,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """Pass a true displacement through the probe.

        Parameters
        ----------
        true_um : ndarray of shape (n_t,), um
            Tool displacement along the probe's axis (contract sign).
        holder_degc : ndarray of shape (n_t,), degC
            Holder temperature (:meth:`holder_temperature`).
        dt_s : float
            Sampling interval, s.
        rng : numpy.random.Generator
            Draws, in order: 1 normal (offset), 1 uniform (coefficient), n_t normal (walk),
            n_t normal (noise).

        Returns
        -------
        ndarray of shape (n_t,), um, multiples of ``resolution_um``.
        """
        n = np.size(true_um)
        offset = self.offset_sd_um * rng.standard_normal()
        coefficient = -rng.uniform(*self.tc_range_um_per_k)
        step_sd = self.walk_um_per_sqrt_h * np.sqrt(dt_s / 3600.0)
        walk = np.cumsum(step_sd * rng.standard_normal(n))
        walk -= walk[0]
        noise = self.noise_sd_um * rng.standard_normal(n)
        value = true_um + offset + coefficient * (holder_degc - holder_degc[0]) + walk + noise
        return np.round(value / self.resolution_um) * self.resolution_um


def speed_log(
    program: Program, times_s: np.ndarray, noise_rel: float, rng: np.random.Generator
) -> np.ndarray:
    """Measured spindle speed: the commanded speed with relative noise, 0 when stopped.

    Parameters
    ----------
    program : Program
        Commanded speed, rpm.
    times_s : ndarray of shape (n_t,), s
    noise_rel : float
        Relative standard deviation of the reading (0.003 = 0.3 %, a drive's speed display).
    rng : numpy.random.Generator
        n_t normal draws.

    Returns
    -------
    ndarray of shape (n_t,), rpm, rounded to 1 rpm.
    """
    commanded = program.value_at(times_s)
    return np.round(commanded * (1.0 + noise_rel * rng.standard_normal(np.size(times_s))))

"""Linear-axis (Y) positioning twin: geometric error plus a thermal slope from the ball screw.

Follows the Chinese invention patent "Optimal selection method for the thermal
temperature-sensitive points of a machine tool's linear axis based on independent-variable
selection criteria" (published 2022): the cold machine's laser run carries the geometric error
(a 4th-order polynomial over position); warming the axis by moving it makes the error grow
linearly with position, with a slope k (um/mm) that follows the screw/nut temperatures. Here
``k = alpha_steel * (T_screw(t) - T_screw(0))`` (1e-3 alpha um/(mm K) = 0.0115 um/(mm K)),
plus a small position-independent offset from the fixed-end bearing block, a periodic lead
error and a reversal between + and - runs. The truth is returned in memory
(:class:`AxisTruth`) so tests can check that the pipeline's separation recovers it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from pipeline.thermal.program import Program
from pipeline.twin.params import AxisParams
from pipeline.twin.simulate import machine_frame, simulate_machine


@dataclass(frozen=True)
class AxisTruth:
    """What the laser campaign was generated from.

    Attributes
    ----------
    geometric_coeffs_um : tuple of 5 float
        Polynomial c0..c4 (ascending powers of x in mm; um).
    periodic_amplitude_um, periodic_period_mm, periodic_phase_rad : float
        Periodic lead error ``P sin(2 pi x / lambda + phi)``.
    reversal_um : float
        + run minus - run, um.
    passes : pandas.DataFrame
        One row per pass: ``elapsed_min``, ``slope_um_per_mm`` (true thermal slope k),
        ``offset_um`` (true thermal offset b), ``screw_rise_K``.
    """

    geometric_coeffs_um: tuple[float, ...]
    periodic_amplitude_um: float
    periodic_period_mm: float
    periodic_phase_rad: float
    reversal_um: float
    passes: pd.DataFrame

    def polynomial_um(self, x_mm: np.ndarray) -> np.ndarray:
        """Return the polynomial part of the geometric error at ``x_mm``, um."""
        return np.polynomial.polynomial.polyval(
            np.asarray(x_mm, dtype=float), self.geometric_coeffs_um
        )

    def periodic_um(self, x_mm: np.ndarray) -> np.ndarray:
        """Return the periodic lead error at ``x_mm``, um."""
        x = np.asarray(x_mm, dtype=float)
        return self.periodic_amplitude_um * np.sin(
            2.0 * np.pi * x / self.periodic_period_mm + self.periodic_phase_rad
        )

    def geometric_um(self, x_mm: np.ndarray) -> np.ndarray:
        """Return the full geometric error (polynomial + periodic, bidirectional mean), um."""
        return self.polynomial_um(x_mm) + self.periodic_um(x_mm)

    def thermal_um(self, x_mm: np.ndarray, elapsed_min: float) -> np.ndarray:
        """Return the true thermal error ``k x + b`` of the pass at ``elapsed_min``, um."""
        row = self.passes.loc[np.isclose(self.passes["elapsed_min"], elapsed_min)]
        if row.empty:
            raise KeyError(f"no pass at {elapsed_min} min; passes: {list(self.passes.elapsed_min)}")
        k = float(row["slope_um_per_mm"].iloc[0])
        b = float(row["offset_um"].iloc[0])
        return k * np.asarray(x_mm, dtype=float) + b


def simulate_axis(
    params: AxisParams,
    effects: Iterable[str],
    program: Program | Sequence[Mapping[str, Any]] | float,
    ambient: Any,
    times_s: np.ndarray,
    *,
    method: str = "expm",
    preroll_h: float = 72.0,
    history: Program | Sequence[Mapping[str, Any]] | None = None,
) -> pd.DataFrame:
    """Simulate the axis network, its noise-free sensors and its thermal slope and offset.

    Parameters
    ----------
    params : AxisParams
    effects : iterable of str
        Effect names; only ``ambient_variation`` and ``sensor_lag`` apply to the axis.
    program : Program, list of dict or float
        Warm-up feed, mm/s (contract-like list uses the key ``feed_mm_s``).
    ambient : object with ``at(t_s)``
    times_s : array-like of shape (n_t,), s
    method, preroll_h, history
        As in :func:`pipeline.twin.spindle.simulate_spindle` (history: feed before the start).

    Returns
    -------
    pandas.DataFrame
        ``elapsed_s``, ``feed_mm_s``, ``ambient_degC``, ``node_<name>`` (degC), sensor columns
        ``T1``... (noise-free), ``screw_rise_K``, ``slope_um_per_mm`` (k), ``offset_um`` (b).
    """
    machine = simulate_machine(
        "axis",
        params,
        effects,
        program,
        "feed_mm_s",
        ambient,
        times_s,
        method=method,
        preroll_h=preroll_h,
        history=history,
    )
    net = params.network
    screw_rise = machine.rise_k[:, net.index("screw")]
    bearing_rise = machine.rise_k[:, net.index("screw_bearing")]
    return machine_frame(
        machine,
        {
            "screw_rise_K": screw_rise,
            "slope_um_per_mm": 1e3 * params.alpha_steel_per_k * screw_rise,
            "offset_um": (
                1e3 * params.alpha_steel_per_k * params.bearing_offset_length_mm * bearing_rise
            ),
        },
    )


def laser_runs(
    params: AxisParams,
    truth: AxisTruth,
    rng: np.random.Generator,
) -> pd.DataFrame:
    """Bidirectional laser runs, one + and one - run per pass, with interferometer noise.

    Parameters
    ----------
    params : AxisParams
        Stroke, step and noise.
    truth : AxisTruth
        Geometric error, reversal and per-pass slope/offset.
    rng : numpy.random.Generator
        Draws the reading noise (one normal per reading, in row order).

    Returns
    -------
    pandas.DataFrame
        ``elapsed_min, run, direction, target_mm, deviation_um`` (laser.csv columns); runs
        numbered from 1, + (ascending targets) then - (descending) for each pass.
    """
    targets = np.arange(0.0, params.stroke_mm + 0.5 * params.step_mm, params.step_mm)
    frames = []
    run = 0
    for elapsed_min in truth.passes["elapsed_min"]:
        thermal = truth.thermal_um(targets, float(elapsed_min))
        for sign, direction, order in ((1.0, "+", targets), (-1.0, "-", targets[::-1])):
            run += 1
            idx = np.searchsorted(targets, order)
            dev = (
                truth.geometric_um(order)
                + sign * 0.5 * truth.reversal_um
                + thermal[idx]
                + params.laser_noise_um * rng.standard_normal(order.size)
            )
            frames.append(
                pd.DataFrame(
                    {
                        "elapsed_min": float(elapsed_min),
                        "run": run,
                        "direction": direction,
                        "target_mm": order,
                        "deviation_um": dev,
                    }
                )
            )
    return pd.concat(frames, ignore_index=True)


def axis_truth(params: AxisParams, sim: pd.DataFrame, passes_min: Sequence[float]) -> AxisTruth:
    """Collect the truth of a campaign from the simulation at the pass instants.

    Parameters
    ----------
    params : AxisParams
    sim : pandas.DataFrame
        Output of :func:`simulate_axis` whose ``elapsed_s`` include every pass instant.
    passes_min : sequence of float
        Pass times, minutes since the start.
    """
    at = sim.set_index("elapsed_s")
    t = np.asarray(passes_min, dtype=float) * 60.0
    missing = [x for x in t if x not in at.index]
    if missing:
        raise ValueError(f"axis_truth: simulation lacks the pass instants {missing} s")
    passes = pd.DataFrame(
        {
            "elapsed_min": np.asarray(passes_min, dtype=float),
            "slope_um_per_mm": at.loc[t, "slope_um_per_mm"].to_numpy(),
            "offset_um": at.loc[t, "offset_um"].to_numpy(),
            "screw_rise_K": at.loc[t, "screw_rise_K"].to_numpy(),
        }
    )
    return AxisTruth(
        geometric_coeffs_um=tuple(params.geometric_coeffs_um),
        periodic_amplitude_um=params.periodic_amplitude_um,
        periodic_period_mm=params.periodic_period_mm,
        periodic_phase_rad=params.periodic_phase_rad,
        reversal_um=params.reversal_um,
        passes=passes,
    )

"""Spindle Z-drift twin of a vertical machining centre.

Nine lumped nodes (front and rear bearing, spindle sleeve, motor, headstock, column front and
rear, bed, Z screw) heated by the spindle-speed program (and any external heat loads),
convection to the workshop air; the Z drift at the spindle nose is the sum of the model's
displacement terms. Which terms are in the model is set by the effect names
(:mod:`pipeline.thermal.effects`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from pipeline.thermal.effects import slot_terms
from pipeline.thermal.loads import HeatLoad
from pipeline.thermal.program import Program
from pipeline.twin.params import SpindleParams
from pipeline.twin.simulate import machine_frame, simulate_machine


def simulate_spindle(
    params: SpindleParams,
    effects: Iterable[str],
    program: Program | Sequence[Mapping[str, Any]] | float,
    ambient: Any,
    times_s: np.ndarray,
    *,
    method: str = "expm",
    preroll_h: float = 72.0,
    history: Program | Sequence[Mapping[str, Any]] | None = None,
    heat_loads: Sequence[HeatLoad] | Sequence[Mapping[str, Any]] = (),
) -> pd.DataFrame:
    """Simulate node temperatures, noise-free sensor readings and the Z drift.

    Parameters
    ----------
    params : SpindleParams
        Machine parameters.
    effects : iterable of str
        Effects switched on (names from :data:`pipeline.thermal.effects.EFFECTS`); empty = the
        baseline.
    program : Program, list of dict or float
        Spindle speed, rpm: a :class:`Program`, the contract's ``spindle_program`` list, or a
        constant speed.
    ambient : object with ``at(t_s)``
        :class:`~pipeline.twin.ambient.AmbientProfile` or
        :class:`~pipeline.twin.ambient.AmbientSeries`; t in s since the start.
    times_s : array-like of shape (n_t,), s
        Output instants since the start, >= 0, increasing.
    method : str
        ``"expm"`` (exact) or a stiff ``solve_ivp`` method (``"Radau"``, ``"BDF"``, ``"LSODA"``).
    preroll_h : float
        Hours simulated before the start (the machine follows the ambient law of the model).
    history : Program or list of dict, optional
        Spindle speed before the start (negative ``from_min``, e.g. the previous day's work,
        within ``preroll_h``); None = idle, so the machine starts cold.
    heat_loads : sequence of HeatLoad or of dict
        External heat loads (or the contract's ``heat_loads`` entries), W, each into the node
        read by the sensors of its role (``column_rear`` -> ``column_rear``, ``ball_screw`` ->
        ``z_screw``); empty = none, the result unchanged.

    Returns
    -------
    pandas.DataFrame
        One row per instant: ``elapsed_s`` (s), ``rpm``, ``ambient_degC``, ``node_<name>``
        (degC, one per network node), the sensor columns as named in ``params.sensors``
        (``T1``...; noise-free readings, no offset), ``z_<term>_um`` per displacement term and
        ``z_um`` (their sum; um, positive = tool away from the table). ``attrs["effects"]``
        lists the effects on, ``attrs["terms"]`` the model's term names.
    """
    machine = simulate_machine(
        "spindle",
        params,
        effects,
        program,
        "rpm",
        ambient,
        times_s,
        method=method,
        preroll_h=preroll_h,
        history=history,
        loads=heat_loads,
    )
    z_parts = {
        f"z_{term.name}_um": np.asarray(
            term.func(params, machine.rise_k, machine.run.drive), dtype=float
        )
        for term in slot_terms(machine.terms, "displacement")
    }
    z = sum(z_parts.values(), np.zeros(machine.run.times_s.size))
    return machine_frame(machine, {**z_parts, "z_um": z})

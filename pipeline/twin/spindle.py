"""Spindle Z-drift twin of a vertical machining centre.

Nine lumped nodes (front and rear bearing, spindle sleeve, motor, headstock, column front and
rear, bed, Z screw) heated by the spindle-speed program, convection to the workshop air; the Z
drift at the spindle nose is the sum of the model's displacement terms. Which terms are in the
model is set by the effect names (:mod:`pipeline.twin.effects`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from pipeline.twin.effects import check_effects, model_terms, slot_terms
from pipeline.twin.params import SpindleParams
from pipeline.twin.program import Program
from pipeline.twin.simulate import run_network


def as_program(program: Program | Sequence[Mapping[str, Any]] | float, key: str) -> Program:
    """Accept a :class:`Program`, a contract list ``[{from_min, to_min?, key}]`` or a constant."""
    if isinstance(program, Program):
        return program
    if isinstance(program, int | float):
        return Program.constant(float(program), key=key)
    return Program.from_contract(program, key=key)


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
) -> pd.DataFrame:
    """Simulate node temperatures, noise-free sensor readings and the Z drift.

    Parameters
    ----------
    params : SpindleParams
        Machine parameters.
    effects : iterable of str
        Effects switched on (names from :data:`pipeline.twin.effects.EFFECTS`); empty = the
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

    Returns
    -------
    pandas.DataFrame
        One row per instant: ``elapsed_s`` (s), ``rpm``, ``ambient_degC``, ``node_<name>``
        (degC, one per network node), the sensor columns as named in ``params.sensors``
        (``T1``...; noise-free readings, no offset), ``z_<term>_um`` per displacement term and
        ``z_um`` (their sum; um, positive = tool away from the table). ``attrs["effects"]``
        lists the effects on, ``attrs["terms"]`` the model's term names.
    """
    names = check_effects(effects)
    terms = model_terms("spindle", names)
    prog = as_program(program, key="rpm")
    past = None if history is None else as_program(history, key=prog.key)
    run = run_network(
        params, terms, prog, ambient, times_s, method=method, preroll_h=preroll_h, history=past
    )
    rise = run.nodes_degc - run.start_degc
    cols: dict[str, np.ndarray] = {
        "elapsed_s": run.times_s,
        "rpm": run.drive,
        "ambient_degC": run.ambient_degc,
    }
    for j, node in enumerate(params.network.nodes):
        cols[f"node_{node}"] = run.nodes_degc[:, j]
    for j, sensor in enumerate(params.sensors):
        cols[sensor.name] = run.sensors_degc[:, j]
    z = np.zeros(run.times_s.size)
    for term in slot_terms(terms, "displacement"):
        part = np.asarray(term.func(params, rise, run.drive), dtype=float)
        cols[f"z_{term.name}_um"] = part
        z = z + part
    cols["z_um"] = z
    frame = pd.DataFrame(cols)
    frame.attrs["effects"] = sorted(names)
    frame.attrs["terms"] = [t.name for t in terms]
    return frame

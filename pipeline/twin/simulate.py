"""Run the generator's thermal network under a program and an ambient.

The machine stands idle (drive 0) for ``preroll_h`` hours before the start, following the
ambient law of the model, so that at t = 0 the structure carries the realistic lag of the
workshop's daily cycle; with a constant ambient it is simply at the air temperature.
Temperatures are then integrated exactly (first-order-hold matrix exponential, see
:mod:`pipeline.thermal.stepping`) on a grid made of the requested instants and the program's
breakpoints; ``method="Radau"`` (or ``"BDF"``, ``"LSODA"``) uses ``scipy.integrate.solve_ivp``.

External heat loads (:class:`~pipeline.thermal.loads.HeatLoad`: a heater mat, a lamp, a blower)
add their power to the node that the machine's sensors of the load's role read (e.g.
``column_rear`` -> node ``column_rear``, ``ball_screw`` -> ``z_screw``); their switching instants
are breakpoints of the grid, so the steps are exact. A load whose power is 0 throughout is left
out: it changes nothing, not even the grid.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import pandas as pd

from pipeline.thermal.effects import Term, check_effects, slot_terms
from pipeline.thermal.loads import HeatLoad, loads_from_contract
from pipeline.thermal.network import LinearSystem, build_system
from pipeline.thermal.program import Program
from pipeline.thermal.stepping import integrate_foh, integrate_ivp, time_grid
from pipeline.twin.effects import model_terms
from pipeline.twin.params import SensorSpec

logger = logging.getLogger(__name__)

IVP_METHODS = ("Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class NetworkRun:
    """Raw result of :func:`run_network` at the requested instants.

    Attributes
    ----------
    times_s : ndarray of shape (n_t,), s
    drive : ndarray of shape (n_t,)
        Program value at each instant (rpm or mm/s), right-continuous.
    ambient_degc : ndarray of shape (n_t,)
        Air temperature the structure sees.
    nodes_degc : ndarray of shape (n_t, n_nodes)
    start_degc : ndarray of shape (n_nodes,)
        Node temperatures at t = 0 (reference for expansion).
    sensors_degc : ndarray of shape (n_t, n_sensors)
        Noise-free sensor readings (direct or lagged).
    """

    times_s: np.ndarray
    drive: np.ndarray
    ambient_degc: np.ndarray
    nodes_degc: np.ndarray
    start_degc: np.ndarray
    sensors_degc: np.ndarray


def sensor_time_constants(value: Any, n_sensors: int) -> np.ndarray:
    """Broadcast the value of a sensor term to one time constant per sensor.

    Parameters
    ----------
    value : float or sequence of float
        What the model's ``sensor`` term returned, s: one value for all sensors or one per
        sensor (0 = the sensor reads its node directly).
    n_sensors : int

    Returns
    -------
    ndarray of shape (n_sensors,), s
    """
    taus = np.broadcast_to(np.asarray(value, dtype=float), (n_sensors,)).copy()
    if np.any(~np.isfinite(taus)) or np.any(taus < 0):
        raise ValueError(f"sensor time constants must be finite and >= 0 s, got {taus.tolist()}")
    return taus


@dataclass(frozen=True)
class _Model:
    """A machine's network with the terms of its model and its ambient, ready to integrate.

    Attributes
    ----------
    params : SpindleParams or AxisParams
    heat_terms : tuple of Term
    ambient_term : Term
    ambient : object with ``at(t_s)``
    system : LinearSystem
        Nodes plus one state per lagged sensor; inputs ``[T_amb, q_1..q_n]``.
    sensor_nodes : tuple of int
        Node each sensor reads, -1 for the air.
    lagged : tuple of int
        Sensors read through a lag (positions in ``params.sensors``), in state order.
    method : str
        ``"expm"`` or a ``solve_ivp`` method.
    loads : tuple of (int, HeatLoad)
        External heat loads that are not 0 throughout, each with the index of its node.
    """

    params: Any
    heat_terms: tuple[Term, ...]
    ambient_term: Term
    ambient: Any
    system: LinearSystem
    sensor_nodes: tuple[int, ...]
    lagged: tuple[int, ...]
    method: str
    loads: tuple[tuple[int, HeatLoad], ...] = ()

    @classmethod
    def build(
        cls,
        params: Any,
        terms: tuple[Term, ...],
        ambient: Any,
        method: str,
        loads: Sequence[HeatLoad] = (),
    ) -> _Model:
        """Assemble the state space of ``params.network`` with the lags of the sensor term."""
        net = params.network
        (ambient_term,) = slot_terms(terms, "ambient")
        (sensor_term,) = slot_terms(terms, "sensor")
        sensors: tuple[SensorSpec, ...] = params.sensors
        sensor_nodes = tuple(-1 if s.node == "ambient" else net.index(s.node) for s in sensors)
        taus = sensor_time_constants(sensor_term.func(params), len(sensors))
        lagged = tuple(j for j, tau in enumerate(taus) if tau > 0)
        system = build_system(
            net,
            tuple(sensor_nodes[j] for j in lagged),
            tuple(float(taus[j]) for j in lagged),
        )
        heat_terms = slot_terms(terms, "heat")
        placed = load_nodes(params, loads)
        return cls(
            params, heat_terms, ambient_term, ambient, system, sensor_nodes, lagged, method, placed
        )

    @property
    def n_nodes(self) -> int:
        """Number of network nodes."""
        return len(self.params.network.nodes)

    def air(self, t: np.ndarray) -> np.ndarray:
        """Air temperature the structure sees at ``t`` (s), degC."""
        return self.ambient_term.func(self.ambient, np.asarray(t, dtype=float))

    def heat(self, drive: np.ndarray) -> np.ndarray:
        """Heat into each node for each drive value, W, shape (k, n_nodes)."""
        q = np.zeros((np.size(drive), self.n_nodes))
        for term in self.heat_terms:
            q = q + term.func(self.params, drive)
        return q

    def load_heat(self, t: np.ndarray) -> np.ndarray:
        """Heat of the external loads into each node at ``t`` (s), W, shape (k, n_nodes)."""
        q = np.zeros((np.size(t), self.n_nodes))
        for node, load in self.loads:
            q[:, node] += load.power_at(np.asarray(t, dtype=float))
        return q

    def load_breakpoints_s(self) -> np.ndarray:
        """Instants where a load switches, s, shape (k,) (empty without loads)."""
        return np.concatenate(
            [np.empty(0), *(load.program.breakpoints_s() for _, load in self.loads)]
        )

    def initial(self, t_first: float) -> np.ndarray:
        """Every state at the air temperature of ``t_first`` (s), degC."""
        t_air = float(self.air(np.array([t_first]))[0])
        return np.full(self.system.A.shape[0], t_air)

    def ivp_inputs(self, q: np.ndarray, t: float, k: int) -> np.ndarray:
        """Return the inputs ``[T_amb(t), q_k]`` on interval ``k`` for ``solve_ivp``."""
        return np.concatenate([self.air(np.array([t])), q[k]])

    def integrate(self, grid: np.ndarray, x0: np.ndarray, drive: np.ndarray) -> np.ndarray:
        """States on ``grid`` (s) from ``x0`` with ``drive`` on each interval, (L, n_states).

        The loads' heat is taken at the start of each interval (constant within it when their
        breakpoints are on the grid).
        """
        q = self.heat(drive)
        if self.loads:
            q = q + self.load_heat(grid[:-1])
        if self.method != "expm":
            inputs = partial(self.ivp_inputs, q)
            return integrate_ivp(self.system, x0, grid, inputs, method=self.method)
        amb = self.air(grid)
        u_left = np.column_stack([amb[:-1], q])
        u_right = np.column_stack([amb[1:], q])
        return integrate_foh(self.system, x0, grid, u_left, u_right)

    def readings(self, x: np.ndarray, amb: np.ndarray) -> np.ndarray:
        """Noise-free sensor readings from states ``x`` (n_t, n_states) and the air, degC."""
        n = self.n_nodes
        readings = np.empty((x.shape[0], len(self.sensor_nodes)))
        for j, node in enumerate(self.sensor_nodes):
            readings[:, j] = amb if node < 0 else x[:, node]
        for k, j in enumerate(self.lagged):
            readings[:, j] = x[:, n + k]
        return readings


def _check_times(times_s: np.ndarray, method: str) -> np.ndarray:
    """Return the output instants as floats; raise ValueError for bad instants or method."""
    times = np.asarray(times_s, dtype=float)
    if times.ndim != 1 or times.size == 0:
        raise ValueError("times_s must be a non-empty 1-d array of seconds")
    if times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ValueError("times_s must be >= 0 and strictly increasing")
    if method != "expm" and method not in IVP_METHODS:
        raise ValueError(f"unknown method '{method}'; use 'expm' or one of {IVP_METHODS}")
    return times


def _start_state(
    model: _Model, history: Program | None, preroll_h: float, max_step_s: float
) -> np.ndarray:
    """State at t = 0 after the pre-roll: the machine's history before the start.

    Idle unless ``history`` says otherwise (or a load has a negative ``from_min``); only
    integrated if the air the model sees changes before the start, the machine ran or a load
    was on, else every state is at the air temperature at 0.
    """
    n_pre = max(int(np.ceil(preroll_h * 3600.0 / max_step_s)), 1)
    pre = np.linspace(-preroll_h * 3600.0, 0.0, n_pre + 1)
    past = history if history is not None else Program(())
    breaks = np.concatenate([past.breakpoints_s(), model.load_breakpoints_s()])
    pre = np.unique(np.concatenate([pre, breaks[(breaks > pre[0]) & (breaks < 0)]]))
    pre_drive = past.value_at(pre[:-1])
    loaded = bool(model.loads) and np.any(model.load_heat(pre[:-1]) != 0)
    if preroll_h > 0 and (np.ptp(model.air(pre)) > 0 or np.any(pre_drive != 0) or loaded):
        return model.integrate(pre, model.initial(pre[0]), pre_drive)[-1]
    return model.initial(0.0)


def run_network(
    params: Any,
    terms: tuple[Term, ...],
    program: Program,
    ambient: Any,
    times_s: np.ndarray,
    *,
    method: str = "expm",
    preroll_h: float = 72.0,
    max_step_s: float = 600.0,
    history: Program | None = None,
    loads: Sequence[HeatLoad] = (),
) -> NetworkRun:
    """Integrate ``params.network`` under the heat/ambient/sensor terms of a model.

    Parameters
    ----------
    params : SpindleParams or AxisParams
        Must have ``network`` and ``sensors`` (may be empty: nodes only).
    terms : tuple of Term
        From :func:`pipeline.twin.effects.model_terms`.
    program : Program
        Drive (rpm or mm/s) over time.
    ambient : object with ``at(t_s)``
        Air temperature law.
    times_s : array-like of shape (n_t,), s
        Output instants, >= 0, strictly increasing.
    method : str
        ``"expm"`` (exact, default) or a ``solve_ivp`` method in :data:`IVP_METHODS`.
    preroll_h : float
        Hours simulated before t = 0, idle unless ``history`` is given (only matters when the
        ambient varies or the machine ran).
    max_step_s : float
        Longest integration step, s (the ambient is linear within a step).
    history : Program, optional
        Drive during the pre-roll, minutes relative to the start (negative ``from_min``),
        e.g. the previous day's work; None = idle.
    loads : sequence of HeatLoad
        External heat loads, W, each into the node read by the sensors of its role
        (:func:`load_nodes`); their switching instants are added to the integration grid.

    Returns
    -------
    NetworkRun

    Raises
    ------
    ValueError
        For bad instants or method, or a load whose role no sensor of ``params`` reads.
    """
    times = _check_times(times_s, method)
    model = _Model.build(params, terms, ambient, method, loads)
    x0 = _start_state(model, history, preroll_h, max_step_s)
    breaks = np.concatenate([program.breakpoints_s(), model.load_breakpoints_s()])
    grid = time_grid(times, breaks, max_step_s=max_step_s)
    x = model.integrate(grid, x0, program.value_at(grid[:-1]))[np.searchsorted(grid, times)]
    amb = model.air(times)
    logger.debug("run_network: %d grid steps, method %s", grid.size - 1, method)
    return NetworkRun(
        times_s=times,
        drive=program.value_at(times),
        ambient_degc=amb,
        nodes_degc=x[:, : model.n_nodes],
        start_degc=x0[: model.n_nodes].copy(),
        sensors_degc=model.readings(x, amb),
    )


def load_nodes(params: Any, loads: Sequence[HeatLoad]) -> tuple[tuple[int, HeatLoad], ...]:
    """Pair each load with the index of the network node its role stands for.

    The node of a role is the one the machine's sensors of that role read (``params.sensors``:
    e.g. ``ball_screw`` -> ``z_screw`` on the spindle twin). Loads whose power is 0 throughout
    are left out.

    Parameters
    ----------
    params : SpindleParams or AxisParams
        Must have ``network`` and ``sensors``.
    loads : sequence of HeatLoad

    Returns
    -------
    tuple of (int, HeatLoad)
        Node index and load, in the order of ``loads``.

    Raises
    ------
    ValueError
        If no sensor of a load's role reads a node, or sensors of the role read several nodes.
    """
    placed = []
    for load in loads:
        if all(segment.value == 0 for segment in load.program.segments):
            continue
        nodes = sorted({s.node for s in params.sensors if s.role == load.role} - {"ambient"})
        if len(nodes) != 1:
            roles = sorted({s.role for s in params.sensors if s.node != "ambient"})
            found = "no sensor reads a node" if not nodes else f"sensors read nodes {nodes}"
            raise ValueError(
                f"heat load on role {load.role!r}: {found}, so the load has no single node of "
                f"the network; load one of the roles {roles}"
            )
        placed.append((params.network.index(nodes[0]), load))
    return tuple(placed)


def as_loads(loads: Sequence[HeatLoad] | Sequence[Mapping[str, Any]]) -> tuple[HeatLoad, ...]:
    """Accept :class:`HeatLoad` objects or the contract's ``heat_loads`` list of entries."""
    items = tuple(loads)
    if all(isinstance(item, HeatLoad) for item in items):
        return items
    return loads_from_contract(items)


def as_program(program: Program | Sequence[Mapping[str, Any]] | float, key: str) -> Program:
    """Accept a :class:`Program`, a contract list ``[{from_min, to_min?, key}]`` or a constant."""
    if isinstance(program, Program):
        return program
    if isinstance(program, int | float):
        return Program.constant(float(program), key=key)
    return Program.from_contract(program, key=key)


@dataclass(frozen=True)
class MachineRun:
    """A network run of one machine with its model and its common output columns.

    Attributes
    ----------
    run : NetworkRun
    effects : frozenset of str
        Effects switched on.
    terms : tuple of Term
        The model's terms for those effects.
    columns : dict of str to ndarray
        ``elapsed_s``, the program (``rpm`` or ``feed_mm_s``), ``ambient_degC``,
        ``node_<name>`` (degC) and the noise-free sensor columns (``T1``...).
    rise_k : ndarray of shape (n_t, n_nodes)
        Node temperatures minus their values at t = 0, K.
    """

    run: NetworkRun
    effects: frozenset[str]
    terms: tuple[Term, ...]
    columns: dict[str, np.ndarray]
    rise_k: np.ndarray


def simulate_machine(
    machine: str,
    params: Any,
    effects: Iterable[str],
    program: Program | Sequence[Mapping[str, Any]] | float,
    key: str,
    ambient: Any,
    times_s: np.ndarray,
    *,
    method: str,
    preroll_h: float,
    history: Program | Sequence[Mapping[str, Any]] | None,
    loads: Sequence[HeatLoad] | Sequence[Mapping[str, Any]] = (),
) -> MachineRun:
    """Run the network of ``machine`` ("spindle" or "axis") under its model for ``effects``.

    Shared by :func:`pipeline.twin.spindle.simulate_spindle` and
    :func:`pipeline.twin.axis.simulate_axis`, which add their own displacement outputs; the
    arguments are documented there. ``key`` names the program's quantity (``rpm``,
    ``feed_mm_s``); ``loads`` are external heat loads (:func:`run_network`).
    """
    names = check_effects(effects)
    terms = model_terms(machine, names)
    prog = as_program(program, key=key)
    past = None if history is None else as_program(history, key=prog.key)
    run = run_network(
        params,
        terms,
        prog,
        ambient,
        times_s,
        method=method,
        preroll_h=preroll_h,
        history=past,
        loads=as_loads(loads),
    )
    columns: dict[str, np.ndarray] = {
        "elapsed_s": run.times_s,
        key: run.drive,
        "ambient_degC": run.ambient_degc,
    }
    for j, node in enumerate(params.network.nodes):
        columns[f"node_{node}"] = run.nodes_degc[:, j]
    for j, sensor in enumerate(params.sensors):
        columns[sensor.name] = run.sensors_degc[:, j]
    return MachineRun(run, names, terms, columns, run.nodes_degc - run.start_degc)


def machine_frame(machine_run: MachineRun, extra: Mapping[str, np.ndarray]) -> pd.DataFrame:
    """Return the run's columns plus ``extra`` as a frame; ``attrs`` name effects and terms."""
    frame = pd.DataFrame({**machine_run.columns, **extra})
    frame.attrs["effects"] = sorted(machine_run.effects)
    frame.attrs["terms"] = [t.name for t in machine_run.terms]
    return frame

"""A second machine for the hidden-effect trials, written without the project's twin.

The project's twin (:mod:`pipeline.twin` on the kernel of :mod:`pipeline.thermal`) generates the
trials' campaigns with exactly the functional forms the discrepancy search fits, so a trial on it
cannot show a rule that only works because the forms match. This generator is a different model
of a vertical machining centre's spindle head, with its own discretisation, numerics, effect
forms, measurement chain and parameter ranges; it shares only the raw campaign contract (the
public interface) with the project:

* **structure** (24 nodes): the spindle shaft as eight axial finite volumes with axial
  conduction and a speed-dependent convection in the air gap; the front and rear bearing
  housings on shaft volumes 1 and 6; a three-volume cartridge sleeve; the motor housing; the
  headstock in a lower and an upper part; the column in three heights, each with a front
  (guideway) and a rear face linked through the ribs; the bed; the Z ball screw;
* **numerics**: the linear network ``C dT/dt = -(K + H(n)) T + H(n) T_air + q(t)`` integrated by
  :func:`scipy.integrate.solve_ivp` (BDF, analytic Jacobian) between the breakpoints of the
  speed program and of the heat loads, output every 30 s; lags are applied on that grid;
* **Z** (positive: the tool away from the table): the shaft from its front (locating) bearing to
  the nose, the headstock and the Z screw move the tool towards the table, the column's front
  and rear faces lift it (0.8 / 0.2 weights, guideways on the front).

The six candidate effects of the discrepancy search, each with a form of its own (the twin's
forms are in :mod:`pipeline.twin.effects`; these are not):

* ``ambient_variation``: the air follows a daily sine (1-3 K amplitude, peak at 15:00) plus an
  Ornstein-Uhlenbeck wander (0.2 K, one hour); without it, the air stays at the day's level;
* ``centrifugal_growth``: Z grows by ``c (n / 1000 rpm)^2`` (c 0.1-0.25 um/krpm^2, the nose
  retracting) through a 20-60 s first-order lag from rest (the shaft's radial response);
* ``nonlinear_bearing_heat``: the bearing power is Palmgren's load term plus a viscous term,
  ``q_ref (w n/n_ref + (1 - w) (n/n_ref)^e)`` with w 0.2-0.5 and e 1.55-1.75; without it, the
  load term alone, ``q_ref n/n_ref``;
* ``motor_heat``: the motor's copper and iron loss ``P_ref (0.6 n/n_ref + 0.4 (n/n_ref)^2)``
  (P_ref 40-100 W at 4000 rpm), 85 % into the motor housing and 15 % into the upper headstock;
* ``sensor_lag``: each sensor reads its part through two cascaded first-order lags (the pad,
  then the part's skin), tau_1 5-30 min per sensor and tau_2 = tau_1 / 4;
* ``thermal_bending``: the column's front-minus-rear rise at each height curves it
  (``alpha dT h / depth``); the tilt at the top moves the nose, at 300-450 mm overhang, by
  ``tilt x overhang``; without it, the column's faces only grow.

Parameters are drawn per seed from ranges around nominal values of a mid-size machining
centre (masses x specific heat; conductances from geometry; bearing heat chosen so that the
rises are 2-15 K and the drift 10-60 um at 2000-6000 rpm, the range of the spindle tests of
Miao et al. 2016, "Improvement of forecasting robustness of time series model for thermal error
on CNC machine tool", Optics and Precision Engineering 24(10)): capacities and conductances
x0.75-1.3, convection x0.7-1.4, bearing heat x0.8-1.25. The measurement chain: PT100 class A
sensors (offset +-0.15 K, noise 0.02 K, 0.01 K resolution), a capacitive probe (noise 0.15-0.35
um, an offset per mounting). Each campaign scatters the bearing and motor heat by 2 % and its
day's air level by 1 K.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from schemas.vocabulary import SEASON_OF_MONTH

MACHINE = "independent-vmc"
"""Machine name of every campaign this generator writes."""

EFFECTS = (
    "ambient_variation",
    "centrifugal_growth",
    "nonlinear_bearing_heat",
    "motor_heat",
    "sensor_lag",
    "thermal_bending",
)
"""Effects this machine can hide (the discrepancy search's candidates, in its own forms)."""

N_SHAFT = 8
"""Axial finite volumes of the spindle shaft, nose first."""
HEIGHTS = 3
"""Column heights (bottom, middle, top), each with a front and a rear face."""
NODES = (
    *(f"shaft{i}" for i in range(N_SHAFT)),
    "front_housing",
    "rear_housing",
    "sleeve_front",
    "sleeve_mid",
    "sleeve_rear",
    "motor",
    "head_lower",
    "head_upper",
    *(f"column_{face}{j}" for j in range(HEIGHTS) for face in ("front", "rear")),
    "bed",
    "screw",
)
INDEX = {name: i for i, name in enumerate(NODES)}

SENSORS = (
    ("T1", "spindle_front_bearing", "front bearing housing, flange", {"front_housing": 1.0}),
    ("T2", "spindle_rear_bearing", "rear bearing housing", {"rear_housing": 1.0}),
    ("T3", "spindle_motor", "motor housing, fan side", {"motor": 1.0}),
    ("T4", "headstock", "headstock side, mid height", {"head_lower": 0.6, "head_upper": 0.4}),
    ("T5", "column_front", "column front, between the guideways", {"column_front1": 1.0}),
    ("T6", "column_rear", "column rear face, mid height", {"column_rear1": 1.0}),
    ("T7", "bed", "bed, front left", {"bed": 1.0}),
    ("T8", "ball_screw", "Z screw support bearing", {"screw": 1.0}),
    ("T9", "other", "cartridge sleeve, nose side", {"sleeve_front": 1.0}),
    ("T10", "ambient", "air, 0.8 m beside the column", {}),
)
"""Name, contract role, where it is mounted, and the nodes it reads (weights)."""

LOAD_NODES = {
    "spindle_front_bearing": {"front_housing": 1.0},
    "spindle_rear_bearing": {"rear_housing": 1.0},
    "spindle_motor": {"motor": 1.0},
    "headstock": {"head_lower": 0.5, "head_upper": 0.5},
    "column_front": {"column_front0": 0.25, "column_front1": 0.5, "column_front2": 0.25},
    "column_rear": {"column_rear0": 0.25, "column_rear1": 0.5, "column_rear2": 0.25},
    "bed": {"bed": 1.0},
    "ball_screw": {"screw": 1.0},
}
"""How an external heater on a structure role spreads over the nodes (a mat at mid height)."""

N_REF = 4000.0
"""Speed at which the heat magnitudes are given, rpm."""
ALPHA_STEEL = 11.5e-6
"""Expansion coefficient of the shaft and the screw, 1/K."""
ALPHA_IRON = 10.5e-6
"""Expansion coefficient of the cast headstock and column, 1/K."""
GRID_S = 30.0
"""Output step of the integration, on which lags are applied, s."""
HEAT_SCATTER_REL = 0.02
"""Campaign-to-campaign relative scatter of the bearing and motor heat."""


@dataclass(frozen=True)
class Machine:
    """One drawn machine: its network, heat, geometry and instruments.

    Attributes
    ----------
    capacity : ndarray
        Heat capacity of each node of :data:`NODES`, J/K.
    conductance : ndarray
        Symmetric node-to-node conductance, W/K, zero diagonal.
    convection : ndarray
        Node-to-air conductance at rest, W/K.
    shaft_convection_per_krpm : float
        Extra air-gap conductance of each shaft volume per 1000 rpm, W/K.
    front_heat_w, rear_heat_w : float
        Bearing power at :data:`N_REF`, W; ``shaft_share`` of it enters the shaft.
    shaft_share : float
    viscous_weight, viscous_exponent : float
        ``w``, the weight of the load term (the viscous term has ``1 - w``), and ``e``, the
        viscous term's exponent (``nonlinear_bearing_heat``).
    motor_w : float
        Motor loss at :data:`N_REF`, W (``motor_heat``).
    centrifugal_um_per_krpm2, centrifugal_tau_s : float
        ``centrifugal_growth``: nose retraction per (1000 rpm)^2, um, and its lag, s.
    sensor_tau_s : ndarray
        First lag of each sensor of :data:`SENSORS`, s (``sensor_lag``).
    overhang_mm, column_depth_mm, column_height_mm : float
        Spindle axis to column front, front-to-rear face distance, column height, mm.
    nose_mm, head_mm, screw_mm : float
        Shaft length from the locating bearing to the nose (drawn but not used: the Z of the
        nose takes a fixed 1.5 shaft volumes, 94 mm, within its range; the draw stays so that
        a seed gives the same machine as before), headstock length below the Z nut, screw
        length from its fixed bearing to the nut, mm.
    daily_amplitude_k : float
        ``ambient_variation``: amplitude of the daily sine, K.
    sensor_offset_k : ndarray
        Calibration offset of each sensor, K.
    probe_noise_um : float
    """

    capacity: np.ndarray
    conductance: np.ndarray
    convection: np.ndarray
    shaft_convection_per_krpm: float
    front_heat_w: float
    rear_heat_w: float
    shaft_share: float
    viscous_weight: float
    viscous_exponent: float
    motor_w: float
    centrifugal_um_per_krpm2: float
    centrifugal_tau_s: float
    sensor_tau_s: np.ndarray
    overhang_mm: float
    column_depth_mm: float
    column_height_mm: float
    nose_mm: float
    head_mm: float
    screw_mm: float
    daily_amplitude_k: float
    sensor_offset_k: np.ndarray
    probe_noise_um: float


def _nominal_network() -> tuple[dict[str, float], list[tuple[str, str, float]], dict[str, float]]:
    """Capacities (J/K), links (W/K) and convections at rest (W/K) of the nominal machine."""
    capacity = {f"shaft{i}": 1.6 * 460.0 for i in range(N_SHAFT)}
    capacity.update(
        front_housing=9.0 * 460.0,
        rear_housing=5.0 * 460.0,
        sleeve_front=7.0 * 460.0,
        sleeve_mid=7.0 * 460.0,
        sleeve_rear=7.0 * 460.0,
        motor=45.0 * 460.0,
        head_lower=100.0 * 500.0,
        head_upper=80.0 * 500.0,
        bed=2000.0 * 500.0,
        screw=12.0 * 460.0,
    )
    capacity.update(
        {f"column_{f}{j}": 170.0 * 500.0 for j in range(HEIGHTS) for f in ("front", "rear")}
    )
    links = [(f"shaft{i}", f"shaft{i + 1}", 3.6) for i in range(N_SHAFT - 1)]
    links += [
        ("front_housing", "shaft1", 3.0),
        ("rear_housing", "shaft6", 2.0),
        ("front_housing", "sleeve_front", 5.0),
        ("rear_housing", "sleeve_rear", 4.0),
        ("sleeve_front", "sleeve_mid", 2.3),
        ("sleeve_mid", "sleeve_rear", 2.3),
        ("sleeve_front", "shaft2", 0.3),
        ("sleeve_mid", "shaft4", 0.3),
        ("sleeve_rear", "shaft5", 0.3),
        ("front_housing", "head_lower", 7.0),
        ("rear_housing", "head_lower", 3.0),
        ("sleeve_mid", "head_lower", 2.0),
        ("motor", "head_upper", 3.0),
        ("head_lower", "head_upper", 12.0),
        ("head_lower", "column_front2", 6.0),
        ("head_upper", "column_front2", 3.0),
        ("head_upper", "screw", 1.5),
        ("screw", "column_front2", 2.0),
        ("column_front0", "bed", 8.0),
        ("column_rear0", "bed", 8.0),
    ]
    for j in range(HEIGHTS):
        links.append((f"column_front{j}", f"column_rear{j}", 6.0))
        if j + 1 < HEIGHTS:
            for face in ("front", "rear"):
                links.append((f"column_{face}{j}", f"column_{face}{j + 1}", 20.0))
    convection = {f"shaft{i}": 0.15 for i in range(N_SHAFT)}
    convection.update(
        front_housing=0.8,
        rear_housing=0.4,
        sleeve_front=0.3,
        sleeve_mid=0.3,
        sleeve_rear=0.3,
        motor=6.0,
        head_lower=3.0,
        head_upper=2.5,
        bed=20.0,
        screw=1.0,
    )
    convection.update({f"column_{f}{j}": 2.5 for j in range(HEIGHTS) for f in ("front", "rear")})
    return capacity, links, convection


def draw_machine(seed: int) -> Machine:
    """Draw one machine from the ranges of the module docstring."""
    rng = np.random.default_rng([seed, 271828])
    capacity, links, convection = _nominal_network()
    n = len(NODES)
    conductance = np.zeros((n, n))
    for a, b, g in links:
        value = g * rng.uniform(0.75, 1.3)
        conductance[INDEX[a], INDEX[b]] = conductance[INDEX[b], INDEX[a]] = value
    heat_scale = rng.uniform(0.8, 1.25)
    return Machine(
        capacity=np.array([capacity[k] for k in NODES]) * rng.uniform(0.75, 1.3, n),
        conductance=conductance,
        convection=np.array([convection[k] for k in NODES]) * rng.uniform(0.7, 1.4, n),
        shaft_convection_per_krpm=rng.uniform(0.04, 0.1),
        front_heat_w=65.0 * heat_scale * rng.uniform(0.9, 1.1),
        rear_heat_w=35.0 * heat_scale * rng.uniform(0.9, 1.1),
        shaft_share=rng.uniform(0.3, 0.5),
        viscous_weight=rng.uniform(0.2, 0.5),
        viscous_exponent=rng.uniform(1.55, 1.75),
        motor_w=rng.uniform(40.0, 100.0),
        centrifugal_um_per_krpm2=rng.uniform(0.1, 0.25),
        centrifugal_tau_s=rng.uniform(20.0, 60.0),
        sensor_tau_s=rng.uniform(300.0, 1800.0, len(SENSORS)),
        overhang_mm=rng.uniform(300.0, 450.0),
        column_depth_mm=rng.uniform(500.0, 700.0),
        column_height_mm=rng.uniform(800.0, 1000.0),
        nose_mm=rng.uniform(90.0, 130.0),
        head_mm=rng.uniform(300.0, 420.0),
        screw_mm=rng.uniform(300.0, 500.0),
        daily_amplitude_k=rng.uniform(1.0, 3.0),
        sensor_offset_k=rng.uniform(-0.15, 0.15, len(SENSORS)),
        probe_noise_um=rng.uniform(0.15, 0.35),
    )


def step_function(entries: Sequence[Mapping[str, Any]], key: str) -> Callable[[float], float]:
    """Return the piecewise-constant ``<key>`` of contract entries at a time in seconds.

    Entries are ``{from_min, to_min?, <key>}``; the value is 0 outside them, and an entry
    without ``to_min`` lasts on.
    """
    pieces = [
        (
            60.0 * float(e["from_min"]),
            np.inf if e.get("to_min") is None else 60.0 * float(e["to_min"]),
            float(e[key]),
        )
        for e in entries
    ]

    def value(t_s: float) -> float:
        return sum(v for a, b, v in pieces if a <= t_s < b)

    return value


def _breakpoints(entries: Iterable[Mapping[str, Any]]) -> list[float]:
    """Every ``from_min`` and ``to_min`` of ``entries``, s."""
    points = []
    for e in entries:
        points.append(60.0 * float(e["from_min"]))
        if e.get("to_min") is not None:
            points.append(60.0 * float(e["to_min"]))
    return points


@dataclass(frozen=True)
class Test:
    """What one campaign ran.

    Attributes
    ----------
    program : tuple of dict
        Contract ``spindle_program`` entries (minutes, rpm).
    loads : tuple of dict
        Contract ``heat_loads`` entries (role, minutes, W).
    duration_s, interval_s : float
        Length of the record and its sample interval, s.
    """

    program: tuple[dict, ...]
    loads: tuple[dict, ...]
    duration_s: float
    interval_s: float


def _bearing_power(machine: Machine, rpm: float, nonlinear: bool) -> float:
    """Total bearing power factor at ``rpm`` relative to :data:`N_REF` (1 at the reference)."""
    ratio = rpm / N_REF
    if not nonlinear:
        return ratio
    w = machine.viscous_weight
    return w * ratio + (1.0 - w) * ratio**machine.viscous_exponent


def _heat(machine: Machine, rpm: float, effects: frozenset, scatter: np.ndarray) -> np.ndarray:
    """Heat into each node at ``rpm`` from the bearings and the motor, W."""
    q = np.zeros(len(NODES))
    power = _bearing_power(machine, rpm, "nonlinear_bearing_heat" in effects)
    share = machine.shaft_share
    for housing, shaft, heat, s in (
        ("front_housing", "shaft1", machine.front_heat_w, scatter[0]),
        ("rear_housing", "shaft6", machine.rear_heat_w, scatter[1]),
    ):
        q[INDEX[housing]] += (1.0 - share) * heat * power * s
        q[INDEX[shaft]] += share * heat * power * s
    if "motor_heat" in effects:
        ratio = rpm / N_REF
        loss = machine.motor_w * (0.6 * ratio + 0.4 * ratio**2) * scatter[2]
        q[INDEX["motor"]] += 0.85 * loss
        q[INDEX["head_upper"]] += 0.15 * loss
    return q


def _load_heat(loads: Sequence[Mapping[str, Any]], t_s: float) -> np.ndarray:
    """Heat of the external loads into each node at ``t_s``, W."""
    q = np.zeros(len(NODES))
    for entry in loads:
        if step_function([entry], "power_W")(t_s) == 0.0:
            continue
        for node, weight in LOAD_NODES[entry["role"]].items():
            q[INDEX[node]] += weight * float(entry["power_W"])
    return q


def _air_conductance(machine: Machine, rpm: float) -> np.ndarray:
    """Node-to-air conductance at ``rpm``, W/K (the shaft's air gap stirs with speed)."""
    h = machine.convection.copy()
    h[:N_SHAFT] += machine.shaft_convection_per_krpm * rpm / 1000.0
    return h


def air_temperature(
    machine: Machine, level_c: float, start: datetime, t_s: np.ndarray, varying: bool, seed: int
) -> np.ndarray:
    """Return the workshop air at each instant, degC.

    The day's level; with ``varying``, plus a daily sine peaking at 15:00 and an
    Ornstein-Uhlenbeck wander (0.2 K, one hour).
    """
    if not varying:
        return np.full(t_s.shape, level_c)
    clock_h = start.hour + start.minute / 60.0 + t_s / 3600.0
    daily = machine.daily_amplitude_k * np.sin(2.0 * np.pi * (clock_h - 9.0) / 24.0)
    rng = np.random.default_rng([seed, 1618])
    dt, tau, sigma = GRID_S, 3600.0, 0.2
    wander = np.zeros(t_s.size)
    decay = np.exp(-dt / tau)
    shocks = rng.standard_normal(t_s.size) * sigma * np.sqrt(1.0 - decay**2)
    for i in range(1, t_s.size):
        wander[i] = decay * wander[i - 1] + shocks[i]
    return level_c + daily - daily[0] + wander


def _first_order(x: np.ndarray, tau_s: float, initial: float | None = None) -> np.ndarray:
    """Return ``x`` (on the :data:`GRID_S` grid) through a first-order lag of ``tau_s``.

    ``tau dy/dt = x - y``, exact for ``x`` linear between grid points, from ``y[0] =
    initial`` (None: settled, ``x[0]``).
    """
    a = np.exp(-GRID_S / tau_s)
    c = 1.0 - tau_s / GRID_S * (1.0 - a)
    y = np.empty_like(x)
    y[0] = x[0] if initial is None else initial
    for i in range(1, x.size):
        y[i] = a * y[i - 1] + (1.0 - a - c) * x[i - 1] + c * x[i]
    return y


def simulate(
    machine: Machine,
    test: Test,
    effects: frozenset,
    start: datetime,
    level_c: float,
    scatter: np.ndarray,
    seed: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Run one campaign on the grid of :data:`GRID_S`.

    Returns
    -------
    t_s : ndarray
        Grid instants, s.
    temperatures : ndarray
        Node temperatures, degC, shape (grid, nodes).
    air : ndarray
        Workshop air, degC.
    z_um : ndarray
        True Z of the nose relative to the start, um.
    """
    t_s = np.arange(0.0, test.duration_s + GRID_S / 2, GRID_S)
    varying = "ambient_variation" in effects
    air = air_temperature(machine, level_c, start, t_s, varying, seed)
    rpm_at = step_function(test.program, "rpm")
    stops = sorted({0.0, test.duration_s, *_breakpoints(test.program), *_breakpoints(test.loads)})
    stops = [s for s in stops if 0.0 <= s <= test.duration_s]
    k_matrix = np.diag(machine.conductance.sum(axis=1)) - machine.conductance
    inverse_c = 1.0 / machine.capacity
    state = np.full(len(NODES), air[0])
    out = np.empty((t_s.size, len(NODES)))
    out[0] = state
    for a, b in zip(stops[:-1], stops[1:], strict=True):
        if b <= a:
            continue
        middle = 0.5 * (a + b)
        rpm = rpm_at(middle)
        h = _air_conductance(machine, rpm)
        q = _heat(machine, rpm, effects, scatter) + _load_heat(test.loads, middle)
        jac = -(k_matrix + np.diag(h)) * inverse_c[:, None]

        def rate(t, x, h=h, q=q, jac=jac):
            return jac @ x + inverse_c * (h * np.interp(t, t_s, air) + q)

        inside = t_s[(t_s > a) & (t_s <= b)]
        solved = solve_ivp(
            rate,
            (a, b),
            state,
            method="BDF",
            t_eval=inside if inside.size else None,
            jac=jac,
            rtol=1e-7,
            atol=1e-7,
            max_step=600.0 if varying else np.inf,  # the air's wander, when it varies
        )
        if inside.size:
            out[(t_s > a) & (t_s <= b)] = solved.y.T
        state = solved.y[:, -1]
    return t_s, out, air, _z_um(machine, t_s, out, rpm_at, effects)


def _z_um(
    machine: Machine,
    t_s: np.ndarray,
    temps: np.ndarray,
    rpm_at: Callable[[float], float],
    effects: frozenset,
) -> np.ndarray:
    """Return the true Z of the nose from its start, um (positive: tool away from the table)."""
    rise = temps - temps[0]
    dx = 500.0 / N_SHAFT  # mm per shaft volume, locating bearing in volume 1
    shaft = dx * rise[:, INDEX["shaft0"]] + 0.5 * dx * rise[:, INDEX["shaft1"]]
    head = 0.7 * rise[:, INDEX["head_lower"]] + 0.3 * rise[:, INDEX["head_upper"]]
    column = np.zeros(t_s.size)
    tilt = np.zeros(t_s.size)
    piece = machine.column_height_mm / HEIGHTS
    for j in range(HEIGHTS):
        front, rear = rise[:, INDEX[f"column_front{j}"]], rise[:, INDEX[f"column_rear{j}"]]
        column += piece * (0.8 * front + 0.2 * rear)
        tilt += ALPHA_IRON * piece * (front - rear) / machine.column_depth_mm
    z_mm = (
        -ALPHA_STEEL * shaft
        - ALPHA_IRON * machine.head_mm * head
        - ALPHA_STEEL * machine.screw_mm * rise[:, INDEX["screw"]]
        + ALPHA_IRON * column
    )
    if "thermal_bending" in effects:
        z_mm = z_mm + tilt * machine.overhang_mm
    z_um = 1000.0 * z_mm
    if "centrifugal_growth" in effects:
        rpm = np.array([rpm_at(t) for t in t_s])
        growth = machine.centrifugal_um_per_krpm2 * (rpm / 1000.0) ** 2
        z_um = z_um + _first_order(growth, machine.centrifugal_tau_s, initial=0.0)
    return z_um


def campaign_rng(seed: int, campaign_id: str) -> np.random.Generator:
    """Return one campaign's random generator (its draws whatever other campaigns exist)."""
    return np.random.default_rng([seed, zlib.crc32(campaign_id.encode())])


def day_level_c(start: datetime, rng: np.random.Generator) -> float:
    """Return the workshop air's level on the day, degC.

    17 degC and 7 K over the seasons (warmest in late July), scattered by 1 K.
    """
    day = start.timetuple().tm_yday
    return 17.0 + 7.0 * np.sin(2.0 * np.pi * (day - 115) / 365.0) + rng.normal(0.0, 1.0)


def read_sensors(
    machine: Machine,
    temps: np.ndarray,
    air: np.ndarray,
    lagged: bool,
    rng: np.random.Generator,
) -> np.ndarray:
    """Return each sensor's reading on the grid, degC, shape (grid, sensors).

    Its nodes (or the air), through two cascaded lags with ``lagged``, plus its offset, noise
    and 0.01 K resolution.
    """
    readings = np.empty((temps.shape[0], len(SENSORS)))
    for k, (_, _, _, nodes) in enumerate(SENSORS):
        value = sum(w * temps[:, INDEX[n]] for n, w in nodes.items()) if nodes else air
        if lagged:
            tau = machine.sensor_tau_s[k]
            value = _first_order(_first_order(value, tau), tau / 4.0)
        noisy = value + machine.sensor_offset_k[k] + rng.normal(0.0, 0.02, value.size)
        readings[:, k] = np.round(noisy, 2)
    return readings


def season_of(start: datetime) -> str:
    """Return the contract season of a start date."""
    return SEASON_OF_MONTH[start.month]


def _entries_yaml(name: str, entries: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return a YAML list of flow mappings, e.g. ``spindle_program:`` entries."""
    if not entries:
        return []
    lines = [f"{name}:"]
    for entry in entries:
        fields = ", ".join(
            f"{k}: {_yaml_value(v)}" for k, v in entry.items() if v is not None and k != "what"
        )
        lines.append(f"  - {{{fields}}}")
    return lines


def _yaml_value(value: Any) -> str:
    """Return a number as a YAML scalar (integers without a fraction), or text as it is."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def campaign_yaml(campaign_id: str, start: datetime, test: Test, note: str) -> str:
    """Return the campaign's ``campaign.yaml`` in the raw contract."""
    lines = [
        f"campaign_id: {campaign_id}",
        "kind: spindle_drift",
        f"machine: {MACHINE}",
        f"start: {start.isoformat()}",
        f"season: {season_of(start)}",
        "synthetic: true",
        "split: train",
        f'notes: "{note}"',
        *_entries_yaml("spindle_program", test.program),
        *_entries_yaml("heat_loads", test.loads),
        "sensors:",
        *(
            f'  {name}: {{role: {role}, location: "{where}", type: PT100}}'
            for name, role, where, _ in SENSORS
        ),
        "displacement:",
        '  Z: {probe: capacitive, location: "spindle nose, against a test mandrel"}',
    ]
    return "\n".join(lines) + "\n"


def write_campaign(
    folder: Path,
    campaign_id: str,
    start: datetime,
    test: Test,
    machine: Machine,
    effects: frozenset,
    seed: int,
    note: str,
) -> Path:
    """Simulate one campaign and write ``folder/<campaign_id>/`` in the raw contract."""
    rng = campaign_rng(seed, campaign_id)
    level = day_level_c(start, rng)
    scatter = 1.0 + HEAT_SCATTER_REL * rng.standard_normal(3)
    t_s, temps, air, z_um = simulate(machine, test, effects, start, level, scatter, seed)
    readings = read_sensors(machine, temps, air, "sensor_lag" in effects, rng)
    keep = np.flatnonzero(np.isclose(np.mod(t_s + 1e-9, test.interval_s), 0.0, atol=1e-6))
    probe = z_um + rng.uniform(-0.5, 0.5) + rng.normal(0.0, machine.probe_noise_um, t_s.size)
    out = folder / campaign_id
    out.mkdir(parents=True, exist_ok=True)
    (out / "campaign.yaml").write_text(campaign_yaml(campaign_id, start, test, note))
    names = [name for name, *_ in SENSORS]
    rows = ["elapsed_s," + ",".join(names)]
    rows += [f"{t_s[i]:.0f}," + ",".join(f"{v:.2f}" for v in readings[i]) for i in keep]
    (out / "temperature.csv").write_text("\n".join(rows) + "\n")
    rows = ["elapsed_s,Z"] + [f"{t_s[i]:.0f},{probe[i]:.2f}" for i in keep]
    (out / "displacement.csv").write_text("\n".join(rows) + "\n")
    return out


PROGRAMS = (
    ((0.0, 2000.0), (120.0, 6000.0)),
    ((0.0, 4000.0), (90.0, 2000.0), (180.0, 6000.0)),
    ((0.0, 6000.0), (150.0, 3000.0)),
    ((0.0, 3000.0), (100.0, 5000.0)),
    ((0.0, 5000.0), (120.0, 2000.0), (200.0, 4000.0)),
    ((0.0, 2500.0), (80.0, 4500.0), (160.0, 6000.0)),
    ((0.0, 6000.0), (60.0, 4000.0)),
    ((0.0, 4000.0), (140.0, 6000.0)),
)
"""Speed steps ((from_min, rpm), ...) of the trial campaigns: the trials' test protocol."""


def stepped_test(steps: Sequence[tuple[float, float]], run_min: float, cool_min: float) -> Test:
    """Speed steps until ``run_min``, then stopped for ``cool_min``; a sample every 3 min."""
    ends = [s[0] for s in steps[1:]] + [run_min]
    program = [
        {"from_min": a, "to_min": b, "rpm": rpm} for (a, rpm), b in zip(steps, ends, strict=True)
    ]
    program.append({"from_min": run_min, "rpm": 0.0})
    return Test(tuple(program), (), 60.0 * (run_min + cool_min), 180.0)


def note(seed: int, what: str) -> str:
    """Return the ``notes:`` of a written campaign: what wrote it, that it is not a measurement."""
    return (
        f"Synthetic campaign of an independent machine model (benchmarks.independent_machine, "
        f"seed {seed}, {what}); not a measurement."
    )


def write_hidden_campaigns(folder: Path, effects: Iterable[str], seed: int, n: int = 8) -> None:
    """Write ``n`` stepped campaigns of seed ``seed``'s machine, 45 days apart from January.

    Parameters
    ----------
    folder : Path
        Raw folder (one sub-folder per campaign).
    effects : iterable of str
        Effects of :data:`EFFECTS` the machine has.
    seed : int
        Seed of the machine and of every campaign's draws.
    n : int
        Number of campaigns (270 min running in steps, then 60 min stopped).
    """
    effects = frozenset(effects)
    unknown = effects - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; this machine has {EFFECTS}")
    machine = draw_machine(seed)
    start = datetime(2024, 1, 10, 8, 30)
    for i in range(n):
        test = stepped_test(PROGRAMS[i % len(PROGRAMS)], 270.0, 60.0)
        day = start + timedelta(days=45 * i)
        write_campaign(
            folder, f"H{i + 1:02d}", day, test, machine, effects, seed, note(seed, "trial")
        )


def write_plan_campaigns(
    folder: Path,
    proposed: Mapping[str, Any],
    effects: Iterable[str],
    seed: int,
    n: int,
    round_: int = 1,
) -> list[str]:
    """Write ``n`` campaigns of a proposed test on seed ``seed``'s machine.

    Parameters
    ----------
    folder : Path
        Raw folder to add them to.
    proposed : mapping
        A proposed test of ``discrepancy.json``: ``spindle_program``, ``heat_loads``,
        ``sample_interval_s`` (s) and ``duration_h`` (h).
    effects : iterable of str
        The machine's effects.
    seed : int
    n : int
        Number of campaigns, 20 days apart from March 2025.
    round_ : int
        Round of proposed tests: campaigns ``P<round>_<nn>``, each round 60 days later.

    Returns
    -------
    list of str
        The campaign ids written.
    """
    machine = draw_machine(seed)
    test = Test(
        tuple(dict(e) for e in proposed["spindle_program"]),
        tuple(dict(e) for e in proposed.get("heat_loads") or ()),
        3600.0 * float(proposed["duration_h"]),
        float(proposed["sample_interval_s"]),
    )
    start = datetime(2025, 3, 10, 8, 30) + timedelta(days=60 * (round_ - 1))
    ids = [f"P{round_}_{i + 1:02d}" for i in range(n)]
    for i, campaign_id in enumerate(ids):
        day = start + timedelta(days=20 * i)
        what = f"test plan {proposed.get('name', '')}".strip()
        write_campaign(
            folder, campaign_id, day, test, machine, frozenset(effects), seed, note(seed, what)
        )
    return ids

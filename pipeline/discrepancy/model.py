"""The calibratable baseline twin, built from sensor roles alone, and its candidate effects.

The baseline is a lumped thermal network whose nodes are the structure parts the campaign's
sensors sit on (roles ``spindle_front_bearing``, ``spindle_rear_bearing``, ``spindle_motor``,
``headstock``, ``column_front``, ``column_rear``, ``bed``, ``ball_screw``) plus two nodes that
exist even without a sensor: the rotating ``spindle_shaft`` (no sensor can sit on it; its
growth is most of the Z drift) and the ``headstock`` carrying the spindle. It knows nothing of
the machine that produced the data: every physical value is a bounded parameter fitted by
:func:`pipeline.discrepancy.calibrate.calibrate`.

Baseline physics (``C dT/dt = -K T + h T_amb + q``)::

    q_front_bearing = q_fb * rpm / 1000      (into the front-bearing node, else the shaft)
    q_rear_bearing  = q_rb * rpm / 1000      (into the rear-bearing node, else the shaft;
                                              one q_bearing into the shaft without either);
                      a share s (bearing_heat_to_shaft) of it enters the shaft instead
    T_amb           = the ambient sensor's reading at the start (constant; mean of its first
                      15 min, :data:`AMBIENT_START_S`), or the mean first reading of all
                      sensors without an ambient sensor
    z = - alpha_spindle dT_shaft - alpha_headstock dT_headstock - alpha_screw dT_ball_screw
        + alpha_column (dT_column_front + dT_column_rear) / 2          (um; rises since t0)
    reading = first reading + (T_node(t) - T_node(t0))                (direct sensors)
    q_load          = P(t)                   (a campaign's external heat load, W, known, into
                                              the node of its role: ``heat_loads:``)

Topology (links exist when both ends exist): bearings - shaft, bearings - headstock (shaft -
headstock when no bearing node), motor - headstock, headstock - column (front, else rear),
column front - rear, columns - bed (headstock - bed without column), ball screw - headstock
and - column. The initial node temperatures are the sensors' first readings (the sensors read
their node directly), so a campaign may start warm or out of balance with the air; an unsensed
node starts at the mean of its neighbours.

The baseline goes beyond the spindle and its structure in one place: a sensor with role
``ball_screw`` brings in the Z ball screw (its growth moves the head towards the table on a
semi-closed-loop Z axis). Without it, the screw's response to the air, which the data show, is left
in every residual and masks the effects being looked for (held-out Z RMS after
``ambient_variation`` 1.0 um against a 0.6 um floor on trial data).

Parameters are shared within node groups to stay identifiable on ~10 campaigns: one heat
capacity for both bearings and one for both column halves; one convection conductance for the
spindle group (bearings and shaft) and one for both column halves; one conductance per link
kind (both bearings to the shaft, both bearings to the headstock, both columns to the bed).

Candidate effects (:data:`EFFECTS`, the names of the kernel's registry
:data:`pipeline.thermal.effects.EFFECTS`), each adding the bounded parameters of its row of
:data:`EFFECT_SPECS`: ``ambient_variation`` (the measured ambient drives the convection; no new
parameter), ``centrifugal_growth``, ``nonlinear_bearing_heat``, ``sensor_lag``,
``thermal_bending``, ``motor_heat``. Every parameter is a row of a spec table
(:data:`CAPACITY_SPECS`, :data:`CONVECTION_SPECS`, :data:`LINK_SPECS`, :data:`HEAT_SPECS`,
:data:`DISPLACEMENT_SPECS`, :data:`EFFECT_SPECS`); the Z laws are the rows of :data:`Z_TERMS`.

This module is a parameterisation on top of the thermal-network kernel (:mod:`pipeline.thermal`):
the network, its state space with sensor-lag states, the exact first-order-hold discretisation
(computed once per distinct step length and parameter vector) and the stepping are the
kernel's. Integration is exact for the piecewise-constant speed and piecewise-linear ambient on
a grid of the sample instants and the program's speed steps, and the campaigns and parameter
vectors are stepped together in the modes of the network
(:func:`pipeline.thermal.stepping.propagate`). The calibration's finite-difference Jacobian is
one such batched run (:meth:`TwinModel.run_batch`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.thermal.discretise import foh_matrices
from pipeline.thermal.effects import EFFECTS as EFFECT_REGISTRY
from pipeline.thermal.network import LinearSystem, ThermalNetwork, build_system
from pipeline.thermal.program import Program
from pipeline.thermal.stepping import propagate, time_grid

logger = logging.getLogger(__name__)

EFFECTS = tuple(name for name, effect in EFFECT_REGISTRY.items() if "spindle" in effect.machines)
"""Candidate effects: the kernel registry's effects of the spindle, in registry order."""

ROLE_NODES = {
    "spindle_front_bearing": "front_bearing",
    "spindle_rear_bearing": "rear_bearing",
    "spindle_motor": "motor",
    "headstock": "headstock",
    "column_front": "column_front",
    "column_rear": "column_rear",
    "bed": "bed",
    "ball_screw": "ball_screw",
}
"""Sensor role -> network node; other roles (``ambient``, ``other``, ...) are not nodes."""

NODE_ORDER = (
    "front_bearing",
    "rear_bearing",
    "spindle_shaft",
    "motor",
    "headstock",
    "column_front",
    "column_rear",
    "bed",
    "ball_screw",
)

CAPACITY_GROUP = {
    "front_bearing": "bearing",
    "rear_bearing": "bearing",
    "spindle_shaft": "spindle_shaft",
    "motor": "motor",
    "headstock": "headstock",
    "column_front": "column",
    "column_rear": "column",
    "bed": "bed",
    "ball_screw": "ball_screw",
}
CONVECTION_GROUP = {
    "front_bearing": "spindle",
    "rear_bearing": "spindle",
    "spindle_shaft": "spindle",
    "motor": "motor",
    "headstock": "headstock",
    "column_front": "column",
    "column_rear": "column",
    "bed": "bed",
    "ball_screw": "ball_screw",
}

AMBIENT_START_S = 900.0
"""The constant ambient of the baseline is the mean ambient reading over the first 15 min
(the reading at the start, without the sensor's white noise and quantisation), degC."""

REFERENCE_RPM = 3000.0
"""Speed at which ``nonlinear_bearing_heat`` gives the same heat as the linear law, rpm."""


@dataclass(frozen=True)
class ParamSpec:
    """One bounded parameter of the twin.

    Attributes
    ----------
    name : str
        Readable name with its unit, e.g. ``"C_headstock_J_per_K"``.
    unit : str
        Unit, e.g. ``"J/K"``.
    lower, upper : float
        Bounds (physical plausibility), ``lower < upper``.
    initial : float
        Starting value of the calibration, inside the bounds.
    effect : str or None
        Effect that brings the parameter in, None for the baseline.
    description : str
        What it is, in words.
    """

    name: str
    unit: str
    lower: float
    upper: float
    initial: float
    effect: str | None = None
    description: str = ""

    @property
    def log(self) -> bool:
        """True when the parameter is calibrated in log space (strictly positive bounds)."""
        return self.lower > 0


# ----------------------------------------------------------------------- baseline spec tables
# Generic magnitudes of a mid-size machining centre (mass x specific heat, h A), not fitted:
# they are the calibration's starting values. Columns: lower, upper, initial.


def _group_specs(
    symbol: str,
    unit: str,
    description: str,
    bounds: dict[str, tuple[float, float, float]],
    label: Callable[[str], str] = str,
) -> dict[str, ParamSpec]:
    """Return one parameter per group, ``<symbol>_<group>_<unit>``, with bounds and initial value.

    Parameters
    ----------
    symbol : str
        ``C`` (capacity), ``h`` (convection) or ``G`` (link conductance).
    unit : str
        ``J/K`` or ``W/K``; the name spells it ``J_per_K``, ``W_per_K``.
    description : str
        With ``{}`` where the group's label goes.
    bounds : dict
        Group -> (lower, upper, initial), in ``unit``.
    label : callable
        The group's words in the description.
    """
    suffix = unit.replace("/", "_per_")
    return {
        group: ParamSpec(
            f"{symbol}_{group}_{suffix}",
            unit,
            lower,
            upper,
            initial,
            description=description.format(label(group)),
        )
        for group, (lower, upper, initial) in bounds.items()
    }


CAPACITY_SPECS = _group_specs(
    "C",
    "J/K",
    "heat capacity of each {} node",
    {
        "bearing": (1e3, 1e6, 5e3),
        "spindle_shaft": (1e3, 1e6, 5e3),
        "motor": (1e3, 1e6, 2e4),
        "headstock": (1e3, 1e6, 1e5),
        "column": (1e4, 1e7, 3e5),
        "bed": (1e4, 1e7, 1e6),
        "ball_screw": (1e3, 1e6, 5e3),
    },
)
"""Heat capacity of each :data:`CAPACITY_GROUP`, J/K."""

CONVECTION_SPECS = _group_specs(
    "h",
    "W/K",
    "convection to the air of each {} node",
    {
        "spindle": (0.1, 200.0, 1.0),
        "motor": (0.1, 200.0, 2.0),
        "headstock": (0.1, 200.0, 5.0),
        "column": (0.1, 200.0, 10.0),
        "bed": (0.1, 200.0, 20.0),
        "ball_screw": (0.1, 200.0, 1.0),
    },
)
"""Convection conductance to the air of each :data:`CONVECTION_GROUP`, W/K."""

LINK_SPECS = _group_specs(
    "G",
    "W/K",
    "conductance {}",
    {
        "bearing_shaft": (0.1, 500.0, 5.0),
        "bearing_headstock": (0.1, 500.0, 5.0),
        "shaft_headstock": (0.1, 500.0, 5.0),
        "motor_headstock": (0.1, 500.0, 2.0),
        "headstock_column": (0.1, 500.0, 10.0),
        "column_front_rear": (0.1, 500.0, 10.0),
        "column_bed": (0.1, 500.0, 10.0),
        "headstock_bed": (0.1, 500.0, 10.0),
        "screw_headstock": (0.1, 500.0, 2.0),
        "screw_column": (0.1, 500.0, 2.0),
    },
    label=lambda group: group.replace("_", " - ", 1),
)
"""Conductance of each link kind (the third field of :attr:`TwinModel.links`), W/K."""

BEARING_SHARE_SPEC = ParamSpec(
    "bearing_heat_to_shaft",
    "1",
    0.0,
    0.9,
    0.3,
    description="share of the bearing friction heat entering the shaft through the inner rings "
    "(the rest heats the bearing housings)",
)
"""Present when the model has a bearing node."""

HEAT_SPECS = {
    (source, node): ParamSpec(
        f"q_{source}_W_per_krpm",
        "W/krpm",
        0.0,
        200.0,
        5.0,
        description=f"{source} friction heat into {node} per 1000 rpm",
    )
    for source, node in (
        ("front_bearing", "front_bearing"),
        ("front_bearing", "spindle_shaft"),  # no front-bearing node
        ("rear_bearing", "rear_bearing"),
        ("rear_bearing", "spindle_shaft"),  # no rear-bearing node
        ("bearing", "spindle_shaft"),  # no bearing node at all: one source into the shaft
    )
}
"""Friction heat per 1000 rpm of each (heat source, node it enters), W/krpm."""

DISPLACEMENT_SPECS = tuple(
    (ParamSpec(f"alpha_{part}_um_per_K", "um/K", 0.01, 30.0, initial, description=text), roles)
    for part, initial, roles, text in (
        ("spindle", 3.0, (), "spindle growth towards the table per K of shaft rise"),
        ("headstock", 3.0, ("headstock",), "headstock growth towards the table per K"),
        (
            "ball_screw",
            3.0,
            ("ball_screw",),
            "Z ball-screw growth moving the head towards the table per K (semi-closed-loop Z axis)",
        ),
        (
            "column",
            5.0,
            ("column_front", "column_rear"),
            "column growth lifting the head per K (mean rise)",
        ),
    )
)
"""Baseline expansion coefficients, um/K, each with the sensor roles of which at least one
brings it in (none: always)."""


# ------------------------------------------------------------------------ effect spec table


@dataclass(frozen=True)
class EffectSpecs:
    """What a candidate effect needs and brings into the twin.

    Attributes
    ----------
    roles : tuple of str
        Sensor roles the campaigns need for the effect to be testable.
    params : tuple of ParamSpec
        Parameters it adds (when the nodes of its roles are in the model).
    """

    roles: tuple[str, ...]
    params: tuple[ParamSpec, ...]


EFFECT_SPECS = {
    "ambient_variation": EffectSpecs(("ambient",), ()),
    "centrifugal_growth": EffectSpecs(
        (),
        (
            ParamSpec(
                "centrifugal_um_per_krpm2",
                "um/krpm^2",
                -2.0,
                2.0,
                0.0,
                "centrifugal_growth",
                "instantaneous Z shift per (1000 rpm)^2",
            ),
        ),
    ),
    "nonlinear_bearing_heat": EffectSpecs(
        (),
        (
            ParamSpec(
                "bearing_exponent",
                "1",
                0.5,
                3.0,
                1.0,
                "nonlinear_bearing_heat",
                "exponent a of bearing friction heat ~ rpm^a",
            ),
        ),
    ),
    "sensor_lag": EffectSpecs(
        (),
        (
            ParamSpec(
                "sensor_lag_s",
                "s",
                60.0,
                7200.0,
                120.0,
                "sensor_lag",
                "first-order time constant of every temperature sensor",
            ),
        ),
    ),
    "thermal_bending": EffectSpecs(
        ("column_front", "column_rear"),
        (
            ParamSpec(
                "bending_um_per_K",
                "um/K",
                -50.0,
                50.0,
                0.0,
                "thermal_bending",
                "Z per kelvin of column front-minus-rear rise (bending)",
            ),
        ),
    ),
    "motor_heat": EffectSpecs(
        ("spindle_motor",),
        (
            ParamSpec(
                "q_motor_W_per_krpm",
                "W/krpm",
                0.0,
                200.0,
                5.0,
                "motor_heat",
                "spindle-motor loss into the motor node per 1000 rpm",
            ),
            ParamSpec(
                "motor_exponent",
                "1",
                1.0,
                3.0,
                1.0,
                "motor_heat",
                "exponent b of the motor loss ~ rpm^b",
            ),
        ),
    ),
}
"""Row of each candidate effect (units and bounds):

- ``ambient_variation``: none (the measured ambient drives the existing convection);
- ``centrifugal_growth``: ``centrifugal_um_per_krpm2`` in [-2, 2] um/krpm^2 (z = c
  ((rpm/1000)^2 - (rpm0/1000)^2); +-72 um at 6000 rpm at the bounds);
- ``nonlinear_bearing_heat``: ``bearing_exponent`` in [0.5, 3] (q ~ rpm^a, equal to the linear
  law at :data:`REFERENCE_RPM`); it starts at 1, the baseline's linear law, so the
  recalibration starts from the current model's optimum (a start inside the typical 1.3-2
  lands in worse local minima);
- ``sensor_lag``: ``sensor_lag_s`` in [60, 7200] s, one first-order time constant shared by
  every sensor; it starts at 120 s, close to the baseline's direct reading. One per role would
  follow the physics (each sensor lags by its own mounting) more closely, but seven free lags
  give the twin extra dynamics that stand in for structure it lacks: on trial data without any
  lag they cut the held-out Z RMS by 39 % and were named (seed 1, centrifugal growth hidden);
- ``thermal_bending``: ``bending_um_per_K`` in [-50, 50] um/K on the column front-rear rise
  difference;
- ``motor_heat``: ``q_motor_W_per_krpm`` in [0, 200] W per 1000 rpm into the motor node, at
  :data:`REFERENCE_RPM`, and ``motor_exponent`` in [1, 3] (q ~ rpm^b, as the bearing law). A
  motor's no-load loss is iron loss, hysteresis growing with the supply frequency and eddy
  currents with its square (Steinmetz; Bertotti, 1988, "General properties of power losses in
  soft ferromagnetic materials", IEEE Transactions on Magnetics 24(1)), plus windage growing
  faster still: b = 1 is the slowest such law, and it starts there, the linear law the
  effect had before the exponent.
"""


def _speed_power_law(rpm: np.ndarray, exponent: np.ndarray) -> np.ndarray:
    """Heat law ``ref (r / ref)^exponent`` in krpm, equal to rpm / 1000 at :data:`REFERENCE_RPM`."""
    ref = REFERENCE_RPM / 1000.0
    return ref * (rpm / 1000.0 / ref) ** exponent


# ------------------------------------------------------------------------------- Z laws


def _node_rise(rise: np.ndarray, cols: list[int], prep: _Prepared) -> np.ndarray:
    """Rise of the term's node, K, shape (P, n)."""
    return rise[:, :, cols[0]]


def _mean_rise(rise: np.ndarray, cols: list[int], prep: _Prepared) -> np.ndarray:
    """Mean rise of the term's nodes present in the model, K, shape (P, n)."""
    return rise[:, :, cols].mean(axis=2)


def _rise_difference(rise: np.ndarray, cols: list[int], prep: _Prepared) -> np.ndarray:
    """Rise of the first node minus that of the second, K, shape (P, n)."""
    return rise[:, :, cols[0]] - rise[:, :, cols[1]]


def _speed_squared(rise: np.ndarray, cols: list[int], prep: _Prepared) -> np.ndarray:
    """``(rpm / 1000)^2`` minus its value at the first sample, krpm^2, shape (n,)."""
    r2 = (prep.rpm_samples / 1000.0) ** 2
    return r2 - r2[0]


@dataclass(frozen=True)
class ZTerm:
    """One Z law of the twin: ``z += sign * theta[param] * feature``, um.

    Attributes
    ----------
    param : str
        Parameter name; the law applies when the model has it.
    sign : float
        +1 (lifts the head) or -1 (moves it towards the table).
    nodes : tuple of str
        Nodes the feature reads (those present in the model, in this order).
    feature : callable ``(rise, cols, prepared) -> ndarray``
        From the node rises since the start (P, n, n_nodes), K, and the node columns.
    """

    param: str
    sign: float
    nodes: tuple[str, ...]
    feature: Callable[[np.ndarray, list[int], _Prepared], np.ndarray]


Z_TERMS = (
    ZTerm("alpha_spindle_um_per_K", -1.0, ("spindle_shaft",), _node_rise),
    ZTerm("alpha_headstock_um_per_K", -1.0, ("headstock",), _node_rise),
    ZTerm("alpha_ball_screw_um_per_K", -1.0, ("ball_screw",), _node_rise),
    ZTerm("alpha_column_um_per_K", 1.0, ("column_front", "column_rear"), _mean_rise),
    ZTerm("bending_um_per_K", 1.0, ("column_front", "column_rear"), _rise_difference),
    ZTerm("centrifugal_um_per_krpm2", 1.0, (), _speed_squared),
)
"""The Z laws in summation order (the first, the spindle's growth, is always present)."""


@dataclass(frozen=True)
class Simulation:
    """Twin output for one campaign at its sample instants.

    Attributes
    ----------
    temperatures : pandas.DataFrame of shape (n, k), degC
        Predicted reading of every sensor whose role is a node of the model.
    z_um : ndarray of shape (n,), um
        Z drift at the spindle nose since the first sample.
    nodes : pandas.DataFrame of shape (n, n_nodes), degC
        Node temperatures (including unsensed nodes).
    """

    temperatures: pd.DataFrame
    z_um: np.ndarray
    nodes: pd.DataFrame


@dataclass
class _Prepared:
    """Per-campaign quantities that do not depend on the parameters."""

    campaign: MeasuredCampaign
    grid: np.ndarray  # (L,) s
    h: np.ndarray  # (L - 1,) step lengths, s
    rpm_steps: np.ndarray  # (L - 1,) speed on each interval
    sample_idx: np.ndarray  # (n,) index of each sample instant in grid
    ambient_grid: np.ndarray  # (L,) measured ambient at the grid (degC) or NaN
    ambient0: float
    first: dict[str, float]  # sensor -> first valid reading
    role_sensors: dict[str, list[str]]  # node -> sensors of the campaign on it
    rpm_samples: np.ndarray  # (n,)
    load_steps: np.ndarray  # (n_loads, L - 1) power of each load node's load on each step, W
    x0: np.ndarray | None = None  # (ns,) initial state, degC, set on the first run


def missing_roles(effect: str, roles: Iterable[str]) -> list[str]:
    """Roles ``effect`` needs that are absent from ``roles``.

    Parameters
    ----------
    effect : str
        One of :data:`EFFECTS`.
    roles : iterable of str
        Sensor roles present in the campaigns.

    Returns
    -------
    list of str
        Empty when the effect can be tested.
    """
    _check_effect(effect)
    have = set(roles)
    return [r for r in EFFECT_SPECS[effect].roles if r not in have]


def _check_effect(effect: str) -> None:
    if effect not in EFFECT_SPECS:
        raise KeyError(f"unknown effect '{effect}'; candidate effects are {', '.join(EFFECTS)}")


def effect_specs(effect: str, nodes: Sequence[str]) -> list[ParamSpec]:
    """Parameters an effect adds to a model with ``nodes``: its row of :data:`EFFECT_SPECS`.

    An effect whose roles' nodes are not all in ``nodes`` adds none.
    """
    _check_effect(effect)
    row = EFFECT_SPECS[effect]
    needed = [ROLE_NODES[r] for r in row.roles if r in ROLE_NODES]
    return list(row.params) if all(n in nodes for n in needed) else []


def _first_readings(temps: pd.DataFrame) -> dict[str, float]:
    """First valid reading of each sensor that has one, degC."""
    first = {}
    for s in temps.columns:
        values = temps[s].to_numpy(dtype=float)
        ok = np.flatnonzero(np.isfinite(values))
        if ok.size:
            first[s] = float(values[ok[0]])
    return first


def _measured_ambient(
    campaign: MeasuredCampaign, first: dict[str, float], grid: np.ndarray
) -> tuple[np.ndarray, float]:
    """Ambient reading interpolated on ``grid`` (NaN without an ambient sensor) and at the start.

    The start value is the mean over :data:`AMBIENT_START_S`, or the mean first reading of all
    sensors without an ambient sensor, degC.
    """
    amb = [s for s in campaign.sensors_with_role("ambient") if s in first]
    if not amb:
        return np.full(grid.size, np.nan), float(np.mean(list(first.values())))
    t = campaign.t_s
    values = campaign.temperatures[amb[0]].to_numpy(dtype=float)
    ok = np.isfinite(values)
    early = ok & (t <= t[ok][0] + AMBIENT_START_S)
    return np.interp(grid, t[ok], values[ok]), float(values[early].mean())


@dataclass
class TwinModel:
    """A calibratable twin: the baseline built from roles plus the switched-on effects.

    Attributes
    ----------
    roles : frozenset of str
        Sensor roles the model was built for.
    effects : frozenset of str
    nodes : tuple of str
        Network nodes (sensed and unsensed).
    links : tuple of (str, str, str)
        ``(node_a, node_b, conductance group)``.
    param_specs : list of ParamSpec
        Baseline parameters first, then each effect's in :data:`EFFECTS` order.
    heat_nodes : dict of str to str
        Bearing heat source -> node it enters (:data:`HEAT_SPECS`).
    load_nodes : tuple of str
        Nodes that take an external heat load (``heat_loads:``) in some campaign; one input
        column each, W.
    """

    roles: frozenset[str]
    effects: frozenset[str]
    nodes: tuple[str, ...]
    links: tuple[tuple[str, str, str], ...]
    param_specs: list[ParamSpec]
    heat_nodes: dict[str, str]
    load_nodes: tuple[str, ...] = ()
    _prepared: dict[int, _Prepared] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ parameters

    @property
    def names(self) -> list[str]:
        """Parameter names in theta order."""
        return [p.name for p in self.param_specs]

    @property
    def sensed_nodes(self) -> tuple[str, ...]:
        """Nodes that carry a sensor role of the model."""
        return tuple(n for n in self.nodes if n in ROLE_NODES.values() and _role(n) in self.roles)

    def initial(self) -> np.ndarray:
        """Return the starting parameter vector, ndarray of shape (n_params,)."""
        return np.array([p.initial for p in self.param_specs])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds, each ndarray of shape (n_params,)."""
        return (
            np.array([p.lower for p in self.param_specs]),
            np.array([p.upper for p in self.param_specs]),
        )

    def check_theta(self, theta: np.ndarray) -> np.ndarray:
        """Return ``theta`` as floats; raise ValueError if its length or bounds are wrong."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (len(self.param_specs),):
            raise ValueError(
                f"theta has shape {theta.shape} but the model has {len(self.param_specs)} "
                f"parameters ({', '.join(self.names)})"
            )
        lo, hi = self.bounds()
        bad = [
            f"{p.name}={v:g} not in [{p.lower:g}, {p.upper:g}] {p.unit}"
            for p, v in zip(self.param_specs, theta, strict=True)
            if not (p.lower <= v <= p.upper)
        ]
        if bad:
            raise ValueError("parameters out of bounds: " + "; ".join(bad))
        return theta

    def values(self, theta: np.ndarray) -> dict[str, float]:
        """Parameter name -> value."""
        return dict(zip(self.names, (float(v) for v in theta), strict=True))

    # ------------------------------------------------------------------ network

    @property
    def node_index(self) -> dict[str, int]:
        """Node name -> position in :attr:`nodes` (and in the state vector)."""
        return {node: i for i, node in enumerate(self.nodes)}

    def lag_nodes(self) -> np.ndarray:
        """Positions of the nodes read through a lag state (``sensor_lag``), int array."""
        if "sensor_lag" not in self.effects:
            return np.zeros(0, dtype=int)
        idx = self.node_index
        return np.array([idx[s] for s in self.sensed_nodes], dtype=int)

    def network(self, p: dict[str, float]) -> ThermalNetwork:
        """Return the kernel's thermal network for parameter values ``p`` (name -> value)."""
        return ThermalNetwork(
            self.nodes,
            tuple(p[f"C_{CAPACITY_GROUP[node]}_J_per_K"] for node in self.nodes),
            tuple(p[f"h_{CONVECTION_GROUP[node]}_W_per_K"] for node in self.nodes),
            tuple((a, b, p[f"G_{group}_W_per_K"]) for a, b, group in self.links),
        )

    def heat_input(self, p: dict[str, float], network: ThermalNetwork) -> np.ndarray:
        """Heat input matrix of the kernel's state space, shape (n_nodes, 2 + n_loads).

        Column 0 takes the bearing law (rpm / 1000, or its nonlinear form): each bearing
        source's ``q`` enters its node, a share ``bearing_heat_to_shaft`` of it the shaft;
        column 1 takes the motor law (rpm / 1000, or rpm^b) into the motor node (``motor_heat``),
        both K/s per krpm;
        column ``2 + j`` takes the external load on :attr:`load_nodes` ``[j]``, K/s per W.
        """
        idx = self.node_index
        cinv = 1.0 / network.capacities
        heat = np.zeros((len(self.nodes), 2 + len(self.load_nodes)))
        for j, node in enumerate(self.load_nodes):
            heat[idx[node], 2 + j] = cinv[idx[node]]
        share = p.get("bearing_heat_to_shaft", 0.0)
        shaft = idx["spindle_shaft"]
        for source, node in self.heat_nodes.items():
            q = p[f"q_{source}_W_per_krpm"]
            heat[idx[node], 0] += cinv[idx[node]] * q * (1.0 - share)
            heat[shaft, 0] += cinv[shaft] * q * share
        if "motor" in idx and "q_motor_W_per_krpm" in p:
            heat[idx["motor"], 1] = cinv[idx["motor"]] * p["q_motor_W_per_krpm"]
        return heat

    def system(self, p: dict[str, float]) -> LinearSystem:
        """State space ``dx/dt = A x + B u``, ``u = [T_amb, bearing law, motor law, loads]``.

        States are the nodes, then one lag state per sensed node with ``sensor_lag``.
        """
        network = self.network(p)
        lag_nodes = tuple(int(i) for i in self.lag_nodes())
        taus = (p["sensor_lag_s"],) * len(lag_nodes) if lag_nodes else ()
        return build_system(network, lag_nodes, taus, heat_input=self.heat_input(p, network))

    # ------------------------------------------------------------------ preparation

    def prepare(self, campaign: MeasuredCampaign) -> _Prepared:
        """Precompute (and cache) what does not depend on the parameters for a campaign."""
        key = id(campaign)
        cached = self._prepared.get(key)
        if cached is not None and cached.campaign is campaign:
            return cached
        t = campaign.t_s
        program = campaign.program
        breaks = np.zeros(0) if program is None else program.breakpoints_s()
        loads = self._load_programs(campaign)
        breaks = np.concatenate([breaks, *(load.breakpoints_s() for load in loads)])
        grid = time_grid(t, breaks, start_s=t[0])
        if program is not None:
            rpm_steps = program.value_at(grid[:-1])
        else:  # zero-order hold of the sampled speed
            rpm_steps = campaign.rpm[np.searchsorted(t, grid[:-1], side="right") - 1]
        first = _first_readings(campaign.temperatures)
        ambient_grid, ambient0 = _measured_ambient(campaign, first, grid)
        prepared = _Prepared(
            campaign=campaign,
            grid=grid,
            h=np.round(np.diff(grid), 3),
            rpm_steps=np.abs(rpm_steps),
            sample_idx=np.searchsorted(grid, t),
            ambient_grid=ambient_grid,
            ambient0=ambient0,
            first=first,
            role_sensors=self._role_sensors(campaign, first),
            rpm_samples=np.abs(campaign.rpm),
            load_steps=np.array([load.value_at(grid[:-1]) for load in loads]).reshape(
                len(loads), grid.size - 1
            ),
        )
        self._prepared[key] = prepared
        return prepared

    def _load_programs(self, campaign: MeasuredCampaign) -> list[Program]:
        """Power program of each of :attr:`load_nodes` in ``campaign`` (W; empty = no load).

        Raises
        ------
        ValueError
            If the campaign has a load on a role whose node the model lacks.
        """
        by_node = {ROLE_NODES.get(load.role): load.program for load in campaign.heat_loads}
        lacking = sorted(
            load.role
            for load in campaign.heat_loads
            if ROLE_NODES.get(load.role) not in self.load_nodes
        )
        if lacking:
            raise ValueError(
                f"campaign {campaign.campaign_id}: heat load on role(s) {lacking}, which the twin "
                f"takes loads on only at {list(self.load_nodes)}; build it with "
                "load_roles=loaded_roles(campaigns)"
            )
        return [by_node.get(node, Program(())) for node in self.load_nodes]

    def _role_sensors(
        self, campaign: MeasuredCampaign, first: dict[str, float]
    ) -> dict[str, list[str]]:
        """Node -> the campaign's sensors on it that have a reading, in column order."""
        role_sensors: dict[str, list[str]] = {}
        for s in campaign.temperatures.columns:
            node = ROLE_NODES.get(campaign.roles.get(s, ""))
            if node in self.nodes and s in first:
                role_sensors.setdefault(node, []).append(s)
        return role_sensors

    # ------------------------------------------------------------------ simulation

    def _bearing_law(self, rpm: np.ndarray, p: dict[str, np.ndarray]) -> np.ndarray:
        if "nonlinear_bearing_heat" in self.effects:
            return _speed_power_law(rpm, p["bearing_exponent"])
        return rpm / 1000.0

    def _ambient(self, prep: _Prepared) -> np.ndarray:
        """Air at the grid: measured with ``ambient_variation`` (if complete), else constant."""
        if "ambient_variation" in self.effects and np.all(np.isfinite(prep.ambient_grid)):
            return prep.ambient_grid
        return np.full(prep.grid.size, prep.ambient0)

    def _initial_state(self, prep: _Prepared, n_states: int) -> np.ndarray:
        assigned: dict[str, float] = {}
        for node, sensors in prep.role_sensors.items():
            assigned[node] = sum(prep.first[s] for s in sensors) / len(sensors)
        for node in self.nodes:
            if node in assigned:
                continue
            near = [
                assigned[b if a == node else a]
                for a, b, _ in self.links
                if node in (a, b) and (b if a == node else a) in assigned
            ]
            assigned[node] = sum(near) / len(near) if near else prep.ambient0
        values = [assigned[node] for node in self.nodes]
        if "sensor_lag" in self.effects:
            values += [assigned[node] for node in self.sensed_nodes]
        return np.array(values[:n_states])

    def _step_inputs(
        self, p: dict[str, np.ndarray], preps: list[_Prepared], hs: np.ndarray, shape: tuple
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Stack the campaigns' step lengths, inputs and initial states for the kernel.

        Parameters
        ----------
        p : dict of str to ndarray of shape (P, 1)
        preps : list of _Prepared
        hs : ndarray of shape (n_h,), s
            Distinct step lengths of all campaigns.
        shape : tuple of int
            ``(P, n_states, n_inputs)``.

        Returns
        -------
        H, U, dU, X0
            As :func:`pipeline.thermal.stepping.propagate` takes them; a campaign shorter
            than the longest is padded with zero inputs.
        """
        n_p, ns, ni = shape
        n_c = len(preps)
        L = max(pr.grid.size for pr in preps)
        H = np.zeros((n_c, L - 1), dtype=int)
        U = np.zeros((n_p, L - 1, n_c, ni))
        dU = np.zeros((L - 1, n_c, ni))
        X0 = np.empty((n_c, ns))
        motor = "q_motor_W_per_krpm" in p
        for c, pr in enumerate(preps):
            k = pr.h.size
            H[c, :k] = np.searchsorted(hs, pr.h)
            amb = self._ambient(pr)
            U[:, :k, c, 0] = amb[:-1]
            U[:, :k, c, 1] = self._bearing_law(pr.rpm_steps[None, :], p)
            if motor:
                U[:, :k, c, 2] = _speed_power_law(pr.rpm_steps[None, :], p["motor_exponent"])
            U[:, :k, c, 3:] = pr.load_steps.T
            dU[:k, c, 0] = np.diff(amb)
            if pr.x0 is None:
                pr.x0 = self._initial_state(pr, ns)
            X0[c] = pr.x0
        return H, U, dU, X0

    def _z(self, p: dict[str, np.ndarray], rise: np.ndarray, prep: _Prepared) -> np.ndarray:
        """Sum of the :data:`Z_TERMS` the model has, um, shape (P, n)."""
        idx = self.node_index
        z = None
        for term in Z_TERMS:
            if term.param not in p:
                continue
            cols = [idx[node] for node in term.nodes if node in idx]
            part = (term.sign * p[term.param]) * term.feature(rise, cols, prep)
            z = part if z is None else z + part
        return z

    def _outputs(
        self, p: dict[str, np.ndarray], prep: _Prepared, xs: np.ndarray, x0: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Return readings, nodes and Z of a campaign from its states at the samples (P, n, ns)."""
        n = len(self.nodes)
        lag_nodes = self.lag_nodes()
        nodes = xs[:, :, :n]
        readings = nodes.copy()
        readings[:, :, lag_nodes] = xs[:, :, n : n + lag_nodes.size]
        rise = nodes - x0[:n]
        return {"readings": readings, "nodes": nodes, "z_um": self._z(p, rise, prep)}

    def run(self, theta: np.ndarray, campaigns: Sequence[MeasuredCampaign]) -> list[dict]:
        """Simulate several campaigns together; raw arrays (used by the calibration).

        Each sensed node starts at its sensors' first reading.

        Returns
        -------
        list of dict
            Per campaign: ``readings`` (n, n_nodes) degC of the state each node's sensors read
            (lagged with ``sensor_lag``), ``nodes`` (n, n_nodes) degC, ``z_um`` (n,) um.
        """
        theta = self.check_theta(theta)
        return [
            {key: value[0] for key, value in raw.items()}
            for raw in self.run_batch(theta[None, :], campaigns)
        ]

    def run_batch(self, thetas: np.ndarray, campaigns: Sequence[MeasuredCampaign]) -> list[dict]:
        """Simulate several campaigns for several parameter vectors in one vectorised pass.

        The calibration's finite-difference Jacobian needs one simulation per parameter; doing
        them together costs a few single simulations (one batched matrix exponential, one time
        loop over the stacked states) instead of one Python time loop each.

        Parameters
        ----------
        thetas : ndarray of shape (P, n_params)
            Parameter vectors, each within the bounds (not checked here).
        campaigns : sequence of MeasuredCampaign

        Returns
        -------
        list of dict
            Per campaign: ``readings`` and ``nodes`` (P, n, n_nodes) degC, ``z_um`` (P, n) um.
        """
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        p = {name: thetas[:, i, None] for i, name in enumerate(self.names)}  # (P, 1) each
        preps = [self.prepare(c) for c in campaigns]
        systems = [self.system(self.values(th)) for th in thetas]
        A = np.stack([s.A for s in systems])
        B = np.stack([s.B for s in systems])
        hs = np.unique(np.concatenate([pr.h for pr in preps]))
        phi, g0, g1 = foh_matrices(A, B, hs)  # (P, n_h, ns, ns), (P, n_h, ns, ni) x 2
        H, U, dU, X0 = self._step_inputs(p, preps, hs, (thetas.shape[0], *B.shape[1:]))
        X = propagate(A, phi, g0, g1, U, dU, X0, H, hs)  # (P, L, n_c, ns)
        return [self._outputs(p, pr, X[:, pr.sample_idx, c], X0[c]) for c, pr in enumerate(preps)]

    def sensor_predictions(self, campaign: MeasuredCampaign, raw: dict) -> pd.DataFrame:
        """Predicted readings per sensor of ``campaign`` from a :meth:`run` result, degC."""
        prep = self.prepare(campaign)
        idx = {node: i for i, node in enumerate(self.nodes)}
        cols = {}
        for node, sensors in prep.role_sensors.items():
            series = raw["readings"][:, idx[node]]
            for s in sensors:
                cols[s] = prep.first[s] + (series - series[0])
        order = [s for s in campaign.temperatures.columns if s in cols]
        return pd.DataFrame({s: cols[s] for s in order}, index=range(campaign.t_s.size))

    def simulate_many(
        self, theta: np.ndarray, campaigns: Sequence[MeasuredCampaign]
    ) -> list[Simulation]:
        """Simulate several campaigns with the same parameters (one discretisation)."""
        with threadpool_limits(limits=1):  # BLAS threads only slow down these small matrices
            raws = self.run(theta, campaigns)
        return [
            Simulation(
                temperatures=self.sensor_predictions(c, r),
                z_um=r["z_um"],
                nodes=pd.DataFrame(r["nodes"], columns=list(self.nodes)),
            )
            for c, r in zip(campaigns, raws, strict=True)
        ]

    def simulate(self, theta: np.ndarray, campaign: MeasuredCampaign) -> Simulation:
        """Simulate one campaign.

        Parameters
        ----------
        theta : ndarray of shape (n_params,)
            Parameter values in :attr:`param_specs` order, within their bounds.
        campaign : MeasuredCampaign

        Returns
        -------
        Simulation
        """
        return self.simulate_many(theta, [campaign])[0]


def _role(node: str) -> str:
    return {v: k for k, v in ROLE_NODES.items()}.get(node, node)


def _network(roles: set[str]) -> tuple[tuple[str, ...], tuple[tuple[str, str, str], ...]]:
    sensed = {ROLE_NODES[r] for r in roles if r in ROLE_NODES}
    present = sensed | {"spindle_shaft", "headstock"}
    nodes = tuple(n for n in NODE_ORDER if n in present)
    links: list[tuple[str, str, str]] = []
    bearings = [b for b in ("front_bearing", "rear_bearing") if b in present]
    for b in bearings:
        links.append((b, "spindle_shaft", "bearing_shaft"))
        links.append((b, "headstock", "bearing_headstock"))
    if not bearings:
        links.append(("spindle_shaft", "headstock", "shaft_headstock"))
    if "motor" in present:
        links.append(("motor", "headstock", "motor_headstock"))
    columns = [c for c in ("column_front", "column_rear") if c in present]
    if columns:
        links.append(("headstock", columns[0], "headstock_column"))
    if len(columns) == 2:
        links.append(("column_front", "column_rear", "column_front_rear"))
    if "bed" in present:
        for c in columns:
            links.append((c, "bed", "column_bed"))
        if not columns:
            links.append(("headstock", "bed", "headstock_bed"))
    if "ball_screw" in present:
        links.append(("ball_screw", "headstock", "screw_headstock"))
        if columns:
            links.append(("ball_screw", columns[0], "screw_column"))
    return nodes, tuple(links)


def _heat_nodes(nodes: Sequence[str]) -> dict[str, str]:
    """Bearing heat source -> node it enters: each bearing's own node, else the shaft."""
    if "front_bearing" in nodes or "rear_bearing" in nodes:
        return {b: b if b in nodes else "spindle_shaft" for b in ("front_bearing", "rear_bearing")}
    return {"bearing": "spindle_shaft"}


def baseline_specs(
    nodes: Sequence[str], links: Sequence[tuple[str, str, str]], sensed_roles: Sequence[str]
) -> tuple[list[ParamSpec], dict[str, str]]:
    """Baseline parameters, read from the spec tables, and the heat node of each source.

    Parameters
    ----------
    nodes : sequence of str
        Network nodes.
    links : sequence of (str, str, str)
        ``(node_a, node_b, link kind)``.
    sensed_roles : sequence of str
        Sensor roles that are nodes.

    Returns
    -------
    specs : list of ParamSpec
        Capacities, convections and conductances of the groups present (first-seen order),
        the bearing heat share (with a bearing node), the heat of each source, the expansion
        coefficients whose roles are sensed.
    heat_nodes : dict of str to str
        Bearing heat source -> node it enters.
    """
    specs = [CAPACITY_SPECS[g] for g in dict.fromkeys(CAPACITY_GROUP[n] for n in nodes)]
    specs += [CONVECTION_SPECS[g] for g in dict.fromkeys(CONVECTION_GROUP[n] for n in nodes)]
    specs += [LINK_SPECS[g] for g in dict.fromkeys(g for _, _, g in links)]
    heat_nodes = _heat_nodes(nodes)
    if "bearing" not in heat_nodes:
        specs.append(BEARING_SHARE_SPEC)
    specs += [HEAT_SPECS[source, node] for source, node in heat_nodes.items()]
    specs += [
        spec for spec, roles in DISPLACEMENT_SPECS if not roles or set(roles) & set(sensed_roles)
    ]
    return specs, heat_nodes


def build_model(
    roles: Iterable[str], effects: Iterable[str] = frozenset(), load_roles: Iterable[str] = ()
) -> TwinModel:
    """Build the calibratable twin for the sensor roles present and the effects switched on.

    Parameters
    ----------
    roles : iterable of str
        Sensor roles of the campaigns (any subset; ``ambient``, ``other`` etc. are not nodes).
    effects : iterable of str
        Names from :data:`EFFECTS`.
    load_roles : iterable of str
        Structure roles that take an external heat load in some campaign
        (:func:`loaded_roles`); a role without a sensor still gets its node.

    Returns
    -------
    TwinModel

    Raises
    ------
    ValueError
        If no role is a structure node, or an effect needs a role that is absent.
    KeyError
        For an unknown effect name.
    """
    if isinstance(effects, str):
        raise TypeError(f"effects must be a collection of names; write frozenset({{'{effects}'}})")
    roles = frozenset(roles)
    effects = frozenset(effects)
    for e in sorted(effects):
        _check_effect(e)
        lacking = missing_roles(e, roles)
        if lacking:
            raise ValueError(
                f"effect '{e}' needs sensor role(s) {lacking}, absent from the campaigns; "
                "it cannot be tested on these data (leave it out)"
            )
    sensed = [r for r in ROLE_NODES if r in roles]
    if not sensed:
        raise ValueError(
            f"no sensor has a structure role (roles present: {sorted(roles)}); give at least "
            f"one sensor one of {', '.join(ROLE_NODES)} in campaign.yaml"
        )
    unknown = sorted(set(load_roles) - set(ROLE_NODES))
    if unknown:
        raise ValueError(
            f"heat loads on role(s) {unknown}, which are not structure parts of the twin; put "
            f"a load on one of {', '.join(ROLE_NODES)}"
        )
    nodes, links = _network(set(roles) | set(load_roles))
    load_nodes = tuple(n for n in nodes if _role(n) in set(load_roles))
    specs, heat_nodes = baseline_specs(nodes, links, sensed)
    for e in EFFECTS:
        if e in effects:
            specs += effect_specs(e, nodes)
    logger.debug(
        "twin model: nodes %s, effects %s, %d parameters", nodes, sorted(effects), len(specs)
    )
    return TwinModel(roles, effects, nodes, links, specs, heat_nodes, load_nodes)


def loaded_roles(campaigns: Iterable[MeasuredCampaign]) -> frozenset[str]:
    """Structure roles that take an external heat load in any of ``campaigns``."""
    return frozenset(load.role for c in campaigns for load in c.heat_loads)

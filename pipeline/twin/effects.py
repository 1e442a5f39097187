"""Library of named physical terms of the twin, and the registry of switchable effects.

A model is a tuple of :class:`Term` objects, each filling one *slot*:

``heat``
    ``func(params, drive) -> ndarray (k, n_nodes)``, W: heat into each node for each value of
    the drive (spindle rpm or axis feed mm/s); the terms of the slot add up.
``ambient``
    ``func(ambient, t_s) -> ndarray (k,)``, degC: the air temperature the structure sees.
``displacement``
    ``func(params, rise_K, drive) -> ndarray (n_t,)``, um: a Z component at the spindle nose
    from the node temperature rises ``rise_K`` (n_t, n_nodes) since the start; terms add up.
``sensor``
    ``func(params) -> float or tuple of float``: first-order time constant (s) through which
    each sensor reads its node, one value for all sensors or one per sensor of
    ``params.sensors``; 0 = reads it directly.

The *baseline* of a machine is a fixed tuple of terms (spindle: bearing friction heat
proportional to speed, constant ambient equal to its value at the start, uniform expansion of
spindle and column, direct sensors). An :class:`Effect` is a named switch that adds a term or
replaces a baseline term; :func:`model_terms` assembles the model for a set of effect names.
The ``discrepancy`` workflow switches effects by these names.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

SLOTS = ("heat", "ambient", "displacement", "sensor")
MACHINES = ("spindle", "axis")


@dataclass(frozen=True)
class Term:
    """One physical term of a model.

    Attributes
    ----------
    name : str
        Identifier, e.g. ``"bearing_friction_heat"``; displacement terms also name the
        ``z_<name>_um`` column of the simulation output.
    slot : str
        One of :data:`SLOTS`.
    description : str
        What it is, in a machine-tool engineer's words.
    func : callable
        See the module docstring for the signature of each slot.
    """

    name: str
    slot: str
    description: str
    func: Callable[..., Any]


@dataclass(frozen=True)
class Effect:
    """A switchable physical effect.

    Attributes
    ----------
    name : str
        Registry key (e.g. ``"motor_heat"``).
    description : str
        What switching it on changes, in words.
    term : Term
        The term it brings in.
    replaces : str or None
        Name of the baseline term it replaces, None if it adds ``term``.
    machines : tuple of str
        Machines it applies to (``"spindle"``, ``"axis"``); ignored for the others.
    changes : tuple of str
        Outputs it changes: any of ``"ambient"``, ``"temperatures"``, ``"sensors"``, ``"z"``.
    """

    name: str
    description: str
    term: Term
    replaces: str | None
    machines: tuple[str, ...]
    changes: tuple[str, ...]


# --------------------------------------------------------------------------- heat terms


def _rate(drive: np.ndarray, reference: float) -> np.ndarray:
    return np.abs(np.asarray(drive, dtype=float)) / reference


def _bearing_heat(params: Any, rpm: np.ndarray, exponent: float) -> np.ndarray:
    net = params.network
    r = _rate(rpm, params.reference_rpm) ** exponent
    total = (params.front_bearing_heat_w + params.rear_bearing_heat_w) * r
    housing = 1.0 - params.bearing_heat_to_shaft
    q = np.zeros((r.size, len(net.nodes)))
    q[:, net.index("front_bearing")] = housing * params.front_bearing_heat_w * r
    q[:, net.index("rear_bearing")] = housing * params.rear_bearing_heat_w * r
    q[:, net.index("spindle_shaft")] = params.bearing_heat_to_shaft * total
    return q


def bearing_friction_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Front/rear bearing friction ``q = Q_ref * rpm / rpm_ref``, W, shape (k, n_nodes).

    A fraction ``bearing_heat_to_shaft`` enters the shaft through the inner rings, the rest
    the bearing housings.
    """
    return _bearing_heat(params, rpm, 1.0)


def nonlinear_bearing_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Bearing friction ``q = Q_ref * (rpm / rpm_ref)^a`` (Palmgren a = 5/3), W."""
    return _bearing_heat(params, rpm, params.bearing_heat_exponent)


def motor_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Spindle-motor loss ``q = Q_motor * rpm / rpm_ref`` into the motor node, W."""
    net = params.network
    q = np.zeros((np.size(rpm), len(net.nodes)))
    q[:, net.index("motor")] = params.motor_heat_w * _rate(rpm, params.reference_rpm)
    return q


def axis_friction_heat(params: Any, feed: np.ndarray) -> np.ndarray:
    """Nut, fixed-bearing, servo-motor and guideway losses proportional to feed, W."""
    net = params.network
    r = _rate(feed, params.reference_feed_mm_s)
    q = np.zeros((r.size, len(net.nodes)))
    q[:, net.index("nut")] = params.nut_heat_w * r
    q[:, net.index("screw_bearing")] = params.bearing_heat_w * r
    q[:, net.index("motor")] = params.motor_heat_w * r
    q[:, net.index("carriage")] = params.guideway_heat_w * r
    return q


# ------------------------------------------------------------------------ ambient terms


def constant_ambient(ambient: Any, t_s: np.ndarray) -> np.ndarray:
    """Air held at its value at the campaign start, degC."""
    return np.full(np.shape(t_s), float(ambient.at(0.0)))


def varying_ambient(ambient: Any, t_s: np.ndarray) -> np.ndarray:
    """Air following its season mean and daily cycle (or the given series), degC."""
    return np.asarray(ambient.at(t_s), dtype=float)


# ------------------------------------------------------------------- displacement terms


def uniform_expansion(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Free expansion of spindle shaft, headstock, Z screw (down) and column (up), um.

    ``z = 1e3 [alpha_ci H (dT_cf + dT_cr)/2 - alpha_s L_sp dT_shaft - alpha_ci L_hs dT_head
    - alpha_s L_zs dT_zscrew]`` with lengths in mm.
    """
    net = params.network
    col = 0.5 * (rise_K[:, net.index("column_front")] + rise_K[:, net.index("column_rear")])
    up = params.alpha_cast_iron_per_k * params.column_height_mm * col
    down = (
        params.alpha_steel_per_k * params.spindle_length_mm * rise_K[:, net.index("spindle_shaft")]
        + params.alpha_cast_iron_per_k
        * params.headstock_length_mm
        * rise_K[:, net.index("headstock")]
        + params.alpha_steel_per_k * params.z_screw_length_mm * rise_K[:, net.index("z_screw")]
    )
    return 1e3 * (up - down)


def thermal_bending(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Column bending from its front-rear temperature difference, seen at the nose, um.

    A front face warmer than the rear tilts the column top backwards by ``alpha H dT / W``
    rad; the nose, ``d`` in front of the column, rises: ``z = 1e3 alpha H d / W (dT_cf -
    dT_cr)`` (rises since the start, so the initial gradient gives no drift).
    """
    net = params.network
    diff = rise_K[:, net.index("column_front")] - rise_K[:, net.index("column_rear")]
    gain = (
        params.alpha_cast_iron_per_k
        * params.column_height_mm
        * params.spindle_overhang_mm
        / params.column_depth_mm
    )
    return 1e3 * gain * diff


def centrifugal_growth(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Instantaneous nose shift ``z = z_ref (rpm / rpm_ref)^2``, um (no thermal lag)."""
    return params.centrifugal_um * (np.asarray(rpm, dtype=float) / params.reference_rpm) ** 2


# ------------------------------------------------------------------------- sensor terms


def direct_sensors(params: Any) -> float:
    """Sensors read their node's temperature directly (time constant 0)."""
    return 0.0


def lagged_sensors(params: Any) -> tuple[float, ...]:
    """Each sensor reads its node through a first-order lag, s, one value per sensor.

    ``tau dS/dt = T_node - S``: a sensor glued, screwed or magnet-mounted on a surface reads
    the local skin of the part through the contact resistance and its own housing, and the
    skin follows the bulk of the lumped node with a delay. The time constant is the sensor's
    ``tau_s`` (set by its mounting) or, when that is None, the machine's ``sensor_tau_s``.
    """
    return tuple(float(params.sensor_tau_s if s.tau_s is None else s.tau_s) for s in params.sensors)


# ----------------------------------------------------------------------------- registry

BASELINE_TERMS: dict[str, tuple[Term, ...]] = {
    "spindle": (
        Term(
            "bearing_friction_heat",
            "heat",
            "friction heat in the front and rear spindle bearings, proportional to speed",
            bearing_friction_heat,
        ),
        Term(
            "constant_ambient",
            "ambient",
            "workshop air constant at its value at the start",
            constant_ambient,
        ),
        Term(
            "uniform_expansion",
            "displacement",
            "uniform thermal expansion of spindle, headstock, Z screw and column",
            uniform_expansion,
        ),
        Term("direct_sensors", "sensor", "sensors read the structure directly", direct_sensors),
    ),
    "axis": (
        Term(
            "axis_friction_heat",
            "heat",
            "nut, fixed-bearing, servo-motor and guideway losses, proportional to feed",
            axis_friction_heat,
        ),
        Term(
            "constant_ambient",
            "ambient",
            "workshop air constant at its value at the start",
            constant_ambient,
        ),
        Term("direct_sensors", "sensor", "sensors read the structure directly", direct_sensors),
    ),
}

EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "ambient_variation",
            "the structure follows the workshop's daily temperature cycle and drift "
            "(off: air constant at its start value)",
            Term("varying_ambient", "ambient", "time-varying workshop air", varying_ambient),
            replaces="constant_ambient",
            machines=("spindle", "axis"),
            changes=("ambient", "temperatures", "sensors", "z"),
        ),
        Effect(
            "centrifugal_growth",
            "spindle nose shifts instantly with speed squared (centrifugal force, bearing "
            "contact angle); no temperature change",
            Term("centrifugal_growth", "displacement", "centrifugal growth", centrifugal_growth),
            replaces=None,
            machines=("spindle",),
            changes=("z",),
        ),
        Effect(
            "nonlinear_bearing_heat",
            "bearing friction heat grows as speed^a (Palmgren, a = 5/3) instead of linearly",
            Term(
                "nonlinear_bearing_heat",
                "heat",
                "bearing friction heat ~ rpm^a",
                nonlinear_bearing_heat,
            ),
            replaces="bearing_friction_heat",
            machines=("spindle",),
            changes=("temperatures", "sensors", "z"),
        ),
        Effect(
            "sensor_lag",
            "each sensor reads its location through a first-order lag set by its mounting "
            "(spindle: 4 min in a bearing housing to 20 min on the bed)",
            Term("lagged_sensors", "sensor", "first-order sensor lag", lagged_sensors),
            replaces="direct_sensors",
            machines=("spindle", "axis"),
            changes=("sensors",),
        ),
        Effect(
            "thermal_bending",
            "column bends when its front face is warmer than its rear, tilting the head",
            Term("thermal_bending", "displacement", "column thermal bending", thermal_bending),
            replaces=None,
            machines=("spindle",),
            changes=("z",),
        ),
        Effect(
            "motor_heat",
            "spindle-motor losses heat the motor and, through it, the headstock",
            Term("motor_heat", "heat", "spindle-motor loss", motor_heat),
            replaces=None,
            machines=("spindle",),
            changes=("temperatures", "sensors", "z"),
        ),
    )
}
"""Switchable effects by name; exactly these six."""

DEMO_EFFECTS = frozenset(
    {"ambient_variation", "motor_heat", "nonlinear_bearing_heat", "sensor_lag", "thermal_bending"}
)
"""Effects switched on in the demo campaigns (never written to the campaign files)."""


def check_effects(effects: Iterable[str]) -> frozenset[str]:
    """Return the names as a frozenset; raise KeyError naming any unknown effect.

    Raises
    ------
    KeyError
        ``unknown effect 'x'; known effects: ...``.
    """
    if isinstance(effects, str):
        raise TypeError(
            f"effects must be a collection of names, not the string '{effects}'; "
            f"write frozenset({{'{effects}'}})"
        )
    names = frozenset(effects)
    for name in sorted(names):
        if name not in EFFECTS:
            raise KeyError(f"unknown effect '{name}'; known effects: {', '.join(sorted(EFFECTS))}")
    return names


def model_terms(machine: str, effects: Iterable[str]) -> tuple[Term, ...]:
    """Assemble the terms of ``machine`` with the given effects switched on.

    Parameters
    ----------
    machine : str
        ``"spindle"`` or ``"axis"``.
    effects : iterable of str
        Effect names from :data:`EFFECTS`; effects that do not apply to ``machine`` are
        skipped (logged at debug level).

    Returns
    -------
    tuple of Term
        Baseline terms, with replaced ones swapped and added ones appended in the order of
        :data:`EFFECTS`.
    """
    if machine not in BASELINE_TERMS:
        raise KeyError(f"unknown machine '{machine}'; known: {', '.join(BASELINE_TERMS)}")
    names = check_effects(effects)
    terms = list(BASELINE_TERMS[machine])
    for name, effect in EFFECTS.items():
        if name not in names:
            continue
        if machine not in effect.machines:
            logger.debug("effect %s does not apply to the %s twin; skipped", name, machine)
            continue
        if effect.replaces is None:
            terms.append(effect.term)
        else:
            terms = [effect.term if t.name == effect.replaces else t for t in terms]
    return tuple(terms)


def slot_terms(terms: Iterable[Term], slot: str) -> tuple[Term, ...]:
    """Return the terms of one slot, in model order."""
    if slot not in SLOTS:
        raise KeyError(f"unknown slot '{slot}'; slots are {SLOTS}")
    return tuple(t for t in terms if t.slot == slot)

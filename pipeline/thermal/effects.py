"""The registry of switchable physical effects and the slots a model's terms fill.

A model is a tuple of terms, each filling one *slot*:

``heat``
    Heat into the nodes for each value of the drive (spindle rpm or axis feed mm/s), W; the
    terms of the slot add up.
``ambient``
    The air temperature the structure sees, degC.
``displacement``
    A Z component at the spindle nose from the node temperature rises since the start, um;
    the terms of the slot add up.
``sensor``
    The first-order time constant (s) through which each sensor reads its node; 0 = directly.

The *baseline* of a machine is a fixed tuple of terms (:data:`BASELINE_TERMS`; spindle: bearing
friction heat proportional to speed, constant ambient equal to its value at the start, uniform
expansion of spindle and column, direct sensors). An :class:`Effect` is a named switch that
adds a term or replaces a baseline term; :func:`term_names` lists the terms of a machine for a
set of effect names. The registry names the physics; each parameterisation implements the
terms: the generator's fixed machine (:mod:`pipeline.twin.effects`) and the calibrated,
role-built twin (:mod:`pipeline.discrepancy.model`, whose candidate effects are these names).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

logger = logging.getLogger(__name__)

SLOTS = ("heat", "ambient", "displacement", "sensor")
MACHINES = ("spindle", "axis")


@dataclass(frozen=True)
class Term:
    """One physical term of a model, as implemented by a parameterisation.

    Attributes
    ----------
    name : str
        Identifier, e.g. ``"bearing_friction_heat"``; displacement terms also name the
        ``z_<name>_um`` column of the generator's output.
    slot : str
        One of :data:`SLOTS`.
    description : str
        What it is, in a machine-tool engineer's words.
    func : callable
        The law; its signature is the parameterisation's (see :mod:`pipeline.twin.effects`).
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
    term : str
        Name of the term it brings in.
    slot : str
        Slot of that term, one of :data:`SLOTS`.
    replaces : str or None
        Name of the baseline term it replaces, None if it adds ``term``.
    machines : tuple of str
        Machines it applies to (``"spindle"``, ``"axis"``); ignored for the others.
    changes : tuple of str
        Outputs it changes: any of ``"ambient"``, ``"temperatures"``, ``"sensors"``, ``"z"``.
    """

    name: str
    description: str
    term: str
    slot: str
    replaces: str | None
    machines: tuple[str, ...]
    changes: tuple[str, ...]


BASELINE_TERMS: dict[str, tuple[str, ...]] = {
    "spindle": ("bearing_friction_heat", "constant_ambient", "uniform_expansion", "direct_sensors"),
    "axis": ("axis_friction_heat", "constant_ambient", "direct_sensors"),
}
"""Baseline term names of each machine, in model order."""

EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "ambient_variation",
            "the structure follows the workshop's daily temperature cycle and drift "
            "(off: air constant at its start value)",
            term="varying_ambient",
            slot="ambient",
            replaces="constant_ambient",
            machines=("spindle", "axis"),
            changes=("ambient", "temperatures", "sensors", "z"),
        ),
        Effect(
            "centrifugal_growth",
            "spindle nose shifts instantly with speed squared (centrifugal force, bearing "
            "contact angle); no temperature change",
            term="centrifugal_growth",
            slot="displacement",
            replaces=None,
            machines=("spindle",),
            changes=("z",),
        ),
        Effect(
            "nonlinear_bearing_heat",
            "bearing friction heat grows as speed^a (Palmgren, a = 5/3) instead of linearly",
            term="nonlinear_bearing_heat",
            slot="heat",
            replaces="bearing_friction_heat",
            machines=("spindle",),
            changes=("temperatures", "sensors", "z"),
        ),
        Effect(
            "sensor_lag",
            "each sensor reads its location through a first-order lag set by its mounting "
            "(spindle: 4 min in a bearing housing to 20 min on the bed)",
            term="lagged_sensors",
            slot="sensor",
            replaces="direct_sensors",
            machines=("spindle", "axis"),
            changes=("sensors",),
        ),
        Effect(
            "thermal_bending",
            "column bends when its front face is warmer than its rear, tilting the head",
            term="thermal_bending",
            slot="displacement",
            replaces=None,
            machines=("spindle",),
            changes=("z",),
        ),
        Effect(
            "motor_heat",
            "spindle-motor losses heat the motor and, through it, the headstock",
            term="motor_heat",
            slot="heat",
            replaces=None,
            machines=("spindle",),
            changes=("temperatures", "sensors", "z"),
        ),
    )
}
"""Switchable effects by name; exactly these six, in this order."""


def check_effects(effects: Iterable[str]) -> frozenset[str]:
    """Return the names as a frozenset; raise KeyError naming any unknown effect.

    Raises
    ------
    KeyError
        ``unknown effect 'x'; known effects: ...``.
    TypeError
        If ``effects`` is a single string.
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


def term_names(machine: str, effects: Iterable[str]) -> tuple[str, ...]:
    """Name the terms of ``machine`` with the given effects switched on.

    Parameters
    ----------
    machine : str
        ``"spindle"`` or ``"axis"``.
    effects : iterable of str
        Effect names from :data:`EFFECTS`; effects that do not apply to ``machine`` are
        skipped (logged at debug level).

    Returns
    -------
    tuple of str
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
            terms = [effect.term if t == effect.replaces else t for t in terms]
    return tuple(terms)


def slot_terms(terms: Iterable[Term], slot: str) -> tuple[Term, ...]:
    """Return the terms of one slot, in model order."""
    if slot not in SLOTS:
        raise KeyError(f"unknown slot '{slot}'; slots are {SLOTS}")
    return tuple(t for t in terms if t.slot == slot)

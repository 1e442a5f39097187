"""The safety envelope of a proposed test: how far it may heat the machine, and how far it could.

A proposed test must not take a part beyond what the machine's own running took it to
(:func:`largest_rise_k`, at least :data:`ENVELOPE_FLOOR_K`). What a test could do is bounded
two ways (:class:`PlanRise`):

- **by the twin**: the peak rise of the plan's campaign over draws from the planning twin's
  posterior (:func:`~pipeline.discrepancy.plan_proposal.plan_rises`);
- **by physics, for a first heating**: a heater on a part no campaign heated directly is an
  extrapolation the calibration cannot vouch for. On the demo campaigns the baseline ties the
  motor node to the headstock (conductance at its 500 W/K bound, capacity at its 1e3 J/K
  bound) and the twin with ``motor_heat`` makes it a 6e5 J/K lump; both expect a 500 W heater
  to warm the motor by a few kelvin in 2 h, where the demo generator's motor passed the
  ingest's 80 degC range. Whatever the conductances, a part cannot warm faster than its
  energy over its heat capacity, so the rise of such a load is bounded by the energy it
  delivers over the part's smallest plausible capacity (:func:`adiabatic_rise_k`): the
  capacity spec's typical value :data:`FIRST_HEATING_PRIOR_SDS` prior scales below it (a
  factor e^-2 at the default ``prior_log_sd`` 1; the 2.3 % point of the prior), not below its
  bound. This admits short pulses and small heaters; once a campaign has heated the part,
  the calibration has seen its response and the twin's bound alone holds.

The same doubt holds for what such a plan would *show*. The campaigns warmed a part no heater
touched only through its neighbours, so its heat capacity and its links are known at best as a
time constant of the whole path, and the planning twin puts them wherever that path fits. On a
trial machine written independently of the twin (four spindle campaigns), the column's
capacity came out at 9e6 J/K per face and its front-to-rear conductance at 330 W/K (the
machine's, nominal: 2.6e5 J/K per face, 18 W/K): the twin expected a 500 W heater on a column
face to warm it by under 1 K in 2 h, with a front-to-rear difference under a tenth of the
machine's, and found no plan that would show the bending; a 15 min pulse of 500 W on the rear
face, run on two days, then named it at 5.6 sigma. A plan heating a part for the first time is
therefore also scored with that part's parameters at their typical values
(:func:`first_heating_values`): what the part would show if it were the machine tool part its
specs describe.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import (
    CAPACITY_GROUP,
    CAPACITY_SPECS,
    CONVECTION_GROUP,
    CONVECTION_SPECS,
    LINK_SPECS,
    ROLE_NODES,
    TwinModel,
)
from pipeline.thermal.loads import HeatLoad

ENVELOPE_FLOOR_K = 10.0
"""Smallest rise a proposed test may give a part, K, however little the campaigns warmed the
machine: a spindle bearing housing runs 10-20 K above the air in normal service, so a part
warmed by 10 K is within what a machine tool meets at work."""

FIRST_HEATING_PRIOR_SDS = 2.0
"""How many prior scales below its typical value the smallest plausible heat capacity of a
part lies (:func:`smallest_capacity_j_per_k`)."""


@dataclass(frozen=True)
class PlanRise:
    """How far a plan heats the machine, K.

    Attributes
    ----------
    expected : float
        Largest rise of a sensed structure node over its first value at the planning point.
    bound : float
        The rise the plan is held to: the larger of the twin's bound over its posterior and,
        for a heater on a part no campaign heated, the adiabatic bound.
    first_heating : float
        That adiabatic bound alone (:func:`first_heating_bound_k`; 0 when the plan heats no
        part for the first time): how hard the plan drives a part the campaigns never heated,
        against its smallest plausible heat capacity.
    """

    expected: float
    bound: float
    first_heating: float = 0.0


def largest_rise_k(campaigns: Sequence[MeasuredCampaign]) -> float:
    """Largest rise of any sensor on the structure over its first reading in ``campaigns``, K.

    The envelope a proposed test must stay in: a heater that takes a part further than the
    machine's own running ever took any part risks the machine (and an ingest range check).
    """
    rises = [0.0]
    for c in campaigns:
        for s in c.temperatures.columns:
            if c.roles.get(s) in ROLE_NODES:
                values = c.temperatures[s].to_numpy(dtype=float)
                ok = values[np.isfinite(values)]
                if ok.size:
                    rises.append(float(ok.max() - ok[0]))
    return max(rises)


def rise_limit_k(campaigns: Sequence[MeasuredCampaign]) -> float:
    """Return the envelope: :func:`largest_rise_k`, at least :data:`ENVELOPE_FLOOR_K`, K."""
    return max(largest_rise_k(campaigns), ENVELOPE_FLOOR_K)


def smallest_capacity_j_per_k(role: str, prior_log_sd: float) -> float:
    """Smallest plausible heat capacity of the part of ``role``, J/K.

    The typical value of its capacity spec :data:`FIRST_HEATING_PRIOR_SDS` prior scales below
    (in the log), not below the spec's lower bound.
    """
    spec = CAPACITY_SPECS[CAPACITY_GROUP[ROLE_NODES[role]]]
    return max(spec.lower, spec.initial * float(np.exp(-FIRST_HEATING_PRIOR_SDS * prior_log_sd)))


def adiabatic_rise_k(load: HeatLoad, prior_log_sd: float) -> float:
    """Rise of the part of ``load`` if all its energy stayed in it, K.

    The energy of the load's segments (W x s) over :func:`smallest_capacity_j_per_k`.

    Raises
    ------
    ValueError
        If a segment of the load has no end.
    """
    energy = 0.0
    for segment in load.program.segments:
        if segment.to_min is None:
            raise ValueError(f"adiabatic_rise_k: the load on {load.role} has no end")
        energy += segment.value * (segment.to_min - segment.from_min) * 60.0
    return energy / smallest_capacity_j_per_k(load.role, prior_log_sd)


def first_heating_bound_k(
    loads: Iterable[HeatLoad], heated: frozenset[str], prior_log_sd: float
) -> float:
    """Largest adiabatic rise of the loads on parts not in ``heated``, K (0 if none).

    Parameters
    ----------
    loads : iterable of HeatLoad
        The plan's heat loads.
    heated : frozenset of str
        Roles some campaign put a heat load on.
    prior_log_sd : float
        Prior scale of a positive parameter, in its natural log.
    """
    return max(
        (adiabatic_rise_k(load, prior_log_sd) for load in loads if load.role not in heated),
        default=0.0,
    )


def first_heating_values(
    values: Mapping[str, float], model: TwinModel, roles: Iterable[str]
) -> dict[str, float]:
    """Return ``values`` with the parameters of the parts of ``roles`` at their typical values.

    A part's parameters are its heat capacity, its convection to the air and the conductance
    of every link to its node; they take their specs' initial values (the centre of the
    planning twin's priors). The other parameters keep ``values``.

    Parameters
    ----------
    values : mapping of str to float
        Parameter name -> value (the planning twin's), in the parameter's unit.
    model : TwinModel
        The twin of the plan's campaign (its links).
    roles : iterable of str
        Structure roles the plan heats for the first time.
    """
    nodes = {ROLE_NODES[role] for role in roles}
    names = {CAPACITY_SPECS[CAPACITY_GROUP[node]].name for node in nodes}
    names |= {CONVECTION_SPECS[CONVECTION_GROUP[node]].name for node in nodes}
    names |= {LINK_SPECS[kind].name for a, b, kind in model.links if a in nodes or b in nodes}
    typical = {p.name: p.initial for p in model.param_specs if p.name in names}
    return {**values, **typical}

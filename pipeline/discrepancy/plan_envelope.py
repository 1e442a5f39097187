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
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import CAPACITY_GROUP, CAPACITY_SPECS, ROLE_NODES
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

"""Whether the search would name an effect once a proposed test joins the campaigns.

Visible is not enough. The identifiability figure is an RMS over the plan's own samples in noise
sigmas, while the search names an effect when the held-out RMS pooled over *every* campaign
falls by ``min_heldout_reduction`` (Z) or ``min_heldout_temperature_reduction`` (temperatures).
In the hidden-effect trials a 15 min heater pulse on a column half left bending 2.5-4.5 sigma
on its campaigns, yet added to the four campaigns of a trial, which do not show it, it did not
move the pooled held-out Z by 20 %, and bending was not named (seeds 1-5); a 2-4 h heater did.

So a plan must also leave a visible response large enough to pass the search's own rule
(:func:`needed_signal`): if the search's final twin (the baseline when nothing is named) misses
every campaign by its held-out RMS ``e`` (the plan's campaigns too) and the effect adds its visible
part ``v`` (RMS over the plan's samples) to the plan's campaigns only, naming the effect takes the
pooled RMS from ``sqrt((n e^2 + m (e^2 + v^2)) / (n + m))`` to ``e``, ``n`` samples of the campaigns
and ``m`` of the plan's; a fall by ``r`` needs ``v >= e sqrt((1 / (1 - r)^2 - 1) (n + m) / m)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.search import SENSOR_ONLY_EFFECTS, SearchResult, SearchSettings
from pipeline.discrepancy.visibility import Visibility


@dataclass(frozen=True)
class HeldOutFloor:
    """What an effect must beat to be named: the search's final held-out RMS and its rule.

    Attributes
    ----------
    z_um, t_k : float
        Held-out Z RMS (um) and temperature RMS (K) of the search's final twin (the baseline
        when nothing is named), pooled over the searched campaigns.
    n_z, n_t : int
        Z samples and temperature readings those RMS pool.
    reduction_z, reduction_t : float
        ``min_heldout_reduction`` and ``min_heldout_temperature_reduction``.
    """

    z_um: float
    t_k: float
    n_z: int
    n_t: int
    reduction_z: float
    reduction_t: float


def counted_samples(campaigns: Sequence[MeasuredCampaign]) -> tuple[int, int]:
    """Return the finite Z samples and temperature readings of ``campaigns``."""
    n_z = sum(int(np.isfinite(c.z_um).sum()) for c in campaigns)
    n_t = sum(int(np.isfinite(c.temperatures.to_numpy(dtype=float)).sum()) for c in campaigns)
    return n_z, n_t


def needed_signal(floor: HeldOutFloor, plan_z: int, plan_t: int) -> tuple[float, float]:
    """Return the visible Z (um) and temperature (K) response a plan needs (module docstring).

    Parameters
    ----------
    floor : HeldOutFloor
    plan_z, plan_t : int
        Z samples and temperature readings the plan's campaigns add.
    """

    def need(e: float, n: int, m: int, r: float) -> float:
        if m <= 0 or not np.isfinite(e):
            return float("inf")
        return float(e * np.sqrt((1.0 / (1.0 - r) ** 2 - 1.0) * (n + m) / m))

    return (
        need(floor.z_um, floor.n_z, plan_z, floor.reduction_z),
        need(floor.t_k, floor.n_t, plan_t, floor.reduction_t),
    )


def would_be_named(
    effect: str, figures: Visibility, floor: HeldOutFloor, plan_z: int, plan_t: int
) -> bool:
    """Whether the effect's visible response under a plan passes the search's held-out rule.

    Z or the temperatures (the temperatures only for a sensor-only effect, which the search
    names on its temperature evidence).
    """
    need_z, need_t = needed_signal(floor, plan_z, plan_t)
    by_t = bool(figures.signal_t_k >= need_t)
    if effect in SENSOR_ONLY_EFFECTS:
        return by_t
    return by_t or bool(figures.signal_z_um >= need_z)


def held_out_floor(
    result: SearchResult, campaigns: Sequence[MeasuredCampaign], settings: SearchSettings
) -> HeldOutFloor:
    """Return the floor a further effect must beat: the final twin's held-out RMS, its rule.

    Parameters
    ----------
    result : SearchResult
    campaigns : sequence of MeasuredCampaign
        The searched campaigns (whose samples the held-out RMS pools).
    settings : SearchSettings
    """
    n_z, n_t = counted_samples(campaigns)
    return HeldOutFloor(
        z_um=result.final.rmse_heldout_um,
        t_k=result.final.rmse_heldout_t_k,
        n_z=n_z,
        n_t=n_t,
        reduction_z=settings.min_heldout_reduction,
        reduction_t=settings.min_heldout_t_reduction,
    )

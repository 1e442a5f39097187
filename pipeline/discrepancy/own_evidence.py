"""A later effect's evidence: its own, or what the effects named before it leave.

Forward selection adds, at each step, the candidate that best fits what the twin still misses.
Once an effect is named, what is left of its signature (a calibration that cannot follow it
exactly, a form that differs from the machine's) can make a second candidate pass that only
mops it up: on an independent machine model, ``thermal_bending`` was named beside the hidden
``nonlinear_bearing_heat``. A later effect is therefore named only when it passes the search's
own rule (:func:`pipeline.discrepancy.search.candidate_evidence`'s thresholds) on the campaigns
where the effects named so far act least (:func:`weak_campaigns`): there, what it fits cannot
be a remainder of theirs. Otherwise it is a *suspect*
(:func:`own_evidence_reason`), reported and left out of the twin.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pipeline.discrepancy.followup import meets_thresholds, reduction_on, signed_percent
from pipeline.discrepancy.model import EFFECT_SPECS
from pipeline.fit_statistics import root_mean_square

PHYSICAL_RANGES = {
    "bearing_exponent": (
        1.15,
        3.0,
        "bearing friction power grows at least as fast as the speed (Palmgren: a load term ~ n, "
        "a viscous term ~ n^(5/3)), so a law flatter than linear is something else that varies "
        "with speed, such as the cooling of the spindle or a drive loss",
    ),
    "bending_um_per_K": (
        0.0,
        50.0,
        "a column whose front face is warmer than its rear tilts back, and the nose, which "
        "overhangs in front of it, rises: a law of the other sign is something else that "
        "follows the column's front-minus-rear difference",
    ),
}
"""Calibrated values an effect's mechanism allows, where its bounds are wider (they let the
calibration move freely): parameter -> (lowest, highest, why). The exponent of
``nonlinear_bearing_heat`` is bounded to [0.5, 3] for the calibration; on a machine whose
spindle cooling grows with speed it settled at 0.87 and was named, fitting a flatter heat-speed
law that no bearing friction gives. From 1.15 the law is steeper than linear by more than the
load term alone explains. ``bending_um_per_K`` is bounded to [-50, 50] um/K; on an independent
machine model ``thermal_bending`` was named with a clean column (seeds 3 and 4 of five, beside
other effects too) at -6 to -40 um/K."""

RELATIVE_FLOORS = {
    "bending_um_per_K": (
        "alpha_column_um_per_K",
        0.5,
        "a column whose expansion weighs its faces unequally (the head carried on guideways on "
        "its front face) lifts the head by alpha H (w dT_front + (1 - w) dT_rear) with w in "
        "[0, 1]: beyond the baseline's law on the mean rise, a front-minus-rear law of (w - 1/2) "
        "alpha H, at most half the column's coefficient. Bending (the front warmer, the column "
        "tilts back and the nose, overhanging by d, rises by alpha H d / W on a column W deep) "
        "is told from that only above it",
    ),
}
"""Calibrated values an effect must exceed, as a share of a baseline parameter, before the fit
is its physics rather than a baseline law with another weighting: parameter -> (baseline
parameter, share, why). The independent machine model's column lifts the head by 0.8 of its
front face's growth and 0.2 of its rear's: its own front-minus-rear law is 0.3 of its column's
coefficient without bending and 0.73-1.2 with it (overhang 300-450 mm on a 500-700 mm deep
column); the twin's bending is 0.75-1.1 of it."""

Residuals = Mapping[str, Any]
"""Campaign -> held-out residual: Z (um, array) or temperatures (K, DataFrame)."""


def _signature(before: Residuals, after: Residuals) -> dict[str, float]:
    """Each campaign's fall of the held-out residual RMS, over the largest fall (0..1)."""
    fall = {
        c: root_mean_square(before[c]) - root_mean_square(after[c]) for c in after if c in before
    }
    largest = max((v for v in fall.values() if np.isfinite(v)), default=0.0)
    return {c: v / largest if largest > 0 else 0.0 for c, v in fall.items()}


def weak_campaigns(
    baseline: tuple[Residuals, Residuals], current: tuple[Residuals, Residuals]
) -> list[str]:
    """Return the campaigns where the named effects change the held-out fit least.

    The signature of the effects named so far on a campaign is how far they lowered its
    held-out residual RMS from the baseline's (um for Z, K for the temperatures), each over its
    largest fall on any campaign, the larger of the two; the campaigns at or below the median
    signature are where their evidence is weakest.

    Parameters
    ----------
    baseline, current : (Z residuals, temperature residuals)
        Held-out residuals of the baseline twin and of the twin with the effects named so far.

    Returns
    -------
    list of str
        Sorted campaign ids.
    """
    z, t = _signature(baseline[0], current[0]), _signature(baseline[1], current[1])
    strength = {c: max(z.get(c, 0.0), t.get(c, 0.0)) for c in current[0]}
    if not strength:
        return []
    median = float(np.median(list(strength.values())))
    return sorted(c for c, v in strength.items() if v <= median)


def own_evidence_reason(
    effect: str,
    named: Sequence[str],
    weak: Sequence[str],
    current: tuple[Residuals, Residuals],
    augmented: tuple[Residuals, Residuals],
    thresholds: tuple[float, float],
    by_readings_only: bool = False,
) -> str | None:
    """Return why ``effect`` is a suspect beside ``named``, or None when its evidence is its own.

    Parameters
    ----------
    effect : str
    named : sequence of str
        Effects named so far (nothing is asked of the first).
    weak : sequence of str
        :func:`weak_campaigns` of the effects named so far.
    current, augmented : (Z residuals, temperature residuals)
        Held-out residuals without and with ``effect``.
    thresholds : (float, float)
        The search's ``min_heldout_reduction`` and ``min_heldout_t_reduction``.
    by_readings_only : bool
        The effect changes the readings only (its Z route does not count).
    """
    if not named:
        return None
    z = reduction_on(weak, current[0], augmented[0])
    t = reduction_on(weak, current[1], augmented[1])
    if meets_thresholds(z, t, thresholds, by_readings_only):
        return None
    return (
        f"its evidence lies where {', '.join(named)} already act: on the campaigns where they "
        f"change the held-out fit least ({', '.join(weak)}), it changes the held-out Z by "
        f"{signed_percent(-z)} and the temperatures by {signed_percent(-t)}, short of the search's "
        f"thresholds; it may fit what {named[-1]} leaves rather than an effect of its own"
    )


def implausible_reason(effect: str, params: Mapping[str, tuple[float, str]]) -> str | None:
    """Return why the calibrated ``params`` are not the physics of ``effect``, or None.

    Parameters
    ----------
    effect : str
    params : mapping of str to (float, str)
        The augmented model's calibrated parameters (name -> (value, unit)).
    """
    own = {spec.name for spec in EFFECT_SPECS[effect].params}
    for name, (low, high, why) in PHYSICAL_RANGES.items():
        if name not in own or name not in params:
            continue
        value = float(params[name][0])
        if not low <= value <= high:
            return (
                f"its calibrated {name} = {value:.3g} lies outside {low:g}-{high:g}, what "
                f"{effect} can be: {why}"
            )
    for name, (reference, share, why) in RELATIVE_FLOORS.items():
        if name not in own or reference not in params:
            continue
        value, floor = float(params[name][0]), share * float(params[reference][0])
        if value <= floor:
            return (
                f"its calibrated {name} = {value:.3g} is not above {share:g} x {reference} = "
                f"{floor:.3g}: {why}"
            )
    return None

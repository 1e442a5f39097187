"""Structure check of an effect that moves the spindle nose at once with the speed.

Centrifugal force expands the rotating shaft and changes the bearings' contact angle with the speed
itself, not with a temperature: the nose moves within seconds of a speed change (the twin's
``centrifugal_growth`` term goes with the speed squared, at once). Its signature of its own is
therefore a step of the displacement at every speed change, where the thermal drift only turns. A
calibration can also use the term as a proxy: with a sensor that lags, the baseline's thermal
response comes too late, and a speed-squared term, which follows the program, fills part of the gap
on the held-out campaigns, although the measurement does not step where the speed changes.

:func:`step_jumps` measures, at every speed change of a campaign, the change of the held-out Z
residual from the last sample before the change to the first sample ``settle_s`` after the
first sample at the new speed (the time the growth needs to settle, with some slack; the sample
during the change may catch it half-way; a residual is measured minus twin, so a step the twin
lacks is a step of the residual), and the same jumps wherever the speed stays constant: how much
the residual moves in that time anyway (noise, a thermal misfit). :func:`speed_step_gate` names
the effect only when the residual of the model without it steps at the speed changes by more
than it moves at a constant speed (:func:`steps_measured`) and the effect removes those steps:
their RMS, pooled over the searched campaigns, falls by at least ``min_reduction`` with it.

A step also stays while the speed stays. A thermal answer that comes late (a lagging sensor
slows the calibrated nodes, so the twin answers a speed change minutes after the machine) also
makes the residual jump across the change, and a speed-squared term can take up the first
minutes of it; but that jump keeps growing after the step would have settled and fades as the
twin catches up. The gate therefore reads the jumps again at every multiple of ``settle_s`` up
to :data:`HOLD_S`, and wherever the residual still steps there, the effect must remove the
jumps by ``min_reduction`` too.

:func:`step_signature` gives the search the same three checks, with steps at least
:data:`SIGNATURE_RATIO` times the residual's movement at a constant speed, as the effect's own
signature: an effect that shows it is named whatever its pooled held-out Z RMS does (the steps
are a few samples at each speed change, which a pooled RMS dilutes with a thermal misfit the
term cannot remove; see :mod:`pipeline.discrepancy.search`), and as a later effect it
needs no evidence on the campaigns where the effects named before it act least (a thermal
effect makes no step).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import f as f_distribution

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.search import Gate, ModelEvidence, SignatureEvidence
from pipeline.fit_statistics import root_mean_square

STEP_EFFECTS = ("centrifugal_growth",)
"""Effects whose own signature is a displacement step at every speed change."""

logger = logging.getLogger(__name__)

SETTLE_S = 180.0
"""Time after a speed change at which the step is read, s: the independent machine's growth
settles with a lag of 20-60 s, three of them at most; the twin's at once."""

HOLD_S = 1800.0
"""Latest time after a speed change at which the jumps are read again, s: a spindle's fast
thermal answers (bearings, sensors, the nose) come within minutes to tens of minutes; later, the
residual's own drift at a constant speed hides any step (see :func:`speed_step_gate`)."""

SIGNATURE_RATIO = 2.0
"""Smallest ratio of the steps' RMS to the residual's movement at a constant speed over the same
time for the steps to be the effect's evidence of its own (:func:`step_signature`): a step one
sees in the residual at a glance. The gate's variance-ratio test alone passes steps within the
residual's scatter once there are enough speed changes (on the twin with a sensor lag and its
test's campaigns: 0.45 against 0.29 um at 11 changes, p = 0.006, nothing stepping there)."""

STEP_SIGNIFICANCE = 0.01
"""Chance that a residual without steps shows jumps at the speed changes as large as those asked
of a measured step (the variance-ratio test of :func:`steps_measured`)."""


def _jump_ends(t_s: np.ndarray, k: int, settle_s: float) -> int:
    """Index of the sample a jump starting at sample ``k - 1`` is read at."""
    return int(np.searchsorted(t_s, t_s[k] + settle_s))


def step_jumps(
    campaign: MeasuredCampaign, residual_um: np.ndarray, settle_s: float = SETTLE_S
) -> tuple[np.ndarray, np.ndarray]:
    """Return the change of a Z residual across each speed change, and at a constant speed, um.

    Parameters
    ----------
    campaign : MeasuredCampaign
        Its ``t_s`` and ``rpm`` (right-continuous: the speed changes between sample ``k - 1``
        and sample ``k`` where they differ).
    residual_um : ndarray of shape (n,), um
        Measured minus twin Z at the campaign's samples (NaN where not measured).
    settle_s : float
        A jump from sample ``k - 1`` is read at the first sample at least this long after
        sample ``k`` (past the sample during a change, which a lag or a logger's averaging may
        catch half-way), s.

    Returns
    -------
    at_changes : ndarray, um
        One jump per speed change between samples ``k - 1`` and ``k`` after which the speed
        stays until the jump is read.
    at_constant_speed : ndarray, um
        The jumps over the same samples wherever the speed stays constant over them: how much
        the residual moves in that time without a step.
    Both keep only jumps with a finite residual at both ends.
    """
    t_s, residual = campaign.t_s, np.asarray(residual_um, dtype=float)
    changed = np.diff(campaign.rpm) != 0.0
    at_changes, at_constant_speed = [], []
    for k in range(1, len(t_s)):
        end = _jump_ends(t_s, k, settle_s)
        if end >= len(t_s) or not (np.isfinite(residual[k - 1]) and np.isfinite(residual[end])):
            continue
        jump = residual[end] - residual[k - 1]
        if changed[k:end].any():
            continue
        if changed[k - 1]:
            at_changes.append(jump)
        else:
            at_constant_speed.append(jump)
    return np.asarray(at_changes, dtype=float), np.asarray(at_constant_speed, dtype=float)


def pooled_jumps(
    campaigns: Mapping[str, MeasuredCampaign],
    residuals_um: Mapping[str, np.ndarray],
    settle_s: float = SETTLE_S,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`step_jumps` of every residual given, pooled (at the changes, at constant speed)."""
    parts = [step_jumps(campaigns[cid], r, settle_s) for cid, r in residuals_um.items()]
    return tuple(np.concatenate([p[i] for p in parts]) if parts else np.zeros(0) for i in range(2))


def steps_measured(at_changes: np.ndarray, at_constant_speed: np.ndarray) -> float:
    """P-value of the residual's jumps at the speed changes against those at a constant speed.

    A one-sided variance-ratio (F) test of the jumps' mean squares, with as many degrees of
    freedom as jumps: small when the residual steps at the changes by more than it moves in the
    same time at a constant speed. The jumps at a constant speed overlap and are not quite
    independent, which the test takes them to be: it is a yardstick, not an exact probability.
    """
    if len(at_changes) == 0 or len(at_constant_speed) == 0:
        return float("nan")
    ratio = np.mean(at_changes**2) / max(np.mean(at_constant_speed**2), 1e-30)
    return float(f_distribution.sf(ratio, len(at_changes), len(at_constant_speed)))


@dataclass(frozen=True)
class StepReading:
    """The held-out Z residual's jumps read at one time after the speed changes, um.

    Attributes
    ----------
    read_s : float
        Time after the first sample at the new speed at which the jumps are read, s.
    n_changes : int
        Speed changes read.
    steps_um, still_um, after_um : float
        RMS of the jumps at the changes without the effect, at a constant speed over the same
        time, and at the changes with the effect, um.
    p_value : float
        :func:`steps_measured` of the jumps without the effect.
    """

    read_s: float
    n_changes: int
    steps_um: float
    still_um: float
    after_um: float
    p_value: float

    def stepped(self) -> bool:
        """Whether the residual without the effect steps at the changes at this read."""
        return self.p_value < STEP_SIGNIFICANCE

    def removed(self, min_reduction: float) -> bool:
        """Whether the effect removes at least ``min_reduction`` of the jumps' RMS."""
        return self.after_um <= (1.0 - min_reduction) * self.steps_um

    def figures(self) -> str:
        """Return the reading in words."""
        return (
            f"the held-out residual's jumps at the {self.n_changes} speed changes, read "
            f"{self.read_s / 60.0:.0f} min after them, are {self.steps_um:.2f} um RMS, against "
            f"{self.still_um:.2f} um over the same time at a constant speed "
            f"(p = {self.p_value:.2g})"
        )


def read_steps(
    campaigns: Mapping[str, MeasuredCampaign],
    current_um: Mapping[str, np.ndarray],
    augmented_um: Mapping[str, np.ndarray],
    read_s: float,
) -> StepReading:
    """Read the jumps of a model's held-out residuals without and with an effect at ``read_s``."""
    steps, still = pooled_jumps(campaigns, current_um, read_s)
    after, _ = pooled_jumps(campaigns, augmented_um, read_s)
    return StepReading(
        read_s=read_s,
        n_changes=len(steps),
        steps_um=root_mean_square(steps) if len(steps) else float("nan"),
        still_um=root_mean_square(still) if len(still) else float("nan"),
        after_um=root_mean_square(after) if len(after) else float("nan"),
        p_value=steps_measured(steps, still),
    )


StepReader = Callable[[ModelEvidence, ModelEvidence], list[StepReading]]
"""``(current, augmented) -> readings``: :func:`read_steps` at every read time."""


def _step_reader(
    campaigns: Sequence[MeasuredCampaign], settle_s: float, hold_s: float
) -> StepReader:
    """Return the reader of two models' held-out Z jumps on ``campaigns``.

    It reads them at every multiple of ``settle_s`` up to ``hold_s``, s.
    """
    by_id = {c.campaign_id: c for c in campaigns}
    read_times = settle_s * np.arange(1, max(int(hold_s // settle_s), 1) + 1)

    def read(current: ModelEvidence, augmented: ModelEvidence) -> list[StepReading]:
        now, then = current.heldout.z_residual_um, augmented.heldout.z_residual_um
        return [read_steps(by_id, now, then, t) for t in read_times]

    return read


def _step_verdict(readings: Sequence[StepReading], min_reduction: float) -> str | None:
    """Why the readings of :func:`speed_step_gate` keep a speed-step effect a suspect, or None."""
    first = readings[0]
    if not first.stepped():
        return (
            f"the measurement does not step where the speed changes: {first.figures()}, so the "
            "held-out fall it brings follows the speed program without its signature: it "
            "is likely a proxy for a thermal effect"
        )
    if not first.removed(min_reduction):
        return (
            f"it does not remove the steps of the displacement: {first.figures()}; with it "
            f"{first.after_um:.2f} um (a fall of at least {100 * min_reduction:.0f} % is asked)"
        )
    for later in readings[1:]:
        if later.stepped() and not later.removed(min_reduction):
            return (
                f"the step it removes does not stay while the speed stays: {later.figures()}, "
                f"and with it {later.after_um:.2f} um (a fall of at least "
                f"{100 * min_reduction:.0f} % is asked; {first.steps_um:.2f} -> "
                f"{first.after_um:.2f} um at {first.read_s / 60.0:.0f} min): the residual keeps "
                "moving after a step would have settled, as a thermal answer that comes late "
                "(a lagging sensor, a slow node) does; it is likely a proxy for one"
            )
    return None


def speed_step_gate(
    campaigns: Sequence[MeasuredCampaign],
    min_reduction: float,
    settle_s: float = SETTLE_S,
    hold_s: float = HOLD_S,
) -> Gate:
    """Return a gate of the forward search: a speed-step effect must remove measured steps.

    An effect of :data:`STEP_EFFECTS` stays a suspect unless, on the held-out Z residuals of
    the current model (the campaigns of the held-out residuals):

    1. the residual steps at the speed changes: its jumps there, read ``settle_s`` after them,
       are larger than at a constant speed over the same time (:func:`steps_measured`, p below
       :data:`STEP_SIGNIFICANCE`);
    2. the effect removes them: the RMS of the jumps at the changes falls by at least
       ``min_reduction`` (a fraction) from the current model to the model with it;
    3. the step stays while the speed stays: read again at every multiple of ``settle_s`` up to
       ``hold_s``, wherever the residual still steps (as in 1), the effect removes the jumps by
       ``min_reduction`` there too. A jump that keeps growing after ``settle_s`` and that the
       effect leaves is a late thermal answer, not a step.

    Campaigns without a speed change cannot show the signature: the effect stays a suspect.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        Every campaign given to the search.
    min_reduction : float
        Smallest relative fall of the jumps' RMS, the search's ``min_heldout_reduction``.
    settle_s : float
        See :func:`step_jumps`, s.
    hold_s : float
        Latest read of 3., s.
    """
    read = _step_reader(campaigns, settle_s, hold_s)

    def gate(
        effect: str, baseline: ModelEvidence, current: ModelEvidence, augmented: ModelEvidence
    ) -> str | None:
        if effect not in STEP_EFFECTS:
            return None
        readings = read(current, augmented)
        if readings[0].n_changes == 0:
            return (
                "the campaigns have no speed change, where its own signature (a step of the "
                "displacement) would show; a test with speed steps can show it"
            )
        for r in readings:
            logger.info(
                "%s: held-out Z jumps at %d speed changes read at %.0f s %.2f um RMS "
                "(%.2f at a constant speed, p = %.2g), %.2f with it",
                effect,
                r.n_changes,
                r.read_s,
                r.steps_um,
                r.still_um,
                r.p_value,
                r.after_um,
            )
        return _step_verdict(readings, min_reduction)

    return gate


def step_signature(
    campaigns: Sequence[MeasuredCampaign],
    min_reduction: float,
    settle_s: float = SETTLE_S,
    hold_s: float = HOLD_S,
) -> SignatureEvidence:
    """Return the search's signature evidence of a speed-step effect.

    For an effect of :data:`STEP_EFFECTS`, the checks of :func:`speed_step_gate` (steps
    measured at the speed changes, removed by ``min_reduction`` by the effect, at every read
    up to ``hold_s`` where they still show) passed on the held-out residuals, with the steps'
    RMS at the first read at least :data:`SIGNATURE_RATIO` times the residual's movement at a
    constant speed, give the words of the first read; otherwise, and for any other effect,
    None. Parameters as in :func:`speed_step_gate`.
    """
    read = _step_reader(campaigns, settle_s, hold_s)

    def shown(effect: str, current: ModelEvidence, augmented: ModelEvidence) -> str | None:
        if effect not in STEP_EFFECTS:
            return None
        readings = read(current, augmented)
        first = readings[0]
        if first.n_changes == 0 or _step_verdict(readings, min_reduction) is not None:
            return None
        if not first.steps_um >= SIGNATURE_RATIO * first.still_um:
            return None
        return (
            f"{first.figures()}; with it {first.after_um:.2f} um, and the steps stay removed "
            f"while the speed stays (read up to {hold_s / 60.0:.0f} min after the changes)"
        )

    return shown

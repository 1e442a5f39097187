"""The structure check of a speed-step effect: it must remove steps the measurement has."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.search import FitResult, ModelEvidence
from pipeline.discrepancy.speed_steps import (
    pooled_jumps,
    speed_step_gate,
    step_jumps,
    step_signature,
    steps_measured,
)

MINUTE = 60.0


def campaign(cid: str, rpm_levels=(0.0, 4000.0, 8000.0, 0.0)) -> MeasuredCampaign:
    """A 4-h campaign sampled every minute, one hour at each of ``rpm_levels``."""
    t = np.arange(0.0, 240.0) * MINUTE
    rpm = np.repeat(np.asarray(rpm_levels, dtype=float), len(t) // len(rpm_levels))
    return MeasuredCampaign(
        campaign_id=cid,
        t_s=t,
        rpm=rpm,
        temperatures=pd.DataFrame({"T1": np.full(len(t), 20.0)}),
        roles={"T1": "ambient"},
        z_um=np.zeros(len(t)),
    )


def evidence(residuals: dict[str, np.ndarray]) -> ModelEvidence:
    fit = FitResult(np.nan, np.nan, {}, residuals)
    return ModelEvidence(frozenset(), fit, fit)


def thermal_drift(c: MeasuredCampaign) -> np.ndarray:
    """A smooth misfit that only turns at the speed changes: no step, um."""
    return 3.0 * np.sin(c.t_s / (90.0 * MINUTE))


def speed_step(c: MeasuredCampaign, um_per_krpm2: float = 0.2) -> np.ndarray:
    """What an instant speed-squared growth leaves in a residual, um."""
    return um_per_krpm2 * (c.rpm / 1000.0) ** 2


def test_jumps_are_read_across_every_speed_change_and_at_a_constant_speed():
    c = campaign("K01")
    at_changes, still = step_jumps(c, speed_step(c))
    np.testing.assert_allclose(at_changes, [3.2, 9.6, -12.8])
    # read 3 min after the first sample at the new speed, 4 samples apart: 236 jumps, of which
    # 3 at the changes and 9 more that span one
    assert len(still) == 224 and np.all(still == 0.0)
    at_changes, still = step_jumps(c, thermal_drift(c))
    assert np.all(np.abs(at_changes) < 0.2) and np.all(np.abs(still) < 0.2)
    gap = speed_step(c)
    gap[59] = np.nan  # the sample before the first change not measured: that change is skipped
    np.testing.assert_allclose(step_jumps(c, gap)[0], [9.6, -12.8])


def noisy(c: MeasuredCampaign, seed: int, sigma_um: float = 0.3) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, sigma_um, len(c.t_s))


CAMPAIGNS = [campaign("K01"), campaign("K02", (0.0, 6000.0, 3000.0, 0.0))]


def test_steps_are_measured_only_beyond_what_the_residual_does_at_a_constant_speed():
    by_id = {c.campaign_id: c for c in CAMPAIGNS}
    with_steps = {c.campaign_id: thermal_drift(c) + speed_step(c) + noisy(c, 1) for c in CAMPAIGNS}
    without = {c.campaign_id: thermal_drift(c) + noisy(c, 1) for c in CAMPAIGNS}
    assert steps_measured(*pooled_jumps(by_id, with_steps)) < 1e-6
    assert steps_measured(*pooled_jumps(by_id, without)) > 0.05


def test_a_term_that_removes_measured_steps_passes():
    current = {c.campaign_id: thermal_drift(c) + speed_step(c) + noisy(c, 1) for c in CAMPAIGNS}
    augmented = {c.campaign_id: thermal_drift(c) + noisy(c, 2) for c in CAMPAIGNS}
    gate = speed_step_gate(CAMPAIGNS, min_reduction=0.2)
    baseline = evidence(current)
    assert gate("centrifugal_growth", baseline, baseline, evidence(augmented)) is None


def test_a_proxy_where_the_measurement_does_not_step_stays_a_suspect():
    # the term follows the program and takes up part of a slow misfit; no step was measured
    current = {c.campaign_id: thermal_drift(c) + noisy(c, 1) for c in CAMPAIGNS}
    augmented = {c.campaign_id: current[c.campaign_id] - 0.02 * speed_step(c) for c in CAMPAIGNS}
    gate = speed_step_gate(CAMPAIGNS, min_reduction=0.2)
    models = evidence(current), evidence(current), evidence(augmented)
    reason = gate("centrifugal_growth", *models)
    assert reason is not None and "does not step" in reason and "6 speed changes" in reason
    assert gate("motor_heat", *models) is None  # only speed-step effects are asked


def test_a_term_that_leaves_the_measured_steps_stays_a_suspect():
    current = {c.campaign_id: thermal_drift(c) + speed_step(c) + noisy(c, 1) for c in CAMPAIGNS}
    # half the steps, of the wrong sign: the jumps grow
    augmented = {c.campaign_id: current[c.campaign_id] + 0.5 * speed_step(c) for c in CAMPAIGNS}
    gate = speed_step_gate(CAMPAIGNS, min_reduction=0.2)
    reason = gate("centrifugal_growth", *(evidence(current),) * 2, evidence(augmented))
    assert reason is not None and "does not remove the steps" in reason


def test_without_a_speed_change_the_signature_cannot_show():
    steady = [campaign("K01", (5000.0,) * 4)]
    residual = {"K01": thermal_drift(steady[0])}
    gate = speed_step_gate(steady, min_reduction=0.2)
    reason = gate("centrifugal_growth", *(evidence(residual),) * 3)
    assert reason is not None and "no speed change" in reason


def late_answer(c: MeasuredCampaign, um_per_krpm2: float = 0.2) -> np.ndarray:
    """A thermal answer the twin gives minutes late: it grows for ~13 min after a speed change
    and fades as the twin catches up (a difference of 8-min and 20-min first-order rises), um."""
    out = np.zeros(len(c.t_s))
    for k in np.flatnonzero(np.diff(c.rpm) != 0.0) + 1:
        since_min = (c.t_s[k:] - c.t_s[k]) / MINUTE
        rise = um_per_krpm2 * ((c.rpm[k] / 1000.0) ** 2 - (c.rpm[k - 1] / 1000.0) ** 2)
        out[k:] += 3.0 * rise * (np.exp(-since_min / 20.0) - np.exp(-since_min / 8.0))
    return out


def test_a_term_that_takes_up_only_the_first_minutes_of_a_late_answer_stays_a_suspect():
    current = {c.campaign_id: late_answer(c) + noisy(c, 1, 0.05) for c in CAMPAIGNS}
    by_id = {c.campaign_id: c for c in CAMPAIGNS}
    first, _ = pooled_jumps(by_id, current)
    ninth, _ = pooled_jumps(by_id, current, settle_s=9 * MINUTE)
    assert np.sqrt(np.mean(ninth**2)) > 1.5 * np.sqrt(np.mean(first**2))  # it keeps growing
    # a speed-squared term sized to a third of the jump read at 3 min: it passes the first read
    unit, _ = pooled_jumps(by_id, {c.campaign_id: speed_step(c) for c in CAMPAIGNS})
    size = np.sum(first * unit) / np.sum(unit**2)
    augmented = {
        c.campaign_id: current[c.campaign_id] - 0.3 * size * speed_step(c) for c in CAMPAIGNS
    }
    gate = speed_step_gate(CAMPAIGNS, min_reduction=0.2)
    models = evidence(current), evidence(current), evidence(augmented)
    reason = gate("centrifugal_growth", *models)
    assert reason is not None and "does not stay while the speed stays" in reason
    # read at 3 min only, the same term passed: the later reads hold it back
    assert speed_step_gate(CAMPAIGNS, 0.2, hold_s=3 * MINUTE)("centrifugal_growth", *models) is None


def test_a_jump_with_another_speed_change_before_its_read_is_not_counted():
    c = campaign("K03", (0.0, 4000.0, 8000.0, 0.0))
    brief = (c.t_s >= 60 * MINUTE) & (c.t_s < 62 * MINUTE)
    short = replace(c, rpm=np.where(brief, 2000.0, c.rpm))
    at_changes, _ = step_jumps(short, speed_step(short))
    # the speed changes again 2 min after the change to 2000 rpm, before its read: that jump
    # is not counted; the change from 2000 to 4000 rpm is
    np.testing.assert_allclose(at_changes, [2.4, 9.6, -12.8])


def test_the_signature_the_search_may_name_on_is_the_gate_passed():
    stepped = {c.campaign_id: thermal_drift(c) + speed_step(c) + noisy(c, 1) for c in CAMPAIGNS}
    removed = {c.campaign_id: thermal_drift(c) + noisy(c, 2) for c in CAMPAIGNS}
    shown = step_signature(CAMPAIGNS, min_reduction=0.2)
    words = shown("centrifugal_growth", evidence(stepped), evidence(removed))
    assert words is not None and "6 speed changes" in words and "stay removed" in words
    assert shown("motor_heat", evidence(stepped), evidence(removed)) is None
    # no step measured: a term that follows the program shows no signature
    drift = {c.campaign_id: thermal_drift(c) + noisy(c, 1) for c in CAMPAIGNS}
    follows = {c.campaign_id: drift[c.campaign_id] - 0.02 * speed_step(c) for c in CAMPAIGNS}
    assert shown("centrifugal_growth", evidence(drift), evidence(follows)) is None


def test_steps_within_the_residuals_scatter_pass_the_gate_but_are_no_signature():
    """Many changes make a small step significant; the signature asks for one seen at a glance."""
    many = [
        *CAMPAIGNS,
        campaign("K03", (0.0, 3000.0, 6000.0, 0.0)),
        campaign("K04", (0.0, 5000.0, 2000.0, 0.0)),
    ]
    by_id = {c.campaign_id: c for c in many}
    for um_per_krpm2, signature in ((0.025, False), (0.035, True)):
        current = {c.campaign_id: speed_step(c, um_per_krpm2) + noisy(c, 1) for c in many}
        removed = {c.campaign_id: noisy(c, 1) for c in many}  # the term takes the step
        steps, still = pooled_jumps(by_id, current)
        assert steps_measured(steps, still) < 0.01
        models = evidence(current), evidence(current), evidence(removed)
        assert speed_step_gate(many, 0.2)("centrifugal_growth", *models) is None
        shown = step_signature(many, 0.2)("centrifugal_growth", models[1], models[2])
        assert (shown is not None) == signature

"""Tests of the twin test plans are scored with (discrepancy/plan_twin.py, calibrate's prior).

Small synthetic campaigns of the project's generator at one constant speed, as in the test-plan
tests: the prior rows of the calibration, the maximum a posteriori refit (what the campaigns
pin down stays, what they leave loose comes back towards the specs' typical values), the draws
from its posterior (seeded, in the bounds, tight where the data are), and a plan's peak rise
over them.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.discrepancy import plan_proposal as tp
from pipeline.discrepancy.calibrate import calibrate, prior_scales, weighted_residuals
from pipeline.discrepancy.plan_twin import plan_twin
from pipeline.discrepancy.visibility import baseline_point
from pipeline.thermal.program import Program, Segment
from tests.helpers.twin_cases import calibrated, constant_speed_campaigns


@pytest.fixture(scope="module")
def flat():
    """Three campaigns at one constant 4000 rpm, their model and calibrated baseline point."""
    campaigns = constant_speed_campaigns()
    model, fit, roles = calibrated(campaigns)
    point = baseline_point(campaigns, {k: v for k, (v, _) in fit.params.items()}, roles)
    return model, point, plan_twin(point)


def _log_distance(model, values) -> np.ndarray:
    """Distance of each parameter from its spec's initial value, in prior scales (log)."""
    theta = np.array([values[n] for n in model.names])
    logs = np.array([p.log for p in model.param_specs])
    x = np.where(logs, np.log(theta), theta)
    x0 = np.where(logs, np.log(model.initial()), model.initial())
    return (x - x0) / prior_scales(model, model.initial(), 1.0)


def test_the_prior_rows_pull_to_the_initial_values_and_the_sse_counts_the_data_only(flat):
    model, point, _ = flat
    plain = calibrate(model, point.campaigns, noise=point.noise, start=point.values, max_nfev=5)
    tight = calibrate(
        model, point.campaigns, noise=point.noise, start=point.values, prior_log_sd=0.01
    )
    r, _ = weighted_residuals(model, tight.theta[None, :], point.campaigns, point.noise)
    assert tight.sse == pytest.approx(float(np.sum(r**2)), rel=1e-9)  # no prior rows in it
    # a prior 100 times tighter holds every parameter near its initial value
    tight_values = {k: v for k, (v, _) in tight.params.items()}
    plain_values = {k: v for k, (v, _) in plain.params.items()}
    assert np.max(np.abs(_log_distance(model, tight_values))) < 0.1 * np.max(
        np.abs(_log_distance(model, plain_values))
    )
    assert tight.sse > plain.sse


def test_the_refit_keeps_the_fit_and_brings_loose_parameters_towards_their_priors(flat):
    model, point, twin = flat
    assert 0.99 < twin.sse_ratio < 1.05  # what the campaigns pin down stays
    before = _log_distance(model, point.values)
    after = _log_distance(model, twin.values)
    assert np.sum(after**2) < 0.5 * np.sum(before**2)
    moved = twin.moved(point.values)
    assert moved and all(max(a / b, b / a) > 2.0 for a, b in moved.values())
    for name in moved:
        i = model.names.index(name)
        assert abs(after[i]) < abs(before[i]), name  # each towards its typical value


def test_the_draws_are_seeded_in_the_bounds_and_tight_where_the_data_are(flat):
    model, point, twin = flat
    lo, hi = model.bounds()
    assert twin.draws.shape == (32, len(model.names))
    assert np.all(twin.draws >= lo) and np.all(twin.draws <= hi)
    assert np.array_equal(plan_twin(point).draws, twin.draws)
    logs = np.array([p.log for p in model.param_specs])
    theta = np.array([twin.values[n] for n in model.names])
    x = np.where(logs, np.log(twin.draws), twin.draws)
    u = (x - np.where(logs, np.log(theta), theta)) / prior_scales(model, theta, 1.0)
    # along the combination the outputs feel most the draws are tight; along the one they do
    # not feel, they spread as the prior (one prior scale)
    at_map = baseline_point(point.campaigns, twin.values, set(point.roles), point.noise)
    _, _, vt = np.linalg.svd(at_map.sensitivities, full_matrices=False)
    assert np.std(u @ vt[0]) < 0.05
    assert 0.5 < np.std(u @ vt[-1]) < 1.5


def test_a_heater_plan_s_rise_is_linear_in_power_and_its_bound_above_it(flat):
    _, point, twin = flat
    sensors = tp.plan_sensors(point.campaigns)
    stopped = Program((Segment(0.0, 240.0, 0.0),), key="rpm")

    def heated(power):
        load = tp.heater("column_rear", power, 0.0, 120.0)
        return tp.TestPlan(f"{power} W", stopped, 4.0, 180.0, (), True, (load,))

    low, high = (tp.plan_rises(heated(p), twin, sensors, 20.0) for p in (50.0, 200.0))
    assert high[0] == pytest.approx(4.0 * low[0], rel=1e-6)
    assert high[1] == pytest.approx(4.0 * low[1], rel=1e-6)
    assert low[1] >= low[0] > 0.1
    cold = tp.TestPlan("nothing", stopped, 4.0, 180.0)
    assert tp.plan_rises(cold, twin, sensors, 20.0) == pytest.approx((0.0, 0.0), abs=1e-9)

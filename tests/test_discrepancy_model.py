"""Tests of the calibratable twin of the discrepancy workflow (data, model, calibration).

The "measured" campaigns come from the project's physical twin (pipeline.twin) with no effect
switched on; the calibratable twin is built from the sensor roles only and must reproduce them
to the noise floor. The generator's parameters are read only in assertions (noise levels).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime

import numpy as np
import pandas as pd
import pytest

from pipeline.discrepancy import (
    EFFECTS,
    MeasuredCampaign,
    build_model,
    calibrate,
    missing_roles,
    predict,
)
from pipeline.discrepancy.calibrate import noise_sd
from pipeline.discrepancy.data import campaigns_from_tables
from pipeline.discrepancy.search import TwinEvaluator
from pipeline.io.tables import ingest
from pipeline.thermal import stepping
from pipeline.thermal.program import Program, Segment
from pipeline.twin.campaigns import SpindlePlan, simulate_spindle_campaign
from pipeline.twin.params import DS18B20, SpindleParams
from pipeline.twin.writer import write_campaign
from pipeline.validation.checks import validate_tables
from pipeline.validation.tables import select_valid
from schemas.vocabulary import SENSOR_ROLES
from tests.helpers.repo_params import alignment_gap_s, validation_limits
from tests.helpers.twin_measured import measured_from_twin

ALL_ROLES = set(SENSOR_ROLES) - {"nut", "coolant"}
# no campaign-to-campaign heat scatter: the data are exactly the twin's baseline plus noise
NO_SCATTER = replace(SpindleParams(), heat_scatter_rel=0.0)
# DS18B20: white noise plus 0.0625 degC quantisation
T_NOISE_K = float(np.hypot(DS18B20.noise_sd_degc, DS18B20.resolution_degc / np.sqrt(12.0)))


@dataclass(frozen=True)
class StepPlan(SpindlePlan):
    """A spindle plan with speed steps (``(from_min, to_min, rpm)``) instead of one speed."""

    steps: tuple[tuple[float, float | None, float], ...] = ()

    def program(self) -> Program:
        """The steps as a program."""
        return Program(tuple(Segment(a, b, v) for a, b, v in self.steps), key="rpm")


SPEEDS = ((2000.0, 4000.0), (4000.0, 6000.0), (6000.0, 3000.0), (3000.0, 5000.0))


def _plan(i: int) -> StepPlan:
    lo, hi = SPEEDS[i % len(SPEEDS)]
    steps = ((0.0, 120.0, lo), (120.0, 240.0, hi), (240.0, None, 0.0))
    return StepPlan(
        f"S{i:02d}",
        datetime(2024, 3 + i, 12, 8, 30),
        lo,
        run_min=240.0,
        cooldown_min=90.0,
        steps=steps,
    )


def _twin_campaign(i: int, effects: frozenset[str] = frozenset(), seed: int = 7):
    return simulate_spindle_campaign(_plan(i), seed=seed, params=NO_SCATTER, effects=effects)


@pytest.fixture(scope="module")
def baseline_campaigns() -> list[MeasuredCampaign]:
    return [measured_from_twin(_twin_campaign(i)) for i in range(4)]


def _roles(campaigns: list[MeasuredCampaign]) -> set[str]:
    return {r for c in campaigns for r in c.roles.values()}


def test_calibrated_baseline_reproduces_baseline_data_to_the_noise_floor(baseline_campaigns):
    model = build_model(_roles(baseline_campaigns), frozenset())
    fit = calibrate(model, baseline_campaigns)
    assert fit.converged
    probe = NO_SCATTER.probe_noise_um
    assert fit.rmse_z_um < 1.5 * probe, fit.rmse_z_um
    assert fit.rmse_T_K < 2.0 * T_NOISE_K, fit.rmse_T_K
    # the noise floors estimated from the data are those of the generator's chain
    assert fit.noise.z_um == pytest.approx(probe, rel=0.3)
    assert np.median(list(fit.noise.temperature_K.values())) == pytest.approx(T_NOISE_K, rel=0.3)
    # predict reproduces the calibration's residuals on a training campaign
    c = baseline_campaigns[1]
    sim = predict(model, fit, c)
    res = c.z_um - sim.z_um
    assert np.allclose(res - res.mean(), fit.residuals[c.campaign_id]["z_um"])
    assert list(sim.temperatures.columns) == ["T1", "T2", "T3", "T4", "T5", "T6", "T7", "T8"]
    # the drift is large compared with the residual: the fit is not trivial
    assert np.ptp(c.z_um) > 20 * fit.rmse_z_um
    assert fit.n_obs == sum(c.t_s.size * 9 for c in baseline_campaigns)
    assert np.isfinite(fit.aicc) and np.isfinite(fit.bic)


def test_calibrated_parameters_are_within_their_bounds(baseline_campaigns):
    model = build_model(_roles(baseline_campaigns), frozenset({"centrifugal_growth"}))
    fit = calibrate(model, baseline_campaigns[:2], max_nfev=30)
    for spec in model.param_specs:
        value, unit = fit.params[spec.name]
        assert spec.lower <= value <= spec.upper
        assert unit == spec.unit
    assert fit.n_params == len(model.param_specs) + 2


def test_a_search_calibration_keeps_the_lower_cost_of_its_warm_and_initial_starts(
    baseline_campaigns,
):
    campaigns = baseline_campaigns[:2]
    ids = tuple(c.campaign_id for c in campaigns)
    model = build_model(_roles(campaigns), frozenset())
    from_initial = calibrate(model, campaigns)
    evaluator = TwinEvaluator(campaigns)
    at_upper = {p.name: p.upper for p in model.param_specs}
    hot_and_loose = {
        p.name: p.upper if p.name.startswith("C_") else p.lower for p in model.param_specs
    }
    # measured here: from every upper bound the fit ends above the initial values' cost, from
    # large capacities and small conductances below it
    assert calibrate(model, campaigns, start=at_upper).sse > 1.0001 * from_initial.sse
    below = calibrate(model, campaigns, start=hot_and_loose)
    assert below.sse < 0.999 * from_initial.sse

    assert evaluator(frozenset(), ids, ids, at_upper).bic == pytest.approx(from_initial.bic)
    assert evaluator(frozenset(), ids, ids, hot_and_loose).bic == pytest.approx(below.bic)
    assert evaluator(frozenset(), ids, ids, None).bic == pytest.approx(from_initial.bic)


def test_an_effect_adds_its_parameters_with_units_and_bounds():
    base = build_model(ALL_ROLES, frozenset())
    expected = {
        "ambient_variation": [],
        "centrifugal_growth": [("centrifugal_um_per_krpm2", "um/krpm^2")],
        "nonlinear_bearing_heat": [("bearing_exponent", "1")],
        "sensor_lag": [("sensor_lag_s", "s")],
        "thermal_bending": [("bending_um_per_K", "um/K")],
        "motor_heat": [("q_motor_W_per_krpm", "W/krpm"), ("motor_exponent", "1")],
    }
    assert set(expected) == set(EFFECTS)
    for effect, names in expected.items():
        model = build_model(ALL_ROLES, frozenset({effect}))
        added = model.param_specs[len(base.param_specs) :]
        assert model.names[: len(base.names)] == base.names
        assert [(p.name, p.unit) for p in added] == names
        for p in added:
            assert p.effect == effect
            assert p.lower <= p.initial <= p.upper
    lag = build_model(ALL_ROLES, frozenset({"sensor_lag"})).param_specs[-1]
    assert (lag.lower, lag.upper) == (60.0, 7200.0)
    exponent = build_model(ALL_ROLES, frozenset({"nonlinear_bearing_heat"})).param_specs[-1]
    assert (exponent.lower, exponent.upper) == (0.5, 3.0)
    motor = build_model(ALL_ROLES, frozenset({"motor_heat"})).param_specs[-1]
    assert (motor.lower, motor.initial, motor.upper) == (1.0, 1.0, 3.0)
    # baseline: no effect parameter, every name carries its unit
    assert all(p.effect is None for p in base.param_specs)
    assert all(
        p.name.endswith(("_J_per_K", "_W_per_K", "_W_per_krpm", "_um_per_K", "_to_shaft"))
        for p in base.param_specs
    )


def test_missing_roles_names_what_an_effect_needs():
    roles = ALL_ROLES - {"column_rear"}
    assert missing_roles("thermal_bending", roles) == ["column_rear"]
    assert missing_roles("thermal_bending", ALL_ROLES - {"column_front", "column_rear"}) == [
        "column_front",
        "column_rear",
    ]
    assert missing_roles("motor_heat", ALL_ROLES - {"spindle_motor"}) == ["spindle_motor"]
    assert missing_roles("ambient_variation", ALL_ROLES - {"ambient"}) == ["ambient"]
    assert missing_roles("sensor_lag", {"bed"}) == []
    with pytest.raises(ValueError, match="thermal_bending.*column_rear.*cannot be tested"):
        build_model(roles, frozenset({"thermal_bending"}))
    with pytest.raises(KeyError, match="unknown effect 'spindle_wobble'"):
        missing_roles("spindle_wobble", ALL_ROLES)


def test_errors_are_clear():
    model = build_model(ALL_ROLES, frozenset())
    theta = model.initial()
    with pytest.raises(ValueError, match="theta has shape"):
        model.check_theta(theta[:-1])
    bad = theta.copy()
    bad[0] = 1.0  # a heat capacity of 1 J/K
    with pytest.raises(ValueError, match=r"C_bearing_J_per_K=1 not in \[1000, 1e\+06\] J/K"):
        model.check_theta(bad)
    with pytest.raises(ValueError, match="no sensor has a structure role"):
        build_model({"ambient", "other"}, frozenset())
    with pytest.raises(KeyError, match="unknown effect"):
        build_model(ALL_ROLES, frozenset({"ambient variation"}))
    with pytest.raises(TypeError, match="frozenset"):
        build_model(ALL_ROLES, "motor_heat")
    with pytest.raises(ValueError, match="at least one campaign"):
        calibrate(model, [])
    with pytest.raises(ValueError, match="strictly increasing"):
        MeasuredCampaign(
            "X", np.array([0.0, 0.0, 1.0]), np.zeros(3), _frame(3), {"T1": "bed"}, np.zeros(3)
        )
    with pytest.raises(ValueError, match="have no role"):
        MeasuredCampaign("X", np.arange(3.0), np.zeros(3), _frame(3), {}, np.zeros(3))


def _frame(n: int) -> pd.DataFrame:
    return pd.DataFrame({"T1": np.full(n, 20.0)})


def test_predict_refuses_a_calibration_of_another_model(baseline_campaigns):
    small = build_model({"spindle_front_bearing", "ambient"}, frozenset())
    fit = calibrate(small, baseline_campaigns[:1], max_nfev=5)
    with pytest.raises(ValueError, match="calibrate this model first"):
        predict(build_model(ALL_ROLES, frozenset()), fit, baseline_campaigns[0])


@pytest.mark.parametrize(
    "drop",
    [
        ("T3",),  # no motor sensor
        ("T5", "T6"),  # no column sensor
        ("T2", "T3", "T4", "T6", "T7", "T8", "T9"),  # only front bearing, column front, ambient
        ("T10",),  # no ambient sensor: reference = mean first reading
    ],
)
def test_any_subset_of_roles_builds_simulates_and_fits(drop):
    campaigns = [measured_from_twin(_twin_campaign(i), drop=drop) for i in range(2)]
    roles = _roles(campaigns)
    model = build_model(roles, frozenset())
    assert "spindle_shaft" in model.nodes and "headstock" in model.nodes
    sim = model.simulate(model.initial(), campaigns[0])
    not_nodes = ("ambient", "other")
    node_sensors = [s for s, r in campaigns[0].roles.items() if r not in not_nodes]
    assert sorted(sim.temperatures.columns) == sorted(node_sensors)
    assert np.all(np.isfinite(sim.z_um)) and sim.z_um[0] == 0.0
    fit = calibrate(model, campaigns, max_nfev=60)
    assert fit.rmse_z_um < 0.2 * np.ptp(campaigns[0].z_um)  # far better than no model


def test_speed_step_between_samples_is_integrated_exactly(baseline_campaigns):
    c = baseline_campaigns[0]
    model = build_model(_roles([c]), frozenset())
    theta = model.initial()
    on_grid = model.simulate(theta, c)
    shifted = replace_program(c, 60.0)  # the step 60 s after a sample instant
    off_grid = model.simulate(theta, shifted)
    i = int(np.searchsorted(c.t_s, 120 * 60.0))
    # before the step nothing changes; after it the later step gives less heat at the high speed
    assert np.allclose(on_grid.z_um[:i], off_grid.z_um[:i])
    assert not np.allclose(on_grid.z_um[i + 1 :], off_grid.z_um[i + 1 :])
    assert model.prepare(shifted).grid.size == c.t_s.size + 1


def _all_effects_and_mixed_grids(campaigns):
    """A model with every effect, three parameter vectors, campaigns on uniform and non-uniform
    step grids (a speed step between two samples)."""
    mixed = [campaigns[0], replace_program(campaigns[1], 60.0), campaigns[2]]
    model = build_model(_roles(mixed), frozenset(EFFECTS))
    lo, hi = model.bounds()
    rng = np.random.default_rng(5)
    thetas = np.array(
        [np.clip(model.initial() * rng.uniform(0.5, 2.0, lo.size), lo, hi) for _ in range(3)]
    )
    thetas[:, model.names.index("sensor_lag_s")] = [300.0, 900.0, 2400.0]
    return model, thetas, mixed


def test_batched_simulation_equals_one_simulation_per_parameter_vector(baseline_campaigns):
    model, thetas, mixed = _all_effects_and_mixed_grids(baseline_campaigns)
    batch = model.run_batch(thetas, mixed)
    for p, theta in enumerate(thetas):
        for c, single in enumerate(model.run(theta, mixed)):
            for key in ("readings", "nodes", "z_um"):
                assert np.allclose(batch[c][key][p], single[key], rtol=1e-10, atol=1e-9)
    # the parameter vectors give different trajectories (the batch is not one vector repeated)
    assert not np.allclose(batch[0]["z_um"][0], batch[0]["z_um"][1])


def test_modal_stepping_equals_stepping_the_full_state(baseline_campaigns, monkeypatch):
    model, thetas, mixed = _all_effects_and_mixed_grids(baseline_campaigns)
    modal = model.run_batch(thetas, mixed)
    monkeypatch.setattr(stepping, "MAX_MODAL_CONDITION", 0.0)  # never trust the eigenbasis
    full = model.run_batch(thetas, mixed)
    for m, f in zip(modal, full, strict=True):
        assert np.max(np.abs(m["readings"] - f["readings"])) < 1e-8  # degC
        assert np.max(np.abs(m["z_um"] - f["z_um"])) < 1e-8  # um
    assert np.ptp(full[0]["z_um"]) > 1.0  # a real trajectory, not a flat line


def _shifted(t_min: float | None, delay_s: float) -> float | None:
    """A segment boundary inside the run (0 to 240 min) moved ``delay_s`` later."""
    return t_min + delay_s / 60.0 if t_min is not None and 0 < t_min < 240 else t_min


def replace_program(c: MeasuredCampaign, delay_s: float) -> MeasuredCampaign:
    segments = tuple(
        Segment(_shifted(s.from_min, delay_s), _shifted(s.to_min, delay_s), s.value)
        for s in c.program.segments
    )
    return MeasuredCampaign(
        c.campaign_id, c.t_s, c.rpm, c.temperatures, c.roles, c.z_um, Program(segments)
    )


def test_from_tables_reads_the_ingest_and_validate_outputs(tmp_path):
    twin = _twin_campaign(2)
    write_campaign(twin, tmp_path / "raw")
    tables = ingest(tmp_path / "raw", alignment_gap_s())
    limits = validation_limits()
    result = validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )
    assert result.valid == ["S02"]
    spindle = select_valid(tables["campaigns"], tables["samples"], tables["laser"], result.valid)[
        "spindle"
    ]
    row = spindle["campaigns"].iloc[0]
    c = MeasuredCampaign.from_tables(row, spindle["samples"])
    assert c.campaign_id == "S02"
    assert np.allclose(c.t_s, twin.temperature["elapsed_s"])
    assert c.roles["T1"] == "spindle_front_bearing" and c.roles["T10"] == "ambient"
    assert c.z_um[0] == 0.0
    raw_z = twin.displacement["Z"].to_numpy()
    assert np.allclose(c.z_um, np.round(raw_z, 2) - np.round(raw_z[0], 2), atol=1e-6)
    assert c.program == twin.program
    assert np.array_equal(c.program.breakpoints_s(), [0.0, 7200.0, 14400.0])
    assert np.array_equal(c.rpm, twin.program.value_at(c.t_s))
    assert list(c.temperatures.columns) == [f"T{i}" for i in range(1, 11)]
    assert campaigns_from_tables(spindle["campaigns"], spindle["samples"])[0].campaign_id == "S02"
    sim = build_model(set(c.roles.values()), frozenset()).simulate(
        build_model(set(c.roles.values()), frozenset()).initial(), c
    )
    assert sim.temperatures.shape == (c.t_s.size, 8)


def test_noise_sd_ignores_slow_drift_and_steps():
    rng = np.random.default_rng(3)
    t = np.arange(200.0)
    drift = 5.0 * (1 - np.exp(-t / 40.0)) + np.where(t > 100, 3.0, 0.0)
    assert noise_sd(drift + 0.2 * rng.standard_normal(t.size)) == pytest.approx(0.2, rel=0.2)

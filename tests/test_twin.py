"""Tests of the physical twin (pipeline.twin): physics, effects, demo data, CLI, contract."""

from __future__ import annotations

import filecmp
from dataclasses import replace
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from pipeline.thermal.effects import check_effects
from pipeline.thermal.program import Program
from pipeline.twin import (
    DEMO_EFFECTS,
    EFFECTS,
    AmbientProfile,
    AxisCampaign,
    AxisParams,
    SpindleCampaign,
    SpindleParams,
    cli,
    demo_campaigns,
    demo_plans,
    model_terms,
    simulate_axis,
    simulate_spindle,
)
from pipeline.twin.ambient import SEASON_OF_MONTH
from pipeline.twin.campaigns import (
    PATENT_PASSES_MIN,
    SpindlePlan,
    campaign_rng,
    simulate_spindle_campaign,
)
from pipeline.twin.conditions import (
    DEMO_SCATTER,
    CampaignState,
    StateScatter,
    apply_state,
    draw_state,
)
from pipeline.twin.effects import TERMS, bearing_friction_heat, uniform_expansion
from pipeline.twin.simulate import sensor_time_constants
from schemas.vocabulary import SENSOR_ROLES

REPO = Path(__file__).resolve().parents[1]
ROLES = set(SENSOR_ROLES)
DEMO_IDS = [f"K{i:02d}" for i in range(1, 13)] + [f"V{i:02d}" for i in range(1, 7)] + ["Y01", "Y02"]
TIMES = np.arange(0.0, 300 * 60 + 1, 180.0)
# 6000 rpm, then 2000 rpm (both away from the 4000 rpm reference), then stopped
PROGRAM = [
    {"from_min": 0, "to_min": 120, "rpm": 6000},
    {"from_min": 120, "to_min": 200, "rpm": 2000},
    {"from_min": 200, "rpm": 0},
]
AMBIENT = AmbientProfile(mean_degc=20.0, daily_amplitude_k=3.0, start_hour=8.5, drift_k_per_h=0.2)
PARAMS = SpindleParams()
SENSORS = [s.name for s in PARAMS.sensors]
NODES = [f"node_{n}" for n in PARAMS.network.nodes]
OUTPUTS = {"ambient": ["ambient_degC"], "temperatures": NODES, "sensors": SENSORS, "z": ["z_um"]}


def run(effects=(), program=PROGRAM, ambient=AMBIENT, times=TIMES, **kw) -> pd.DataFrame:
    return simulate_spindle(PARAMS, frozenset(effects), program, ambient, times, **kw)


@pytest.fixture(scope="module")
def baseline() -> pd.DataFrame:
    return run()


@pytest.fixture(scope="module")
def demo() -> dict[str, SpindleCampaign | AxisCampaign]:
    return {c.info.campaign_id: c for c in demo_campaigns(cli.DEFAULT_SEED)}


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("raw_a")
    assert cli.main(["--preset", "demo", "--out", str(out)]) == 0
    return out


# ----------------------------------------------------------------------------- physics


def test_no_heat_and_constant_ambient_stays_at_ambient():
    amb = AmbientProfile(mean_degc=21.5, daily_amplitude_k=0.0)
    out = run(effects=set(EFFECTS) - {"centrifugal_growth"}, program=0.0, ambient=amb)
    temps = out[NODES + SENSORS].to_numpy()
    np.testing.assert_allclose(temps, 21.5, atol=1e-9)
    np.testing.assert_allclose(out["z_um"], 0.0, atol=1e-9)


def test_baseline_ambient_is_constant_at_its_start_value(baseline):
    amb_start = float(AMBIENT.at(0.0))
    np.testing.assert_array_equal(baseline["ambient_degC"], amb_start)
    # idle machine in a constant ambient: nothing moves
    idle = run(program=0.0)
    np.testing.assert_allclose(idle[NODES + SENSORS], amb_start, atol=1e-9)


def test_steady_state_matches_conductance_network():
    amb = AmbientProfile(mean_degc=20.0)
    out = run(program=4000.0, ambient=amb, times=np.array([0.0, 3.0e6]))
    q = bearing_friction_heat(PARAMS, np.array([4000.0]))[0]
    expected = PARAMS.network.steady_state(q, 20.0)
    np.testing.assert_allclose(out.loc[1, NODES].to_numpy(float), expected, atol=1e-6)
    # energy balance: all friction heat leaves by convection
    lost = PARAMS.network.convection @ (expected - 20.0)
    assert lost == pytest.approx(q.sum(), rel=1e-9)
    assert q.sum() == pytest.approx(PARAMS.front_bearing_heat_w + PARAMS.rear_bearing_heat_w)
    z = uniform_expansion(PARAMS, (expected - 20.0)[None, :], np.array([4000.0]))[0]
    assert out.loc[1, "z_um"] == pytest.approx(z, abs=1e-6)
    assert z < 0  # the spindle grows towards the table


def test_matrix_exponential_matches_solve_ivp():
    kw = {"effects": set(EFFECTS), "preroll_h": 24.0}
    exact = run(**kw)
    radau = run(method="Radau", **kw)
    np.testing.assert_allclose(exact[NODES + SENSORS], radau[NODES + SENSORS], atol=2e-3)
    np.testing.assert_allclose(exact["z_um"], radau["z_um"], atol=2e-2)


def test_heating_then_cooling_is_physical(baseline):
    front = baseline["node_front_bearing"].to_numpy()
    t_min = baseline["elapsed_s"].to_numpy() / 60
    assert np.all(np.diff(front[t_min <= 120]) > 0)  # heats while running fast
    assert np.all(np.diff(front[t_min >= 200]) < 0)  # cools once stopped
    assert front.max() - front[0] > 5.0
    # the spindle (shaft heated through the inner rings, front bearing) is hottest, the bed coolest
    rise = baseline[NODES].iloc[40] - baseline[NODES].iloc[0]
    assert rise.idxmax() in {"node_spindle_shaft", "node_front_bearing"}
    assert rise.idxmin() == "node_bed"
    # the rotating shaft carries no sensor: the spindle growth is not measured directly
    assert "spindle_shaft" not in {s.node for s in PARAMS.sensors}


def test_history_gives_a_warm_start_that_cools():
    amb = AmbientProfile(mean_degc=20.0)
    # ran at 6000 rpm for 3 h until 1 h before the start, then idle
    history = [{"from_min": -240, "to_min": -60, "rpm": 6000}]
    out = run(program=0.0, ambient=amb, history=history)
    cold = run(program=0.0, ambient=amb)
    assert out["node_front_bearing"].iloc[0] > 21.0
    np.testing.assert_allclose(cold[NODES], 20.0, atol=1e-9)
    assert np.all(np.diff(out["node_spindle_shaft"]) < 0)
    assert out["z_um"].iloc[-1] > 5.0  # the spindle shrinks back: the tool moves up


# ----------------------------------------------------------------------------- effects


def test_registry_has_exactly_the_six_effects():
    assert set(EFFECTS) == {
        "ambient_variation",
        "centrifugal_growth",
        "nonlinear_bearing_heat",
        "sensor_lag",
        "thermal_bending",
        "motor_heat",
    }
    assert [t.name for t in model_terms("spindle", ())] == [
        "bearing_friction_heat",
        "constant_ambient",
        "uniform_expansion",
        "direct_sensors",
    ]


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_effect_changes_what_it_declares_and_nothing_else(name, baseline):
    effect = EFFECTS[name]
    assert effect.name == name and effect.description
    on = run(effects={name})
    assert on.attrs["effects"] == [name]
    for group, cols in OUTPUTS.items():
        diff = np.abs(on[cols].to_numpy(float) - baseline[cols].to_numpy(float)).max()
        if group in effect.changes:
            assert diff > 1e-3, f"{name} should change {group}"
        else:
            assert diff < 1e-9, f"{name} must not change {group} (changed by {diff})"


def test_unknown_effect_is_rejected_with_the_known_names():
    with pytest.raises(KeyError, match="unknown effect 'bogus'; known effects: ambient_variation"):
        run(effects={"bogus"})
    with pytest.raises(TypeError, match="not the string 'motor_heat'"):
        check_effects("motor_heat")


def test_ambient_variation_follows_the_daily_cycle(baseline):
    on = run(effects={"ambient_variation"})
    np.testing.assert_allclose(on["ambient_degC"], AMBIENT.at(TIMES))
    # after a night following the cycle, the heavy bed lags: colder than the 08:30 air...
    assert on["node_bed"].iloc[0] < on["ambient_degC"].iloc[0] - 0.3
    # ...and it warms with the morning air, which it does not do in a constant ambient
    rise_on = on["node_bed"].iloc[-1] - on["node_bed"].iloc[0]
    rise_off = baseline["node_bed"].iloc[-1] - baseline["node_bed"].iloc[0]
    assert rise_on > rise_off + 0.3


def test_centrifugal_growth_is_instant_and_proportional_to_rpm_squared(baseline):
    on = run(effects={"centrifugal_growth"})
    dz = (on["z_um"] - baseline["z_um"]).to_numpy()
    rpm = baseline["rpm"].to_numpy()
    expected = PARAMS.centrifugal_um * (rpm / PARAMS.reference_rpm) ** 2
    np.testing.assert_allclose(dz, expected, atol=1e-12)
    np.testing.assert_allclose(on["z_centrifugal_growth_um"], expected, atol=1e-12)
    assert dz[rpm == 0].max() == 0.0 and abs(dz[rpm == 6000][0]) > 3.0
    pd.testing.assert_frame_equal(on[NODES + SENSORS], baseline[NODES + SENSORS])


def test_nonlinear_bearing_heat_is_hotter_above_and_cooler_below_reference():
    def front_rise(effects, rpm):
        out = run(effects=effects, program=rpm, ambient=AmbientProfile(20.0))
        return out["node_front_bearing"].iloc[-1] - 20.0

    a = PARAMS.bearing_heat_exponent
    assert a != 1.0
    for rpm, hotter in ((6000.0, True), (2000.0, False)):
        lin, non = front_rise((), rpm), front_rise({"nonlinear_bearing_heat"}, rpm)
        assert bool(non > lin) is hotter
        # linear network: temperature rise scales with the heat, (rpm / ref)^(a - 1)
        assert non / lin == pytest.approx((rpm / PARAMS.reference_rpm) ** (a - 1), rel=1e-9)
    assert front_rise({"nonlinear_bearing_heat"}, 4000.0) == pytest.approx(front_rise((), 4000.0))


def test_sensor_lag_delays_readings_only(baseline):
    on = run(effects={"sensor_lag"})
    pd.testing.assert_frame_equal(on[NODES + ["z_um"]], baseline[NODES + ["z_um"]])
    t_min = TIMES / 60
    lag = (baseline["T1"] - on["T1"]).to_numpy()
    assert np.all(lag[(t_min > 0) & (t_min <= 120)] > 0)  # reads low while heating
    assert np.all(lag[(t_min > 203) & (t_min <= 260)] < 0)  # reads high while cooling
    # first-order lag: reading error ~ tau * slope (within 20 % on the smooth part), each
    # sensor with the time constant of its own mounting
    k = np.searchsorted(TIMES, 90 * 60)
    for sensor in PARAMS.sensors[:4]:
        slope = np.gradient(baseline[sensor.name].to_numpy(), TIMES)
        lag_s = (baseline[sensor.name] - on[sensor.name]).to_numpy()
        assert lag_s[k] == pytest.approx(sensor.tau_s * slope[k], rel=0.2), sensor.name
    # converges at steady state
    long = run(
        effects={"sensor_lag"},
        program=4000.0,
        ambient=AmbientProfile(20.0),
        times=np.array([0.0, 3.0e6]),
    )
    node_of = {s.name: f"node_{s.node}" for s in PARAMS.sensors if s.node != "ambient"}
    for sensor, node in node_of.items():
        assert long[sensor].iloc[-1] == pytest.approx(long[node].iloc[-1], abs=1e-6)


def test_sensor_time_constants_are_per_mounting_and_realistic():
    taus = {s.name: s.tau_s for s in PARAMS.sensors}
    # several minutes (screwed into a bearing housing) to 20 min (pad on the bed)
    assert all(240.0 <= t <= 1200.0 for t in taus.values())
    assert taus["T1"] < taus["T4"] < taus["T7"] and len(set(taus.values())) >= 5
    assert TERMS[EFFECTS["sensor_lag"].term].func(PARAMS) == tuple(taus.values())
    # a sensor without its own time constant uses the machine's; 0 = reads its node directly
    assert AxisParams().sensors[0].tau_s is None
    assert TERMS[EFFECTS["sensor_lag"].term].func(AxisParams())[0] == AxisParams().sensor_tau_s
    np.testing.assert_array_equal(sensor_time_constants(60.0, 3), [60.0, 60.0, 60.0])
    with pytest.raises(ValueError, match="must be finite and >= 0 s"):
        sensor_time_constants((60.0, -1.0), 2)


def test_sensor_lag_mixes_direct_and_lagged_sensors():
    sensors = tuple(replace(s, tau_s=0.0) if s.name in ("T1", "T10") else s for s in PARAMS.sensors)
    params = replace(PARAMS, sensors=sensors)
    mixed = simulate_spindle(params, {"sensor_lag"}, PROGRAM, AMBIENT, TIMES)
    direct = run()
    lagged = run(effects={"sensor_lag"})
    pd.testing.assert_series_equal(mixed["T1"], direct["T1"])
    pd.testing.assert_series_equal(mixed["T10"], direct["T10"])
    np.testing.assert_allclose(mixed["T5"], lagged["T5"], atol=1e-12)


def test_thermal_bending_follows_column_front_rear_difference(baseline):
    on = run(effects={"thermal_bending"})
    pd.testing.assert_frame_equal(on[NODES + SENSORS], baseline[NODES + SENSORS])
    diff = on["node_column_front"] - on["node_column_rear"]
    diff = diff - diff.iloc[0]
    gain = (
        1e3
        * PARAMS.alpha_cast_iron_per_k
        * PARAMS.column_height_mm
        * PARAMS.spindle_overhang_mm
        / PARAMS.column_depth_mm
    )
    np.testing.assert_allclose(on["z_um"] - baseline["z_um"], gain * diff, atol=1e-9)
    assert (on["z_um"] - baseline["z_um"]).max() > 1.0  # front face warms first: nose rises


def test_motor_heat_heats_motor_and_headstock(baseline):
    on = run(effects={"motor_heat"})
    # without its own heat the motor is passive: never warmer than the headstock feeding it
    assert np.all(baseline["node_motor"] <= baseline["node_headstock"] + 1e-9)
    assert on["node_motor"].iloc[40] > on["node_headstock"].iloc[40] + 2.0
    assert on["node_headstock"].iloc[40] > baseline["node_headstock"].iloc[40] + 0.5
    assert on["z_um"].iloc[40] < baseline["z_um"].iloc[40]  # hotter head grows down more


def test_axis_ignores_spindle_effects_and_follows_ambient():
    ap = AxisParams()
    t = np.arange(0.0, 391 * 60, 600.0)
    base = simulate_axis(ap, (), 20.0, AMBIENT, t)
    same = simulate_axis(
        ap, {"motor_heat", "thermal_bending", "centrifugal_growth"}, 20.0, AMBIENT, t
    )
    pd.testing.assert_frame_equal(base, same, check_like=False)
    amb = simulate_axis(ap, {"ambient_variation"}, 20.0, AMBIENT, t)
    assert np.ptp(amb["ambient_degC"]) > 1.0 and np.ptp(base["ambient_degC"]) == 0.0
    np.testing.assert_allclose(base["slope_um_per_mm"], 0.0115 * base["screw_rise_K"])


# --------------------------------------------------- machine state, campaign to campaign

COLD = StateScatter()
PLAN = SpindlePlan("X01", datetime(2024, 7, 9, 8, 30), 6000.0, scatter=COLD)


def run_state(**state) -> pd.DataFrame:
    """The twin at 6000 rpm in a constant 20 degC air with the given machine state."""
    s = CampaignState(**state)
    params = apply_state(PARAMS, s)
    effects = {"nonlinear_bearing_heat", "motor_heat"}
    return simulate_spindle(params, effects, 6000.0, AmbientProfile(20.0), TIMES, history=s.history)


def shaft_minus_housing(out: pd.DataFrame) -> float:
    return float(out["node_spindle_shaft"].iloc[60] - out["node_front_bearing"].iloc[60])


def test_nominal_state_leaves_the_machine_unchanged():
    assert apply_state(PARAMS, CampaignState()) == PARAMS
    c = simulate_spindle_campaign(replace(PLAN, scatter=None), seed=1)
    assert c.state is None


def test_bearing_state_changes_the_unmeasured_shaft_against_its_housings():
    nominal = run_state()
    # preload/lubrication: more friction heat heats everything
    hot = run_state(bearing_heat_gain=1.2)
    assert hot["node_front_bearing"].iloc[60] > nominal["node_front_bearing"].iloc[60] + 1.0
    # what the sensors cannot see: the shaft against the housings that carry T1/T2
    for state, hotter in (
        ({"shaft_share": 0.55}, True),
        ({"shaft_share": 0.25}, False),
        ({"bearing_contact_gain": 0.7}, True),
        ({"shaft_cooling_gain": 1.4}, False),
    ):
        out = run_state(**state)
        gap = shaft_minus_housing(out) - shaft_minus_housing(nominal)
        assert (gap > 0.3) if hotter else (gap < -0.3), (state, gap)
    # same front-bearing reading, different drift: the T -> Z relation itself changes
    per_kelvin = [
        out["z_um"].iloc[60] / (out["node_front_bearing"].iloc[60] - 20.0)
        for out in (nominal, run_state(shaft_share=0.55))
    ]
    assert abs(per_kelvin[1] / per_kelvin[0] - 1.0) > 0.1
    net = apply_state(PARAMS, CampaignState(bearing_contact_gain=0.5)).network
    links = {frozenset((a, b)): g for a, b, g in net.links}
    assert links[frozenset(("front_bearing", "spindle_shaft"))] == pytest.approx(1.5)
    assert links[frozenset(("headstock", "column_front"))] == pytest.approx(10.0)


def test_motor_state_scales_the_motor_loss():
    out = run_state(motor_heat_gain=1.2)
    nominal = run_state()
    assert out["node_motor"].iloc[60] > nominal["node_motor"].iloc[60] + 0.5
    assert apply_state(PARAMS, CampaignState(motor_heat_gain=1.2)).motor_heat_w == 42.0


def test_season_convection_summer_fans_cool_the_machine():
    winter = run_state(convection_gain=DEMO_SCATTER.convection_factor("winter"))
    summer = run_state(convection_gain=DEMO_SCATTER.convection_factor("summer"))
    assert DEMO_SCATTER.convection_factor("summer") > DEMO_SCATTER.convection_factor("winter")
    for node in ("node_headstock", "node_column_front", "node_motor"):
        assert summer[node].iloc[-1] < winter[node].iloc[-1] - 0.2, node
    conv = apply_state(PARAMS, CampaignState(convection_gain=1.3)).network.convection
    np.testing.assert_allclose(conv, 1.3 * PARAMS.network.convection)


def test_warm_start_after_an_earlier_job():
    scatter = replace(COLD, warm_start_probability=1.0, warm_start_rpm=(6000.0,))
    warm = simulate_spindle_campaign(replace(PLAN, scatter=scatter), seed=3, effects=DEMO_EFFECTS)
    cold = simulate_spindle_campaign(PLAN, seed=3, effects=DEMO_EFFECTS)
    assert warm.state.warm_start and not cold.state.warm_start
    (segment,) = warm.state.history.segments
    assert 2.0 <= -segment.to_min / 60.0 <= 4.0  # stopped 2-4 h before the start
    assert 1.0 <= (segment.to_min - segment.from_min) / 60.0 <= 3.0 and segment.value == 6000.0
    # same day, same noise: only the history differs; the machine starts partially warm
    pd.testing.assert_series_equal(warm.simulation["ambient_degC"], cold.simulation["ambient_degC"])
    start = warm.simulation.iloc[0] - cold.simulation.iloc[0]
    assert start["node_front_bearing"] > 0.5 and start["node_headstock"] > 0.5
    assert start["node_column_front"] > 0.2 and start["T4"] > 0.5  # the sensors see it
    # ... so the temperatures rise, and the spindle drifts, less during the test
    for column in ("node_front_bearing", "node_headstock", "T1"):
        rise_w = warm.simulation[column].iloc[60] - warm.simulation[column].iloc[0]
        rise_c = cold.simulation[column].iloc[60] - cold.simulation[column].iloc[0]
        assert rise_w < rise_c - 0.2, column
    assert warm.simulation["z_um"].iloc[60] > cold.simulation["z_um"].iloc[60] + 1.5


def test_probe_mounting_offset_vanishes_after_zeroing():
    scatter = replace(COLD, probe_offset_sd_um=30.0)
    moved = simulate_spindle_campaign(replace(PLAN, scatter=scatter), seed=5)
    same = simulate_spindle_campaign(PLAN, seed=5)
    shift = moved.displacement["Z"] - same.displacement["Z"]
    assert abs(moved.state.probe_offset_um) > 1.0
    np.testing.assert_allclose(shift, moved.state.probe_offset_um, atol=1e-9)
    pd.testing.assert_frame_equal(moved.temperature, same.temperature)


def test_state_draws_never_shift_the_other_random_draws():
    scatters = (COLD, DEMO_SCATTER, replace(DEMO_SCATTER, warm_start_probability=1.0))
    after = []
    for scatter in scatters:
        rng = campaign_rng(1, "K01")
        draw_state(scatter, PARAMS, "winter", rng)
        after.append(rng.standard_normal(3))
    np.testing.assert_array_equal(after[0], after[1])
    np.testing.assert_array_equal(after[0], after[2])


def test_demo_states_vary_within_physical_limits(demo):
    states = [c.state for c in demo.values() if isinstance(c, SpindleCampaign)]
    gains = np.array([s.bearing_heat_gain for s in states])
    shares = np.array([s.shaft_share for s in states])
    assert 0.6 < gains.min() < 0.95 and 1.05 < gains.max() < 1.6
    assert shares.min() >= 0.15 and shares.max() <= 0.7 and np.ptp(shares) > 0.15
    warm = [s.warm_start for s in states]
    assert 0 < sum(warm) < len(warm)
    summer = [c.state.convection_gain for c in demo.values() if c.info.season == "summer"]
    winter = [
        c.state.convection_gain
        for c in demo.values()
        if c.info.season == "winter" and isinstance(c, SpindleCampaign)
    ]
    assert min(summer) > max(winter)


def _mlr_scores(campaigns: list[SpindleCampaign]) -> tuple[float, float]:
    """Fit S and prediction Mn (residual std, um) of MLR on all sensor rises (the paper's)."""
    data = {}
    for c in campaigns:
        t = c.temperature.drop(columns="elapsed_s").to_numpy()
        z = c.displacement["Z"].to_numpy()
        data[c.info.campaign_id] = (np.column_stack([np.ones(len(t)), t - t[0]]), z - z[0])
    fit, prediction = [], []
    for train, (x, y) in data.items():
        coef = np.linalg.lstsq(x, y, rcond=None)[0]
        for test, (xt, yt) in data.items():
            (fit if test == train else prediction).append(np.std(yt - xt @ coef, ddof=1))
    return float(np.mean(fit)), float(np.mean(prediction))


def test_demo_makes_the_model_choice_matter(demo):
    train = [c for c in demo.values() if isinstance(c, SpindleCampaign) and c.info.split == "train"]
    s_fit, mn = _mlr_scores(train)
    # a model of one campaign predicts another several times worse than it fits its own
    assert 1.5 < mn < 8.0 and mn > 4 * s_fit, (s_fit, mn)


# ------------------------------------------------------------------------ demo campaigns


def test_demo_set_is_the_papers_protocol(demo):
    assert list(demo) == DEMO_IDS
    spindle = [c for c in demo.values() if isinstance(c, SpindleCampaign)]
    assert all(c.effects == DEMO_EFFECTS for c in demo.values())
    assert DEMO_EFFECTS == {
        "ambient_variation",
        "motor_heat",
        "nonlinear_bearing_heat",
        "sensor_lag",
        "thermal_bending",
    }
    assert all(c.state is not None for c in spindle)
    seasons = pd.Series([c.info.season for c in spindle if c.info.split == "train"])
    assert seasons.value_counts().to_dict() == {
        s: 3 for s in ("winter", "spring", "summer", "autumn")
    }
    val = [c for c in spindle if c.info.split == "validation"]
    assert sorted({c.info.start.month for c in val}) == [10, 12] and len(val) == 6
    for c in spindle:
        assert c.program.segments[0].value in (2000.0, 4000.0, 6000.0)
        assert np.all(np.diff(c.temperature["elapsed_s"]) == 180.0)
        assert c.temperature["elapsed_s"].iloc[-1] >= 4 * 3600


def test_demo_magnitudes_match_the_sources(demo):
    z_at_4h = {}
    for cid, c in demo.items():
        if not isinstance(c, SpindleCampaign):
            continue
        first4h = c.temperature["elapsed_s"] <= 4 * 3600
        sensors = [s.name for s in c.sensors if s.role != "ambient"]
        temps = c.temperature.loc[first4h, sensors]
        rise = (temps - temps.iloc[0]).max().max()
        assert 2.0 <= rise <= 15.0, f"{cid}: max temperature rise {rise:.1f} K"
        z = c.displacement.loc[first4h, "Z"]
        drift = (z - z.iloc[0]).abs().max()
        assert 10.0 <= drift <= 60.0, f"{cid}: Z drift {drift:.1f} um in 4 h"
        z_at_4h[cid] = drift
    for season_ids in (("K01", "K02", "K03"), ("K07", "K08", "K09"), ("V04", "V05", "V06")):
        drifts = [z_at_4h[i] for i in season_ids]
        assert drifts == sorted(drifts)  # faster spindle, larger drift


@pytest.mark.parametrize("cid", ["K01", "K03"])
def test_every_demo_effect_changes_the_demo_data_noticeably(demo, cid):
    plan = next(p for p in demo_plans() if p.campaign_id == cid)
    on = demo[cid].simulation
    sensors = [s.name for s in PARAMS.sensors]
    for name in sorted(DEMO_EFFECTS):
        off = simulate_spindle_campaign(plan, seed=cli.DEFAULT_SEED, effects=DEMO_EFFECTS - {name})
        d_temp = np.abs(on[sensors].to_numpy() - off.simulation[sensors].to_numpy()).max()
        d_z = np.abs(on["z_um"] - off.simulation["z_um"]).max()
        assert d_temp > 0.3 or d_z > 1.0, f"{name} hardly changes {cid}: {d_temp} K, {d_z} um"


def test_sensor_chain_quantises_and_offsets(demo):
    c = demo["K05"]
    values = c.temperature[[s.name for s in c.sensors]].to_numpy()
    np.testing.assert_allclose(values / 0.0625, np.round(values / 0.0625), atol=1e-9)
    err = values - c.simulation[[s.name for s in c.sensors]].to_numpy()
    offsets = np.array([s.offset_degc for s in c.sensors])
    assert np.all(np.abs(offsets) <= 0.2)
    np.testing.assert_allclose(err.mean(axis=0), offsets, atol=0.03)
    probe = c.displacement["Z"] - c.simulation["z_um"] - c.state.probe_offset_um
    assert 0.1 < probe.std() < 0.35 and probe.abs().max() < 1.0


@pytest.mark.parametrize("cid", ["Y01", "Y02"])
def test_axis_truth_is_consistent_with_laser(demo, cid):
    c = demo[cid]
    truth, laser = c.truth, c.laser
    assert len(truth.geometric_coeffs_um) == 5
    for elapsed_min, p in laser.groupby("elapsed_min"):
        plus = p[p["direction"] == "+"].set_index("target_mm")["deviation_um"].sort_index()
        minus = p[p["direction"] == "-"].set_index("target_mm")["deviation_um"].sort_index()
        x = plus.index.to_numpy()
        mean = 0.5 * (plus + minus).to_numpy()
        slope, intercept = np.polyfit(x, mean - truth.geometric_um(x), 1)
        row = truth.passes.set_index("elapsed_min").loc[elapsed_min]
        assert slope == pytest.approx(row["slope_um_per_mm"], abs=0.002)
        assert intercept == pytest.approx(row["offset_um"], abs=0.3)
        resid = mean - truth.geometric_um(x) - truth.thermal_um(x, elapsed_min)
        assert resid.std() < 2 * c.params.laser_noise_um
        assert (plus - minus).mean() == pytest.approx(truth.reversal_um, abs=0.2)
    slopes = truth.passes["slope_um_per_mm"].to_numpy()
    assert slopes[0] == 0.0 and 0.03 < slopes.max() < 0.12


def test_axis_slope_grows_during_the_patent_warm_up(demo):
    passes = demo["Y01"].truth.passes
    assert passes["elapsed_min"].tolist() == list(PATENT_PASSES_MIN)
    assert np.all(np.diff(passes["slope_um_per_mm"]) > 0)
    np.testing.assert_allclose(passes["slope_um_per_mm"], 0.0115 * passes["screw_rise_K"])


# ------------------------------------------------------------------- files and the CLI


def _files(root: Path) -> list[Path]:
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())


def test_demo_regenerates_bit_identically(demo_dir, tmp_path):
    again = tmp_path / "raw_b"
    assert cli.main(["--preset", "demo", "--out", str(again)]) == 0
    files = _files(demo_dir)
    assert files == _files(again) and len(files) == 18 * 3 + 2 * 3
    _, mismatch, errors = filecmp.cmpfiles(demo_dir, again, [str(f) for f in files], shallow=False)
    assert mismatch == [] and errors == []


def test_committed_demo_data_is_current(demo_dir):
    committed = REPO / "data" / "raw"
    files = _files(demo_dir)
    missing = [f for f in files if not (committed / f).is_file()]
    assert not missing, (
        f"regenerate with: thermal simulate --preset demo --out data/raw ({missing})"
    )
    _, mismatch, errors = filecmp.cmpfiles(
        committed, demo_dir, [str(f) for f in files], shallow=False
    )
    assert mismatch == [] and errors == [], (
        f"data/raw differs from the twin for {mismatch}; "
        "regenerate with: thermal simulate --preset demo --out data/raw"
    )


def test_seed_changes_the_day_not_the_machine(tmp_path):
    for seed in ("1", "2"):
        assert cli.main(["--only", "K01", "--seed", seed, "--out", str(tmp_path / seed)]) == 0
    a = pd.read_csv(tmp_path / "1" / "K01" / "temperature.csv")
    b = pd.read_csv(tmp_path / "2" / "K01" / "temperature.csv")
    assert not a.equals(b)
    assert [p.name for p in (tmp_path / "1").iterdir()] == ["K01"]
    # another day's air and noise, same machine and protocol: similar temperature rises
    rise_a, rise_b = a - a.iloc[0], b - b.iloc[0]
    assert (rise_a - rise_b).drop(columns="elapsed_s").abs().max().max() < 2.0


def test_written_campaigns_follow_the_contract(demo_dir):
    folders = sorted(p.name for p in demo_dir.iterdir())
    assert folders == DEMO_IDS
    for cid in folders:
        folder = demo_dir / cid
        meta = yaml.safe_load((folder / "campaign.yaml").read_text(encoding="utf-8"))
        assert meta["campaign_id"] == cid
        assert meta["synthetic"] is True
        assert isinstance(meta["start"], datetime)
        assert meta["season"] == SEASON_OF_MONTH[meta["start"].month]
        assert meta["split"] == ("validation" if cid[0] == "V" or cid == "Y02" else "train")
        roles = [s["role"] for s in meta["sensors"].values()]
        assert set(roles) <= ROLES and roles.count("ambient") == 1
        temp = pd.read_csv(folder / "temperature.csv")
        assert list(temp.columns) == ["elapsed_s", *meta["sensors"]]
        assert temp["elapsed_s"].is_monotonic_increasing and temp["elapsed_s"].is_unique
        assert not temp.isna().any().any()
        assert temp.drop(columns="elapsed_s").stack().between(-20, 80).all()
        if meta["kind"] == "spindle_drift":
            assert {s["type"] for s in meta["sensors"].values()} == {"DS18B20"}
            assert len(roles) == 10
            assert meta["displacement"]["Z"]["probe"] == "eddy_current"
            program = Program.from_contract(meta["spindle_program"])
            assert program.value_at(0.0) in (2000.0, 4000.0, 6000.0)
            assert program.segments[0].to_min >= 240
            disp = pd.read_csv(folder / "displacement.csv")
            assert list(disp.columns) == ["elapsed_s", "Z"]
            np.testing.assert_array_equal(disp["elapsed_s"], temp["elapsed_s"])
            assert not (folder / "laser.csv").exists()
        else:
            assert meta["kind"] == "axis_positioning"
            assert {s["type"] for s in meta["sensors"].values()} == {"PT100"}
            assert len(roles) == 7 and {"ball_screw", "nut", "bed"} <= set(roles)
            assert meta["axis"]["name"] == "Y" and meta["axis"]["stroke_mm"] == 280
            assert np.all(np.diff(temp["elapsed_s"]) == 600.0)
            laser = pd.read_csv(folder / "laser.csv", dtype={"direction": str})
            assert list(laser.columns) == [
                "elapsed_min",
                "run",
                "direction",
                "target_mm",
                "deviation_um",
            ]
            runs = laser.groupby("run")
            assert runs["elapsed_min"].nunique().max() == 1
            assert runs["target_mm"].apply(lambda s: sorted(s) == list(range(0, 281, 10))).all()
            direction = runs["direction"].first()
            assert (direction[direction.index % 2 == 1] == "+").all()
            assert (direction[direction.index % 2 == 0] == "-").all()
            per_pass = runs["elapsed_min"].first().groupby(lambda r: (r + 1) // 2).nunique()
            assert (per_pass == 1).all()
            passes = sorted(laser["elapsed_min"].unique())
            if cid == "Y01":
                assert passes == list(PATENT_PASSES_MIN)
            else:
                assert {0.0, 40.0, 220.0} <= set(passes)
            assert temp["elapsed_s"].iloc[-1] == max(passes) * 60
            assert not (folder / "displacement.csv").exists()


def test_campaign_files_do_not_reveal_the_effects(demo_dir):
    text = "".join(p.read_text(encoding="utf-8") for p in demo_dir.rglob("*.yaml"))
    for name in EFFECTS:
        assert name not in text


def test_single_preset_writes_one_campaign(tmp_path):
    args = ["--preset", "single", "--id", "K13", "--season", "summer", "--rpm", "4000"]
    assert cli.main([*args, "--seed", "13", "--out", str(tmp_path)]) == 0
    assert [p.name for p in tmp_path.iterdir()] == ["K13"]
    meta = yaml.safe_load((tmp_path / "K13" / "campaign.yaml").read_text(encoding="utf-8"))
    assert meta["season"] == "summer" and meta["start"].month in (6, 7, 8)
    assert meta["spindle_program"][0]["rpm"] == 4000 and meta["synthetic"] is True
    assert sorted(p.name for p in (tmp_path / "K13").iterdir()) == [
        "campaign.yaml",
        "displacement.csv",
        "temperature.csv",
    ]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--effects", "motor_heat,warp_drive"], "unknown effect 'warp_drive'"),
        (["--only", "K99"], "no demo campaign"),
        (
            ["--preset", "single", "--season", "summer", "--start", "2024-01-05T08:00"],
            "is in winter",
        ),
    ],
)
def test_cli_usage_errors(args, message, tmp_path, capsys):
    assert cli.main([*args, "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_cli_lists_effects(capsys):
    assert cli.main(["--list-effects"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in EFFECTS)
    assert (
        "demo preset: ambient_variation, motor_heat, nonlinear_bearing_heat, sensor_lag, "
        "thermal_bending" in out
    )


def test_demo_plans_ids_are_unique():
    ids = [p.campaign_id for p in demo_plans()]
    assert ids == DEMO_IDS

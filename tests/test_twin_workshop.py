"""Tests of the twin's workshop preset: one continuous run cut into six campaign folders."""

from __future__ import annotations

import filecmp
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from pipeline.io.tables import ingest
from pipeline.thermal.program import Program
from pipeline.twin import SpindleParams, cli
from pipeline.twin.ambient import SEASON_OF_MONTH, AmbientProfile, draw_weather
from pipeline.twin.instruments import EddyCurrentProbe, PlacedSensor, first_order_lag
from pipeline.twin.lateral import LateralParams, lateral_drift
from pipeline.twin.workshop import (
    WORKSHOP_EFFECTS,
    WORKSHOP_SENSORS,
    WorkshopPlan,
    WorkshopSlot,
    simulate_workshop,
    workshop_plan,
)
from pipeline.validation.checks import validate_tables
from tests.helpers.repo_params import alignment_gap_s, validation_limits

IDS = [f"W0{k}" for k in range(1, 7)]
FILES = ["campaign.yaml", "displacement.csv", "spindle.csv", "temperature.csv"]
SENSORS = [f"T{k}" for k in range(1, 17)]
AXES = ["X", "Y", "Z"]
INTERVAL_S = 20.0
KEYS = {
    "campaign_id",
    "kind",
    "machine",
    "start",
    "season",
    "synthetic",
    "notes",
    "spindle_program",
    "sensors",
    "displacement",
}
PROBE_NOISE_UM = EddyCurrentProbe().noise_sd_um


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("workshop")
    assert cli.main(["--preset", "workshop", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def run():
    return simulate_workshop(workshop_plan(), seed=cli.WORKSHOP_SEED)


@pytest.fixture(scope="module")
def folders(raw) -> dict[str, dict]:
    out = {}
    for cid in IDS:
        folder = raw / cid
        out[cid] = {
            "meta": yaml.safe_load((folder / "campaign.yaml").read_text(encoding="utf-8")),
            "temperature": pd.read_csv(folder / "temperature.csv"),
            "displacement": pd.read_csv(folder / "displacement.csv"),
            "spindle": pd.read_csv(folder / "spindle.csv"),
        }
    return out


def _duration_s(folder: dict) -> float:
    """Campaign duration from the data: last sample + one interval."""
    elapsed = folder["temperature"]["elapsed_s"].to_numpy()
    return float(elapsed[-1] + np.median(np.diff(elapsed)))


# ------------------------------------------------------------------- folders and metadata


def test_six_folders_with_the_contract_files(raw):
    assert sorted(p.name for p in raw.iterdir()) == IDS
    for cid in IDS:
        assert sorted(p.name for p in (raw / cid).iterdir()) == FILES


def test_campaigns_are_back_to_back_on_one_machine_in_one_season(folders):
    metas = [folders[cid]["meta"] for cid in IDS]
    assert len({m["machine"] for m in metas}) == 1
    assert {m["season"] for m in metas} == {SEASON_OF_MONTH[metas[0]["start"].month]}
    for a, b in zip(IDS, IDS[1:], strict=False):
        start_a, start_b = folders[a]["meta"]["start"], folders[b]["meta"]["start"]
        assert isinstance(start_a, datetime)
        # the next campaign starts one interval after the last sample of this one
        last = folders[a]["temperature"]["elapsed_s"].iloc[-1]
        assert start_b == start_a + timedelta(seconds=last + INTERVAL_S)
        assert start_b == start_a + timedelta(seconds=_duration_s(folders[a]))
    total_h = sum(_duration_s(folders[cid]) for cid in IDS) / 3600.0
    assert 44.0 <= total_h <= 48.0


def test_metadata_has_no_split_and_nothing_that_reveals_the_chain(folders):
    for cid in IDS:
        meta = folders[cid]["meta"]
        assert set(meta) == KEYS, f"{cid}: unexpected keys {set(meta) ^ KEYS}"
        assert meta["campaign_id"] == cid and meta["kind"] == "spindle_drift"
        assert meta["synthetic"] is True
        assert "thermal simulate --preset workshop" in meta["notes"]


def test_sixteen_ds18b20_sensors_without_role_or_location(folders):
    for cid in IDS:
        sensors = folders[cid]["meta"]["sensors"]
        assert list(sensors) == SENSORS
        assert all(s == {"role": "other", "type": "DS18B20"} for s in sensors.values())
        temp = folders[cid]["temperature"]
        assert list(temp.columns) == ["elapsed_s", *SENSORS]
        assert np.allclose(np.diff(temp["elapsed_s"]), INTERVAL_S)
        readings = temp[SENSORS].to_numpy()
        np.testing.assert_allclose(readings * 16, np.round(readings * 16), atol=1e-9)


def test_three_eddy_current_probes_declared_and_present(folders):
    for cid in IDS:
        declared = folders[cid]["meta"]["displacement"]
        assert declared == {axis: {"probe": "eddy_current"} for axis in AXES}
        disp = folders[cid]["displacement"]
        assert list(disp.columns) == ["elapsed_s", *AXES]
        np.testing.assert_array_equal(disp["elapsed_s"], folders[cid]["temperature"]["elapsed_s"])
        values = disp[AXES].to_numpy()
        np.testing.assert_allclose(values * 10, np.round(values * 10), atol=1e-6)
        assert not disp.isna().any().any()


# ------------------------------------------------------------------------ spindle program


def test_each_campaign_runs_four_hours_then_stops(folders):
    for cid in IDS:
        program = Program.from_contract(folders[cid]["meta"]["spindle_program"])
        running = [s for s in program.segments if s.value > 0]
        assert running[0].from_min == 0 and running[-1].to_min == 240
        last = program.segments[-1]
        assert last.value == 0 and last.to_min * 60 == _duration_s(folders[cid])
    durations = [_duration_s(folders[cid]) / 3600 for cid in IDS]
    assert durations[:-1] == [8.0] * 5 and durations[-1] <= 8.0


def test_one_campaign_steps_its_speed(folders):
    stepped = []
    for cid in IDS:
        program = Program.from_contract(folders[cid]["meta"]["spindle_program"])
        speeds = [s.value for s in program.segments if s.value > 0]
        if len(speeds) > 1:
            stepped.append(cid)
            assert speeds == sorted(speeds) and len(set(speeds)) == 4
    assert len(stepped) == 1


def test_spindle_log_is_the_program_with_noise(folders):
    for cid in IDS:
        log = folders[cid]["spindle"]
        np.testing.assert_array_equal(log["elapsed_s"], folders[cid]["temperature"]["elapsed_s"])
        commanded = Program.from_contract(folders[cid]["meta"]["spindle_program"]).value_at(
            log["elapsed_s"].to_numpy()
        )
        running = commanded > 0
        assert (log["rpm"][~running] == 0).all()
        rel = log["rpm"][running] / commanded[running] - 1.0
        assert 0.001 < rel.std() < 0.006 and abs(rel.mean()) < 0.001


# ------------------------------------------------------------------------ one warm run


def test_temperatures_continue_across_the_cuts(folders):
    cold = folders["W01"]["temperature"][SENSORS].iloc[0].to_numpy()
    for a, b in zip(IDS, IDS[1:], strict=False):
        last = folders[a]["temperature"][SENSORS].iloc[-1].to_numpy()
        first = folders[b]["temperature"][SENSORS].iloc[0].to_numpy()
        jump = np.sqrt(np.mean((first - last) ** 2))
        from_cold = np.sqrt(np.mean((first - cold) ** 2))
        assert jump < 0.1, f"{b} does not start where {a} ended ({jump:.3f} K RMS)"
        assert from_cold > 5 * jump and from_cold > 0.3, f"{b} starts like the cold {IDS[0]}"


def test_displacement_continues_across_the_cuts(folders, run):
    cold = folders["W01"]["displacement"][AXES].iloc[0].to_numpy()
    counts = np.cumsum([len(folders[cid]["displacement"]) for cid in IDS])
    true = run.truth[["x_um", "y_um", "z_um"]].to_numpy()
    for (a, b), cut in zip(zip(IDS, IDS[1:], strict=False), counts, strict=False):
        last = folders[a]["displacement"][AXES].iloc[-1].to_numpy()
        first = folders[b]["displacement"][AXES].iloc[0].to_numpy()
        # the true drift may jump at a cut only by the centrifugal shift of a speed change
        true_jump = true[cut] - true[cut - 1]
        centrifugal = np.diff(run.truth["z_centrifugal_growth_um"].to_numpy()[cut - 1 : cut + 1])
        np.testing.assert_allclose(true_jump, [0.0, 0.0, centrifugal[0]], atol=0.2)
        # same probes, same mounting: the readings continue within the probe noise
        assert np.all(np.abs(first - last - true_jump) < 5 * PROBE_NOISE_UM), (a, b)
    w02 = folders["W02"]["displacement"][AXES].iloc[0].to_numpy()
    assert np.linalg.norm(w02 - cold) > 10 * PROBE_NOISE_UM


def test_truth_is_one_run_cut_at_sample_instants(run):
    stacked = pd.concat([c.truth for c in run.campaigns], ignore_index=True)
    pd.testing.assert_frame_equal(
        stacked.drop(columns="elapsed_s"), run.truth.drop(columns="elapsed_s")
    )
    assert [c.truth["elapsed_s"].iloc[0] for c in run.campaigns] == [0.0] * 6


# ---------------------------------------------------------------------------- magnitudes


def test_drift_magnitudes_per_axis(run):
    for campaign in run.campaigns:
        spread = {a: np.ptp(campaign.truth[f"{a.lower()}_um"]) for a in AXES}
        assert 8.0 < spread["Z"] < 80.0, campaign.info.campaign_id
        assert 1.0 < spread["X"] < 25.0 and 2.0 < spread["Y"] < 30.0, spread
    run_spread = {a: np.ptp(run.truth[f"{a.lower()}_um"]) for a in AXES}
    assert run_spread["Z"] > run_spread["Y"] > run_spread["X"] > 3.0


def test_probe_chain_noise_drift_and_holder(run):
    measured = pd.concat([c.displacement for c in run.campaigns], ignore_index=True)
    for axis in AXES:
        error = measured[axis].to_numpy() - run.truth[f"{axis.lower()}_um"].to_numpy()
        error -= error[0]  # the mounting offset
        # white noise: increments of about sqrt(2) x 0.3 um (drift and holder are slow)
        assert 0.3 < np.std(np.diff(error)) < 0.6
        # holder temperature (0.2-0.6 um/K) and electronics walk: a few um at most
        slow = pd.Series(error).rolling(90, center=True).mean().dropna()
        assert 0.3 < np.ptp(slow) < 6.0, axis


def test_sensors_read_their_places_through_their_lags(run):
    truth = run.truth
    air = truth["ambient_degC"]
    # stratified air: cooler and damped near the floor (T3), warmer up high (T11)
    assert (truth["T3"] - air).mean() < -0.3 and np.ptp(truth["T3"]) < np.ptp(air)
    assert (truth["T11"] - air).mean() > 0.3
    # the bearing housing (4 min) reacts to the speed steps faster than the bed (30 min)
    front, bed = truth["T2"].to_numpy(), truth["T5"].to_numpy()
    assert np.ptp(front) > 3.0 and np.ptp(bed) < np.ptp(front) / 2
    assert not any("spindle_shaft" in dict(s.mix) for s in WORKSHOP_SENSORS)
    assert sum(len(s.mix) > 1 for s in WORKSHOP_SENSORS) >= 4
    assert all(120.0 <= s.tau_s <= 1800.0 for s in WORKSHOP_SENSORS)


# ------------------------------------------------------------------------- seeds and demo


def test_reproducible_from_the_seed_and_different_for_another(raw, tmp_path):
    again, other = tmp_path / "again", tmp_path / "other"
    assert cli.main(["--preset", "workshop", "--out", str(again), "--seed", "2046"]) == 0
    assert cli.main(["--preset", "workshop", "--out", str(other), "--seed", "7"]) == 0
    names = [f"{cid}/{name}" for cid in IDS for name in FILES]
    _, mismatch, errors = filecmp.cmpfiles(raw, again, names, shallow=False)
    assert mismatch == [] and errors == []
    _, mismatch, _ = filecmp.cmpfiles(raw, other, names, shallow=False)
    assert {n.split("/")[1] for n in mismatch} >= {"temperature.csv", "displacement.csv"}


def test_effects_switch_the_workshop_terms():
    plan = workshop_plan()
    base = simulate_workshop(plan, seed=3, effects=WORKSHOP_EFFECTS - {"thermal_bending"})
    assert "y_column_bending_um" not in base.truth
    assert "y_column_bending_um" in simulate_workshop(plan, seed=3).truth
    direct = simulate_workshop(plan, seed=3, effects=WORKSHOP_EFFECTS - {"sensor_lag"})
    assert WORKSHOP_SENSORS[1].mix == (("front_bearing", 1.0),)  # T2: front bearing housing
    np.testing.assert_array_equal(direct.truth["T2"], direct.truth["node_front_bearing"])
    lagged = base.truth["T2"] - base.truth["node_front_bearing"]
    assert np.abs(lagged).max() > 0.2


def test_workshop_folders_pass_ingest_and_validation(raw):
    tables = ingest(raw, alignment_gap_s())
    assert tables["problems"].empty
    assert len(tables["samples"]) == sum(workshop_plan().sample_counts())
    limits = validation_limits()
    result = validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )
    assert result.problems == (), [p.to_dict() for p in result.problems]
    assert sorted(result.campaigns) == IDS


# ------------------------------------------------------------------------------- physics


def test_first_order_lag_is_exact_for_a_ramp_and_a_step():
    t = np.arange(-20.0, 7200.0, 20.0)
    ramp = 20.0 + 1e-3 * t
    np.testing.assert_allclose(first_order_lag(ramp, 600.0, 20.0), ramp - 0.6, atol=1e-12)
    # input 0 until t = 0, rising linearly to 1 at t = 20 s, then 1 (first-order hold)
    lagged = first_order_lag(np.where(t > 0, 1.0, 0.0), 600.0, 20.0)
    after = t >= 20.0
    expected = 1.0 - 30.0 * (np.exp(20.0 / 600.0) - 1.0) * np.exp(-t[after] / 600.0)
    np.testing.assert_allclose(lagged[after], expected, atol=1e-12)
    assert lagged[0] == lagged[1] == 0.0


def test_placed_sensor_rejects_weights_that_do_not_sum_to_one():
    with pytest.raises(ValueError, match="T99: mix weights must be >= 0 and sum to 1"):
        PlacedSensor("T99", (("bed", 0.5), ("motor", 0.4)), 60.0)


def test_lateral_terms_signs_and_gains():
    params = SpindleParams()
    nodes = params.network.nodes
    rise = np.zeros((2, len(nodes)))
    rise[1, nodes.index("headstock")] = 1.0
    rise[1, nodes.index("motor")] = 1.0  # motor as warm as the headstock: no side gradient
    parts = lateral_drift(params, LateralParams(), rise, {"thermal_bending"})
    assert parts["y_headstock_expansion_um"][1] == pytest.approx(-3.15)
    assert parts["x_motor_side_bending_um"][1] == pytest.approx(0.0)
    assert parts["x_spindle_offset_um"][1] == pytest.approx(-0.525)
    assert parts["y_column_bending_um"][1] == 0.0
    rise[1, nodes.index("column_front")] = 1.0  # front warmer: column tilts back
    rise[1, nodes.index("motor")] = 3.0  # motor side warmer: nose moves away from it
    parts = lateral_drift(params, LateralParams(), rise, {"thermal_bending"})
    assert parts["y_column_bending_um"][1] == pytest.approx(4.22625)
    assert parts["x_motor_side_bending_um"][1] < -2.0
    np.testing.assert_allclose(
        parts["x_um"], parts["x_motor_side_bending_um"] + parts["x_spindle_offset_um"]
    )
    assert "y_column_bending_um" not in lateral_drift(params, LateralParams(), rise, ())


def test_weather_wander_is_zero_at_the_start_and_slow():
    profile = AmbientProfile(mean_degc=19.0, daily_amplitude_k=3.0, start_hour=7.0)
    weather = draw_weather(profile, -72 * 3600.0, 46 * 3600.0, np.random.default_rng(1))
    t = np.arange(-72 * 3600.0, 46 * 3600.0, 600.0)
    wander = weather.at(t) - profile.at(t)
    assert weather.at(0.0) == pytest.approx(profile.at(0.0))
    assert np.max(np.abs(np.diff(wander))) < 0.2 and np.ptp(wander) > 0.2


def test_plan_rejects_an_interval_that_does_not_divide_a_campaign():
    with pytest.raises(ValueError, match="W01 lasts 481.0 min, not a whole number of 120.0 s"):
        WorkshopPlan(
            datetime(2025, 4, 7, 7), (WorkshopSlot("W01", ((241.0, 1000.0),)),), interval_s=120.0
        )


def test_plan_interval_is_a_parameter():
    plan = replace(workshop_plan(), interval_s=60.0)
    assert plan.sample_counts() == [480] * 5 + [360]
    run = simulate_workshop(plan, seed=1)
    assert np.all(np.diff(run.campaigns[0].temperature["elapsed_s"]) == 60.0)


def test_the_command_takes_the_sampling_interval_and_refuses_one_that_does_not_divide(
    tmp_path, capsys
):
    assert cli.main(["--preset", "workshop", "--interval-s", "60", "--out", str(tmp_path)]) == 0
    temperature = pd.read_csv(tmp_path / "W01" / "temperature.csv")
    assert len(temperature) == 480 and np.all(np.diff(temperature["elapsed_s"]) == 60.0)
    assert cli.main(["--preset", "workshop", "--interval-s", "7", "--out", str(tmp_path)]) == 2
    assert "not a whole number of 7.0 s intervals" in capsys.readouterr().err
    assert cli.main(["--preset", "demo", "--interval-s", "60", "--out", str(tmp_path)]) == 2
    assert "--interval-s need --preset workshop" in capsys.readouterr().err


def test_logger_table_holds_the_campaigns_readings_on_one_time_base(tmp_path, raw):
    path = tmp_path / "logger.csv"
    assert cli.main(["--preset", "workshop", "--logger-table", str(path), "--hours", "16"]) == 0
    table = pd.read_csv(path, parse_dates=["timestamp"])
    assert list(table.columns) == [
        "timestamp",
        "rpm",
        "ch1",
        "ch2",
        "ch3",
        *[f"t{i}" for i in range(1, 17)],
    ]
    assert len(table) == 16 * 3600 // 20
    assert (table["timestamp"].diff().dropna() == pd.Timedelta(seconds=20)).all()
    second = yaml.safe_load((raw / "W02" / "campaign.yaml").read_text())
    start = pd.Timestamp(second["start"])
    rows = table[table["timestamp"] >= start].reset_index(drop=True)
    temperature = pd.read_csv(raw / "W02" / "temperature.csv")
    displacement = pd.read_csv(raw / "W02" / "displacement.csv")
    n = len(rows)
    np.testing.assert_allclose(rows["t7"], temperature["T7"][:n], atol=1e-4)
    np.testing.assert_allclose(rows["ch3"], displacement["Z"][:n], atol=1e-4)
    assert rows["timestamp"].iloc[0] == start

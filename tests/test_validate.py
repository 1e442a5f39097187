"""Tests of the validate stage and the Pandera models (schemas/).

The ingested tables are built here directly in the format ``ingest`` writes (spec): a valid
spindle campaign K01 and a valid axis campaign A01; each test corrupts one thing.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pandera.pandas as pa
import pytest
from pandera.errors import SchemaErrors

import schemas
from pipeline import paths
from pipeline.config import load_section
from pipeline.errors import ParamsError
from pipeline.settings.base import load_settings, parse_section
from pipeline.settings.validate import ValidateSettings
from pipeline.stages import validate as v
from pipeline.validation.checks import validate_tables
from pipeline.validation.problems import NoValidCampaignError
from pipeline.validation.report import require_valid
from pipeline.validation.tables import select_valid
from pipeline.validation.texts import PROBLEM_TEXTS

REPO = Path(__file__).resolve().parents[1]

LIMITS = schemas.ValidationLimits(
    temperature_range_degC=(-20.0, 80.0),
    ds18b20_power_on_degC=85.0,
    ds18b20_disconnected_degC=-127.0,
    interval_tolerance=0.2,
    stuck_min_samples=5,
    stuck_min_minutes=0.0,
    stuck_min_other_change_degC=0.5,
    spike_threshold_degC=3.0,
    displacement_range_um=(-500.0, 500.0),
    laser_target_tolerance_mm=0.01,
    laser_deviation_range_um=(-1000.0, 1000.0),
    min_samples=10,
    air_temperature_max_degC=45.0,
    displacement_min_span_um=0.5,
    unit_check_min_rise_degC=2.0,
    min_program_coverage=0.25,
)

N = 12  # samples per campaign, 60 s apart
TARGETS = [0.0, 50.0, 100.0, 150.0]
SPINDLE_SENSORS = {
    "T1": {"role": "spindle_front_bearing", "location": "front bearing", "type": "DS18B20"},
    "T2": {"role": "spindle_motor", "type": "PT100"},
    "T3": {"role": "headstock"},  # no type: DS18B20 codes apply
    "T4": {"role": "ambient", "type": "DS18B20"},
}
AXIS_SENSORS = {
    "T1": {"role": "ball_screw", "type": "DS18B20"},
    "T2": {"role": "nut", "type": "DS18B20"},
    "T3": {"role": "ambient", "type": "DS18B20"},
}


def _campaign_row(campaign_id, kind, sensors, displacement, axis_name=None, stroke=np.nan):
    return {
        "campaign_id": campaign_id,
        "kind": kind,
        "machine": "vmc-450",
        "start": pd.Timestamp("2015-01-12T08:30:00"),
        "season": "winter",
        "season_derived": False,
        "synthetic": True,
        "split": "train",
        "start_state": None,
        "follows": None,
        "axis_name": axis_name,
        "stroke_mm": stroke,
        "sensors_json": json.dumps(sensors),
        "displacement_json": json.dumps(displacement),
        "spindle_program_json": json.dumps([{"from_min": 0, "rpm": 4000}]),
        "heat_loads_json": "[]",
        "has_spindle_log": False,
        "source_dir": f"data/raw/{campaign_id}",
    }


def _temperatures(names, start=20.0):
    i = np.arange(N, dtype=float)
    return {name: start + k + (0.2 + 0.1 * k) * i for k, name in enumerate(names)}


def make_tables():
    """Return the four ingested tables with a valid spindle (K01) and axis (A01) campaign."""
    campaigns = pd.DataFrame(
        [
            _campaign_row(
                "K01", "spindle_drift", SPINDLE_SENSORS, {"Z": {"probe": "eddy_current"}}
            ),
            _campaign_row("A01", "axis_positioning", AXIS_SENSORS, {}, "Y", 280.0),
        ]
    )
    campaigns = campaigns.astype({"axis_name": "str"})
    i = np.arange(N)
    spindle = pd.DataFrame(
        {
            "campaign_id": "K01",
            "source_row": i + 1,
            "elapsed_s": 60.0 * i,
            "rpm": 4000.0,
            **_temperatures(SPINDLE_SENSORS),
            "disp_Z": 2.0 * i,  # um
            "disp_Z_source_row": pd.array(i // 2 + 1, dtype="Int64"),  # displacement every 120 s
        }
    )
    axis = pd.DataFrame(
        {
            "campaign_id": "A01",
            "source_row": i + 1,
            "elapsed_s": 60.0 * i,
            "rpm": np.nan,
            **_temperatures(AXIS_SENSORS, start=18.0),
        }
    )
    samples = pd.concat([spindle, axis], ignore_index=True)
    samples = samples.astype({"campaign_id": "str", "source_row": "int64"})
    rows = []
    for run, (minute, direction) in enumerate(
        [(0.0, "+"), (0.0, "-"), (20.0, "+"), (20.0, "-"), (50.0, "+"), (50.0, "-")], start=1
    ):
        targets = TARGETS if direction == "+" else TARGETS[::-1]
        for target in targets:
            rows.append((minute, run, direction, target, 0.01 * target + run))
    laser = pd.DataFrame(
        rows, columns=["elapsed_min", "run", "direction", "target_mm", "deviation_um"]
    )
    laser.insert(0, "source_row", np.arange(1, len(laser) + 1, dtype="int64"))
    laser.insert(0, "campaign_id", "A01")
    laser = laser.astype({"campaign_id": "str", "direction": "str", "run": "int64"})
    problems = pd.DataFrame(
        {
            "campaign_id": pd.Series([], dtype="str"),
            "file": pd.Series([], dtype="str"),
            "row": pd.Series([], dtype="Int64"),
            "column": pd.Series([], dtype="str"),
            "check": pd.Series([], dtype="str"),
            "problem": pd.Series([], dtype="str"),
            "action": pd.Series([], dtype="str"),
        }
    )
    return {"campaigns": campaigns, "samples": samples, "laser": laser, "problems": problems}


def run(tables, limits=LIMITS):
    return validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )


def only(result, check):
    """Return the single problem with this check id (fails with the whole list otherwise)."""
    found = [p for p in result.problems if p.check == check]
    assert len(found) == 1, [p.to_dict() for p in result.problems]
    return found[0]


def set_cells(tables, table, campaign, rows, column, value):
    """Set ``column`` at the given 1-based source rows of one campaign (no other change)."""
    frame = tables[table].copy()
    mask = (frame["campaign_id"] == campaign) & frame["source_row"].isin(rows)
    frame.loc[mask, column] = value
    tables[table] = frame
    return tables


def set_campaign(tables, campaign, column, value):
    frame = tables["campaigns"].copy()
    frame.loc[frame["campaign_id"] == campaign, column] = value
    tables["campaigns"] = frame
    return tables


def assert_located(problem, campaign, file, row, column, check):
    assert problem.campaign == campaign
    assert problem.file == file
    assert problem.row == row
    assert problem.line == (None if row is None else row + 1)
    assert problem.column == column
    assert problem.check == check
    assert problem.message and problem.action
    assert "dvc repro" in problem.action


# --------------------------------------------------------------------------- baseline


def test_builder_tables_are_valid_and_match_the_static_models():
    tables = make_tables()
    result = run(tables)
    assert result.problems == ()
    assert result.valid == ["A01", "K01"]
    schemas.CampaignsModel.validate(tables["campaigns"])
    schemas.SpindleSamplesModel.validate(tables["samples"])
    schemas.AxisSamplesModel.validate(tables["samples"])
    schemas.LaserModel.validate(tables["laser"])
    schemas.ProblemsModel.validate(tables["problems"])


def test_every_check_of_the_schemas_has_a_problem_text():
    sensors = {"T1": {"type": "DS18B20"}}
    names = set()
    for schema in (
        schemas.CampaignsModel.to_schema(),
        schemas.SensorsModel.to_schema(),
        schemas.laser_schema(LIMITS),
        schemas.campaign_samples_schema("spindle_drift", sensors, ["Z"], LIMITS),
    ):
        names |= {c.name for c in schema.checks}
        for column in schema.columns.values():
            names |= {c.name for c in column.checks}
    names -= {"greater_than_or_equal_to"}  # source_row >= 1: an ingest format error (fallback)
    assert names - set(PROBLEM_TEXTS) == set()


# --------------------------------------------------------------------------- temperature.csv


def test_ds18b20_power_on_is_reported_with_rows_and_action():
    tables = set_cells(make_tables(), "samples", "K01", [1, 2], "T1", 85.0)
    problem = only(run(tables), "ds18b20_power_on")
    assert_located(problem, "K01", "temperature.csv", 1, "T1", "ds18b20_power_on")
    assert problem.value == 85.0
    assert "rows 1-2 (lines 2-3)" in problem.message
    assert problem.action.startswith(
        "replace the 85.0 readings of T1 in K01/temperature.csv rows 1-2 with empty cells"
    )
    assert all(p.check == "ds18b20_power_on" for p in run(tables).problems)  # not range/spike


@pytest.mark.parametrize(
    ("sensor", "check"),
    [("T3", "ds18b20_power_on"), ("T2", "temperature_range")],  # no type / PT100
)
def test_ds18b20_codes_apply_to_ds18b20_and_untyped_sensors_only(sensor, check):
    tables = set_cells(make_tables(), "samples", "K01", [N - 1, N], sensor, 85.0)
    problem = only(run(tables), check)
    assert_located(problem, "K01", "temperature.csv", N - 1, sensor, check)


def test_ds18b20_disconnected():
    tables = set_cells(make_tables(), "samples", "A01", [4], "T2", -127.0)
    problem = only(run(tables), "ds18b20_disconnected")
    assert_located(problem, "A01", "temperature.csv", 4, "T2", "ds18b20_disconnected")
    assert problem.value == -127.0
    assert "row 4 (line 5)" in problem.message


def test_temperature_out_of_physical_range():
    tables = set_cells(make_tables(), "samples", "K01", [10, 11, 12], "T2", 95.0)
    result = run(tables)
    problem = only(result, "temperature_range")
    assert_located(problem, "K01", "temperature.csv", 10, "T2", "temperature_range")
    assert "rows 10-12" in problem.message and "-20.0 to 80.0 degC" in problem.message
    assert result.quarantined == ["K01"]


def test_stuck_sensor():
    tables = set_cells(make_tables(), "samples", "K01", range(3, 10), "T2", 21.5)
    problem = only(run(tables), "stuck_sensor")
    assert_located(problem, "K01", "temperature.csv", 3, "T2", "stuck_sensor")
    assert problem.value == 21.5
    assert "7 samples" in problem.message and "rows 3-9" in problem.message


def test_a_short_repeat_at_fast_sampling_is_not_stuck():
    """7 identical samples 60 s apart cover 7 min: a quiet sensor, not a stuck one, at 10 min."""
    tables = set_cells(make_tables(), "samples", "K01", range(3, 10), "T2", 21.5)
    quiet = run(tables, replace(LIMITS, stuck_min_minutes=7.5))
    assert "stuck_sensor" not in {p.check for p in quiet.problems}
    problem = only(run(tables, replace(LIMITS, stuck_min_minutes=7.0)), "stuck_sensor")
    assert "at least 7 min" in problem.message


def test_constant_sensor_is_not_stuck_when_nothing_else_moves():
    tables = make_tables()
    for sensor in SPINDLE_SENSORS:
        tables = set_cells(tables, "samples", "K01", range(1, N + 1), sensor, 20.0)
    assert run(tables).problems == ()


def test_spike():
    tables = make_tables()
    row6 = tables["samples"].query("campaign_id == 'K01' and source_row == 6")["T3"].item()
    tables = set_cells(tables, "samples", "K01", [6], "T3", row6 + 10.0)
    problem = only(run(tables), "spike")
    assert_located(problem, "K01", "temperature.csv", 6, "T3", "spike")
    assert problem.value == pytest.approx(row6 + 10.0)


def test_time_not_strictly_increasing():
    tables = make_tables()
    samples = tables["samples"].copy()
    late = (samples["campaign_id"] == "K01") & (samples["source_row"] >= 6)
    samples.loc[late, "elapsed_s"] -= 60.0  # row 6 repeats the instant of row 5
    tables["samples"] = samples
    result = run(tables)
    problem = only(result, "time_increasing")
    assert_located(problem, "K01", "temperature.csv", 6, "elapsed_s", "time_increasing")
    assert problem.value == 240.0
    assert "240.0 s follows 240.0 s" in problem.message
    assert len(result.problems) == 1


def test_sampling_interval_inconsistent():
    tables = make_tables()
    samples = tables["samples"].copy()
    late = (samples["campaign_id"] == "A01") & (samples["source_row"] >= 7)
    samples.loc[late, "elapsed_s"] += 60.0  # a dropped sample between rows 6 and 7
    tables["samples"] = samples
    problem = only(run(tables), "sampling_interval")
    assert_located(problem, "A01", "temperature.csv", 7, "elapsed_s", "sampling_interval")
    assert problem.value == 120.0  # the interval, s
    assert "is 120.0 s" in problem.message and "median interval 60.0 s" in problem.message


def test_missing_time_is_reported_once():
    tables = set_cells(make_tables(), "samples", "K01", [4], "elapsed_s", np.nan)
    result = run(tables)
    problem = only(result, "missing_value")
    assert_located(problem, "K01", "temperature.csv", 4, "elapsed_s", "missing_value")
    assert len(result.problems) == 1  # no interval/order problem next to it


def test_declared_sensor_without_column():
    sensors = {**SPINDLE_SENSORS, "T5": {"role": "bed"}}
    tables = set_campaign(make_tables(), "K01", "sensors_json", json.dumps(sensors))
    problem = only(run(tables), "sensor_column_missing")
    assert_located(problem, "K01", "temperature.csv", None, "T5", "sensor_column_missing")
    assert "T5" in problem.action and "campaign.yaml" in problem.action


def test_temperature_column_not_in_sensor_map():
    sensors = {k: s for k, s in SPINDLE_SENSORS.items() if k != "T4"}
    tables = set_campaign(make_tables(), "K01", "sensors_json", json.dumps(sensors))
    problem = only(run(tables), "unknown_temperature_column")
    assert_located(problem, "K01", "temperature.csv", None, "T4", "unknown_temperature_column")


def test_sensor_of_other_campaign_is_not_unknown_here():
    # T4 exists in the union table (K01) but is all-NaN for A01: not an A01 column
    assert "T4" in make_tables()["samples"].columns
    assert [p.campaign for p in run(make_tables()).problems] == []


# --------------------------------------------------------------------------- displacement.csv


def test_declared_displacement_axis_without_data():
    displacement = {"Z": {"probe": "eddy_current"}, "X": {"probe": "eddy_current"}}
    tables = set_campaign(make_tables(), "K01", "displacement_json", json.dumps(displacement))
    problem = only(run(tables), "displacement_column_missing")
    assert_located(problem, "K01", "displacement.csv", None, "X", "displacement_column_missing")


def test_other_probe_names_are_accepted_and_bad_ones_reported():
    displacement = {"Z": {"probe": "eddy_current"}, "Z2": {"probe": "eddy_current"}}
    tables = set_campaign(make_tables(), "K01", "displacement_json", json.dumps(displacement))
    tables = set_cells(tables, "samples", "K01", range(1, N + 1), "disp_Z2", 1.5 * np.arange(N))
    rows = tables["samples"]["disp_Z_source_row"]
    tables["samples"]["disp_Z2_source_row"] = rows.where(tables["samples"]["disp_Z2"].notna())
    assert run(tables).problems == ()
    bad = {"Z": {"probe": "eddy_current"}, "Z-2": {"probe": "eddy_current"}}
    tables = set_campaign(make_tables(), "K01", "displacement_json", json.dumps(bad))
    problem = only(run(tables), "displacement_axis_known")
    assert_located(problem, "K01", "campaign.yaml", None, "displacement", "displacement_axis_known")


def test_undeclared_displacement_data():
    tables = set_cells(make_tables(), "samples", "A01", range(1, N + 1), "disp_Z", 1.0)
    tables = set_cells(tables, "samples", "A01", range(1, N + 1), "disp_Z_source_row", 1)
    result = run(tables)
    problem = only(result, "unknown_displacement_column")
    assert_located(problem, "A01", "displacement.csv", None, "Z", "unknown_displacement_column")
    assert len(result.problems) == 1  # disp_Z_source_row is not reported separately


def test_displacement_out_of_probe_range_names_the_displacement_row():
    # temperature rows 5 and 6 both take displacement.csv row 3
    tables = set_cells(make_tables(), "samples", "K01", [5, 6], "disp_Z", 900.0)
    problem = only(run(tables), "displacement_range")
    assert_located(problem, "K01", "displacement.csv", 3, "Z", "displacement_range")
    assert problem.value == 900.0
    assert "K01/displacement.csv row 3 (line 4)" in problem.message


# --------------------------------------------------------------------------- laser.csv


def test_laser_direction_not_plus_or_minus():
    tables = set_cells(make_tables(), "laser", "A01", [5, 6, 7, 8], "direction", "x")
    result = run(tables)
    problem = only(result, "laser_direction")
    assert_located(problem, "A01", "laser.csv", 5, "direction", "laser_direction")
    assert problem.value == "x"
    assert "rows 5-8" in problem.message


def test_one_bad_direction_is_reported_once():
    tables = set_cells(make_tables(), "laser", "A01", [3], "direction", "x")
    result = run(tables)
    problem = only(result, "laser_direction")
    assert_located(problem, "A01", "laser.csv", 3, "direction", "laser_direction")
    assert len(result.problems) == 1


def test_laser_run_with_two_directions():
    tables = set_cells(make_tables(), "laser", "A01", [2], "direction", "-")
    problem = only(run(tables), "laser_run_one_direction")
    assert_located(problem, "A01", "laser.csv", 2, "direction", "laser_run_one_direction")
    assert "run 1" in problem.message


def test_laser_run_with_two_times():
    tables = set_cells(make_tables(), "laser", "A01", [12], "elapsed_min", 21.0)
    problem = only(run(tables), "laser_run_one_time")
    assert_located(problem, "A01", "laser.csv", 12, "elapsed_min", "laser_run_one_time")


def test_laser_target_off_the_reference_set():
    tables = set_cells(make_tables(), "laser", "A01", [10], "target_mm", 50.5)
    result = run(tables)
    problem = only(result, "laser_target_set")
    assert_located(problem, "A01", "laser.csv", 10, "target_mm", "laser_target_set")
    assert problem.value == 50.5
    missing = only(result, "laser_target_missing")  # run 3 no longer measures 50 mm
    assert_located(missing, "A01", "laser.csv", 9, "target_mm", "laser_target_missing")
    assert missing.value == [50.0]


def test_missing_laser_deviation_is_a_missing_value():
    tables = set_cells(make_tables(), "laser", "A01", [7], "deviation_um", np.nan)
    result = run(tables)
    problem = only(result, "missing_value")
    assert_located(problem, "A01", "laser.csv", 7, "deviation_um", "missing_value")
    assert len(result.problems) == 1


def test_laser_run_missing_a_target():
    tables = make_tables()
    tables["laser"] = tables["laser"].iloc[:-1]  # last row of run 6 (target 0 mm) missing
    problem = only(run(tables), "laser_target_missing")
    assert_located(problem, "A01", "laser.csv", 21, "target_mm", "laser_target_missing")
    assert problem.value == [0.0]


def test_laser_without_cold_run():
    tables = make_tables()
    laser = tables["laser"].copy()
    laser["elapsed_min"] += 5.0
    tables["laser"] = laser
    problem = only(run(tables), "laser_cold_run")
    assert_located(problem, "A01", "laser.csv", None, "elapsed_min", "laser_cold_run")


def test_laser_pass_with_one_direction():
    tables = make_tables()
    tables["laser"] = tables["laser"].loc[tables["laser"]["run"] != 6]  # pass at 50 min: '+' only
    problem = only(run(tables), "laser_bidirectional")
    assert_located(problem, "A01", "laser.csv", 17, "direction", "laser_bidirectional")
    assert "elapsed_min 50.0" in problem.message and "only '+'" in problem.message


def test_axis_campaign_without_laser_rows():
    tables = make_tables()
    tables["laser"] = tables["laser"].iloc[0:0]
    problem = only(run(tables), "no_laser")
    assert_located(problem, "A01", "laser.csv", None, None, "no_laser")


# --------------------------------------------------------------------------- campaign.yaml


@pytest.mark.parametrize(
    ("column", "value", "check", "report_column"),
    [
        ("kind", "spindle", "kind_known", "kind"),
        ("split", "test", "split_known", "split"),
        ("season", "monsoon", "season_known", "season"),
        ("axis_name", None, "axis_declared", "axis.name"),
        ("start", pd.NaT, "metadata_missing", "start"),
        ("start_state", "hot", "start_state_known", "start_state"),
        ("follows", "../K00", "follows_format", "follows"),
        ("follows", "K01", "follows_other", "follows"),
    ],
)
def test_campaign_metadata(column, value, check, report_column):
    campaign = "K01" if column != "axis_name" else "A01"
    tables = set_campaign(make_tables(), campaign, column, value)
    problem = only(run(tables), check)
    assert_located(problem, campaign, "campaign.yaml", None, report_column, check)


def test_unknown_sensor_role():
    sensors = {**SPINDLE_SENSORS, "T2": {"role": "spindle_nose", "type": "PT100"}}
    tables = set_campaign(make_tables(), "K01", "sensors_json", json.dumps(sensors))
    problem = only(run(tables), "sensor_role_known")
    assert_located(problem, "K01", "campaign.yaml", None, "sensors.T2.role", "sensor_role_known")
    assert problem.value == "spindle_nose"


def test_two_ambient_sensors_give_one_problem():
    sensors = {**AXIS_SENSORS, "T2": {"role": "ambient", "type": "DS18B20"}}
    tables = set_campaign(make_tables(), "A01", "sensors_json", json.dumps(sensors))
    problem = only(run(tables), "single_ambient")
    assert_located(problem, "A01", "campaign.yaml", None, "sensors", "single_ambient")
    assert problem.value == ["T2", "T3"]


def test_spindle_campaign_without_displacement_axes():
    tables = set_campaign(make_tables(), "K01", "displacement_json", "{}")
    result = run(tables)
    problem = only(result, "displacement_declared")
    assert_located(problem, "K01", "campaign.yaml", None, "displacement", "displacement_declared")
    # the Z data then is undeclared as well
    assert only(result, "unknown_displacement_column").column == "Z"


def test_ingest_problems_quarantine_their_campaign():
    tables = make_tables()
    tables["problems"] = pd.DataFrame(
        {
            "campaign_id": ["K01"],
            "file": ["temperature.csv"],
            "row": pd.array([7], dtype="Int64"),
            "column": ["T2"],
            "check": ["non_numeric"],
            "problem": ["K01/temperature.csv row 7 column T2: 'abc' is not a number"],
            "action": ["write a number or leave the cell empty, then rerun dvc repro"],
        }
    ).astype({"campaign_id": "str", "file": "str", "column": "str", "check": "str"})
    result = run(tables)
    problem = only(result, "non_numeric")
    assert_located(problem, "K01", "temperature.csv", 7, "T2", "non_numeric")
    assert problem.message.startswith("K01/temperature.csv row 7")
    assert result.valid == ["A01"]


def test_missing_file_reported_by_ingest_is_not_repeated():
    tables = make_tables()
    samples = tables["samples"].copy()
    samples.loc[samples["campaign_id"] == "K01", ["disp_Z", "disp_Z_source_row"]] = np.nan
    tables["samples"] = samples
    tables["problems"] = pd.DataFrame(
        {
            "campaign_id": ["K01"],
            "file": ["displacement.csv"],
            "row": pd.array([None], dtype="Int64"),
            "column": [None],
            "check": ["missing_file"],
            "problem": ["displacement.csv is missing; a spindle_drift campaign needs it"],
            "action": ["add data/raw/K01/displacement.csv"],
        }
    ).astype({"campaign_id": "str", "file": "str", "column": "str", "check": "str"})
    result = run(tables)
    assert [(p.check, p.file) for p in result.problems] == [("missing_file", "displacement.csv")]
    assert result.quarantined == ["K01"]


def test_data_without_campaign_metadata():
    tables = make_tables()
    orphan = tables["samples"].loc[tables["samples"]["campaign_id"] == "A01"].copy()
    orphan["campaign_id"] = "K99"
    tables["samples"] = pd.concat([tables["samples"], orphan], ignore_index=True)
    result = run(tables)
    problem = only(result, "campaign_metadata_missing")
    assert_located(problem, "K99", "temperature.csv", None, None, "campaign_metadata_missing")
    assert "K99" in result.quarantined and result.valid == ["A01", "K01"]


# --------------------------------------------------------------------------- lazy, quarantine, I/O


def test_all_problems_of_a_campaign_are_reported_at_once():
    tables = set_cells(make_tables(), "samples", "K01", [1], "T1", 85.0)
    tables = set_cells(tables, "samples", "K01", [N], "T2", 99.0)
    tables = set_campaign(tables, "K01", "split", "test")
    checks = sorted(p.check for p in run(tables).problems)
    assert checks == ["ds18b20_power_on", "split_known", "temperature_range"]


def test_good_campaign_survives_next_to_a_bad_one():
    tables = set_cells(make_tables(), "samples", "K01", [1, 2], "T1", 85.0)
    result = run(tables)
    assert result.valid == ["A01"] and result.quarantined == ["K01"]
    out = select_valid(tables["campaigns"], tables["samples"], tables["laser"], result.valid)
    assert out["spindle"]["campaigns"].empty and out["spindle"]["samples"].empty
    assert list(out["axis"]["campaigns"]["campaign_id"]) == ["A01"]
    assert set(out["axis"]["samples"]["campaign_id"]) == {"A01"}
    assert "disp_Z" not in out["axis"]["samples"] and "T4" not in out["axis"]["samples"]
    assert len(out["axis"]["laser"]) == len(tables["laser"])


def test_no_valid_campaign_raises_naming_the_report():
    tables = set_campaign(make_tables(), "K01", "kind", "drift")
    tables = set_campaign(tables, "A01", "split", "test")
    result = run(tables)
    assert result.valid == []
    with pytest.raises(NoValidCampaignError, match=r"no valid campaign.*reports/validation"):
        require_valid(result, paths.VALIDATION_REPORT)


def test_the_validate_section_reads_the_repo_limits_and_names_bad_keys():
    limits = load_settings(ValidateSettings, "validate", REPO / "params.yaml").limits()
    assert limits.ds18b20_codes == (85.0, -127.0)
    section = load_section("validate", REPO / "params.yaml")
    with pytest.raises(
        ParamsError,
        match=r"params.yaml: validate.spike_degC: unknown key \(did you mean "
        r"'spike_threshold_degC'\?\); allowed here: temperature_range_degC, ",
    ):
        parse_section(ValidateSettings, "validate", {**section, "spike_degC": 1.0})
    with pytest.raises(ParamsError, match=r"validate.min_samples: missing"):
        parse_section(
            ValidateSettings, "validate", {k: v for k, v in section.items() if k != "min_samples"}
        )
    with pytest.raises(
        ParamsError, match=r"validate.temperature_range_degC = \[80, -20\]; low must"
    ):
        parse_section(
            ValidateSettings, "validate", {**section, "temperature_range_degC": [80, -20]}
        )


def _write_ingested(root: Path, tables) -> None:
    (root / paths.INGESTED).mkdir(parents=True)
    tables["campaigns"].to_parquet(root / paths.INGESTED_CAMPAIGNS, index=False)
    tables["samples"].to_parquet(root / paths.INGESTED_SAMPLES, index=False)
    tables["laser"].to_parquet(root / paths.INGESTED_LASER, index=False)
    tables["problems"].to_parquet(root / paths.INGESTED_PROBLEMS, index=False)
    shutil.copy(REPO / "params.yaml", root / "params.yaml")


def test_main_writes_valid_campaigns_and_report(tmp_path, monkeypatch, caplog):
    tables = set_cells(make_tables(), "laser", "A01", [3], "direction", "?")
    _write_ingested(tmp_path, tables)
    monkeypatch.chdir(tmp_path)
    assert v.main([]) == 0
    report = json.loads(paths.VALIDATION_REPORT.read_text())
    machines = {"A01": "vmc-450", "K01": "vmc-450"}  # each campaign's machine
    assert report["summary"] == {
        "campaigns": 2,
        "valid": ["K01"],
        "quarantined": ["A01"],
        "machines": machines,
    }
    assert {"campaign", "file", "row", "line", "column", "check", "value", "message", "action"} == (
        set(report["problems"][0])
    )
    assert {(p["check"], p["row"], p["line"]) for p in report["problems"]} >= {
        ("laser_direction", 3, 4)
    }
    spindle = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.SAMPLES_FILE)
    assert set(spindle["campaign_id"]) == {"K01"} and "disp_Z" in spindle
    schemas.SpindleSamplesModel.validate(spindle)
    assert pd.read_parquet(paths.VALIDATED_AXIS / paths.LASER_FILE).empty
    assert any("A01 quarantined" in r.getMessage() for r in caplog.records)


def test_main_fails_when_no_campaign_is_valid(tmp_path, monkeypatch):
    tables = set_campaign(make_tables(), "K01", "kind", "drift")
    tables = set_campaign(tables, "A01", "kind", "drift")
    _write_ingested(tmp_path, tables)
    monkeypatch.chdir(tmp_path)
    assert v.main([]) == 1
    assert json.loads(paths.VALIDATION_REPORT.read_text())["summary"]["valid"] == []


# --------------------------------------------------------------------------- downstream models


def test_cross_season_scores_model_checks_roles():
    scores = pd.DataFrame(
        {
            "axis": ["Z", "Z"],
            "model": ["mlr", "mlr"],
            "selection": ["all", "all"],
            "mode": ["static", "static"],
            "scheme": ["campaign", "campaign"],
            "train_unit": ["K01", "K01"],
            "test_campaign": ["K01", "K02"],
            "test_split": ["train", "train"],
            "test_season": ["winter", "spring"],
            "role": ["fit", "fit"],  # the second should be "prediction"
            "n_samples": np.array([10, 10], dtype="int64"),
            "rmse_um": [1.0, 2.0],
            "resid_std_um": [1.0, 1.5],
            "uncompensated_rms_um": [4.0, 4.0],
            "eta": [0.75, 0.5],
        }
    )
    with pytest.raises(SchemaErrors, match="role_consistent"):
        schemas.CrossSeasonScoresModel.validate(scores, lazy=True)
    fixed = scores.assign(role=["fit", "prediction"])
    schemas.CrossSeasonScoresModel.validate(fixed)
    validation = fixed.assign(test_split=["train", "validation"])
    with pytest.raises(SchemaErrors, match="role_consistent"):
        schemas.CrossSeasonScoresModel.validate(validation, lazy=True)
    season = fixed.assign(scheme="loso", train_unit="not_winter", role=["fit", "prediction"])
    schemas.CrossSeasonScoresModel.validate(season)
    campaign_out = fixed.assign(scheme="loco", train_unit="not_K02", role=["fit", "prediction"])
    schemas.CrossSeasonScoresModel.validate(campaign_out)
    with pytest.raises(SchemaErrors, match="less_than_or_equal_to"):
        schemas.CrossSeasonScoresModel.validate(fixed.assign(eta=[1.5, 0.5]), lazy=True)


def test_spindle_thermal_error_model_with_sensor_columns():
    frame = pd.DataFrame(
        {
            "axis": ["Z"] * 3,
            "campaign_id": ["K01"] * 3,
            "run_id": ["K01"] * 3,
            "elapsed_s": [0.0, 60.0, 120.0],
            "run_elapsed_s": [0.0, 60.0, 120.0],
            "source_row": np.array([1, 2, 3], dtype="int64"),
            "rpm": [4000.0] * 3,
            "split": ["train"] * 3,
            "season": ["winter"] * 3,
            "synthetic": [True] * 3,
            "warm_start": [False] * 3,
            "reference": ["first sample of K01 (cold start)"] * 3,
            "T1": [20.0, 20.5, 21.0],
            "thermal_error_um": [0.0, 1.0, 2.0],
            "displacement_um": [5.0, 6.0, 7.0],
        }
    )
    schema = schemas.with_sensor_columns(schemas.SpindleThermalErrorModel.to_schema(), ["T1"])
    schema.validate(frame)
    with pytest.raises(SchemaErrors, match="column_in_dataframe"):
        schema.validate(frame.drop(columns="T1"), lazy=True)
    assert isinstance(schema, pa.DataFrameSchema)


def test_axis_slopes_model_one_row_per_pass():
    slopes = pd.DataFrame(
        {
            "campaign_id": ["Y01", "Y01"],
            "axis_name": ["Y", "Y"],
            "split": ["train", "train"],
            "season": ["spring", "spring"],
            "synthetic": [True, True],
            "elapsed_min": [0.0, 20.0],
            "slope_um_per_mm": [0.0, 0.024],
            "intercept_um": [0.0, 0.74],
            "T1": [22.4, 24.5],
        }
    )
    schemas.AxisSlopesModel.validate(slopes)
    with pytest.raises(SchemaErrors, match="one_row_per_pass"):
        schemas.AxisSlopesModel.validate(slopes.assign(elapsed_min=[20.0, 20.0]), lazy=True)

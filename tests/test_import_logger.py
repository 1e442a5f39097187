"""Tests of ``thermal import logger`` (pipeline/importers/): logger table -> contract folders.

The logger tables are written here from a speed plan (rpm, minutes) sampled every 20 s, in the
formats loggers export: CSV with ',' and seconds since start, CSV with ';' and decimal comma and
German timestamps, CSV with a byte-order mark and CRLF line ends, XLSX with date cells. The cut
points the tests expect are derived from the plan, not from the importer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import openpyxl
import pandas as pd
import pytest
import yaml

from pipeline.importers import logger_import
from pipeline.importers.cutting import MIN_SAMPLES, CutRule, segments
from pipeline.importers.logger_table import TableError, read_logger_table
from pipeline.importers.mapping import MappingError, load_mapping
from pipeline.io.reader import read_campaign
from pipeline.io.tables import ingest
from pipeline.separation.runs import RunSettings, build_runs, candidate_links, spans_from_tables
from pipeline.validation.checks import validate_tables
from tests.helpers.repo_params import alignment_gap_s, validation_limits

REPO = Path(__file__).resolve().parents[1]
INTERVAL_S = 20.0
START = pd.Timestamp("2024-03-04T07:00:00")
# (rpm, minutes): three speed cycles; the 3-min stop inside cycle 2 is a tool change
PLAN = [(4000, 60), (0, 30), (6000, 45), (0, 3), (6000, 15), (0, 30), (2000, 40), (0, 20)]
MIN_STOP_MIN = 10.0

MAPPING = {
    "table": {"delimiter": ",", "decimal": "."},
    "time": {"column": "time_s", "unit": "s", "start": "2024-03-04T07:00:00"},
    "speed": {"column": "rpm"},
    "probes": {
        "ch1": {"axis": "Z", "unit": "um", "probe": "eddy_current"},
        "ch2": {"axis": "X", "unit": "mm", "probe": "eddy_current", "location": "spindle nose"},
    },
    "temperatures": {
        "t1": {"sensor": "T1", "role": "spindle_front_bearing", "type": "DS18B20"},
        "t2": {"sensor": "T2", "role": "spindle_motor"},
        "t3": {"sensor": "T3", "location": "column, left"},
        "t4": {"sensor": "T4", "role": "ambient", "unit": "degF"},
    },
    "ignore_columns": ["ch3", "t5"],
    "campaign": {"machine": "vmc-450", "id_prefix": "L", "split": "train", "start_state": "cold"},
    "cut": {"rule": "speed_cycles", "min_stop_min": MIN_STOP_MIN},
}


def logger_frame() -> pd.DataFrame:
    """The logger's record in its own names: time_s, rpm, ch1-ch3 (ch2 in mm), t1-t5 (t4 degF)."""
    rpm = np.concatenate([np.full(int(m * 60 / INTERVAL_S), r, float) for r, m in PLAN])
    t = np.arange(rpm.size) * INTERVAL_S
    heat = np.cumsum(rpm) * INTERVAL_S / 4000.0 / 3600.0  # rpm-hours / 4000
    ambient = 20.0 + 0.8 * np.sin(2 * np.pi * t / 14400.0)
    return pd.DataFrame(
        {
            "time_s": t,
            "rpm": rpm,
            "ch1": np.round(-4.0 * heat + 0.5 * np.sin(t / 900.0), 3),
            "ch2": np.round(0.001 * (1.5 * heat + np.cos(t / 1200.0)), 6),
            "ch3": np.round(np.sin(t / 700.0), 3),
            "t1": np.round(ambient + 3.0 * heat + 0.2 * np.sin(t / 500.0), 2),
            "t2": np.round(ambient + 4.5 * heat + 0.3 * np.cos(t / 600.0), 2),
            "t3": np.round(ambient + 0.5 * heat, 2),
            "t4": np.round(ambient * 9.0 / 5.0 + 32.0, 2),
            "t5": np.round(ambient + 0.1, 2),
        }
    )


def expected_cuts_s(rule: str, min_stop_min: float = MIN_STOP_MIN) -> list[float]:
    """Start times (s) of the campaigns after the first one, from PLAN."""
    ends = np.cumsum([m * 60.0 for _, m in PLAN])
    begins = ends - [m * 60.0 for _, m in PLAN]
    cuts = []
    for k, (rpm, minutes) in enumerate(PLAN):
        if rpm == 0 and minutes >= min_stop_min:
            if rule == "stops":
                cuts.append(begins[k])
            elif k + 1 < len(PLAN):  # speed_cycles: the next start
                cuts.append(ends[k])
    return [float(c) for c in cuts]


def write_mapping(folder: Path, **changes) -> Path:
    content = yaml.safe_load(yaml.safe_dump(MAPPING))
    for dotted, value in changes.items():
        *parents, key = dotted.split("__")
        node = content
        for parent in parents:
            node = node.setdefault(parent, {})
        if value is None:
            node.pop(key, None)
        else:
            node[key] = value
    path = folder / "mapping.yaml"
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    return path


def write_comma_csv(folder: Path, frame: pd.DataFrame | None = None) -> Path:
    path = folder / "logger.csv"
    (logger_frame() if frame is None else frame).to_csv(path, index=False)
    return path


def german(frame: pd.DataFrame) -> pd.DataFrame:
    """Timestamps 04.03.2024 07:00:00 and decimal commas, as text."""
    out = frame.drop(columns="time_s").map(lambda v: f"{v:g}".replace(".", ","))
    stamps = START + pd.to_timedelta(frame["time_s"], unit="s")
    out.insert(0, "Zeit", stamps.dt.strftime("%d.%m.%Y %H:%M:%S"))
    return out


def write_semicolon_csv(folder: Path) -> tuple[Path, Path]:
    path = folder / "logger_de.csv"
    german(logger_frame()).to_csv(path, sep=";", index=False)
    mapping = write_mapping(
        folder,
        table__delimiter=";",
        table__decimal=",",
        time={"column": "Zeit", "unit": "timestamp", "format": "%d.%m.%Y %H:%M:%S"},
    )
    return path, mapping


def write_bom_crlf_csv(folder: Path) -> tuple[Path, Path]:
    path = folder / "logger_bom.csv"
    text = logger_frame().to_csv(index=False, lineterminator="\r\n")
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    return path, write_mapping(folder)


def write_xlsx(folder: Path) -> tuple[Path, Path]:
    frame = logger_frame()
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "Messung"
    sheet.append(["Datum/Zeit", *frame.columns[1:]])
    for row in frame.itertuples(index=False):
        stamp = (START + pd.Timedelta(seconds=row.time_s)).to_pydatetime()
        sheet.append([stamp, *[float(v) for v in row[1:]]])
    path = folder / "logger.xlsx"
    book.save(path)
    mapping = write_mapping(
        folder, table={"sheet": "Messung"}, time={"column": "Datum/Zeit", "unit": "timestamp"}
    )
    return path, mapping


def run_import(table: Path, mapping: Path, out: Path, *flags: str) -> int:
    return logger_import.main([str(table), "--mapping", str(mapping), "--out", str(out), *flags])


def campaign_ids(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir() if p.is_dir())


def ingest_and_validate(out: Path):
    tables = ingest(out, alignment_gap_s())
    limits = validation_limits()
    result = validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )
    return tables, result


def first_samples_s(out: Path) -> list[float]:
    """Each campaign's first sample as seconds since START (from campaign.yaml start)."""
    starts = []
    for cid in campaign_ids(out):
        meta = yaml.safe_load((out / cid / "campaign.yaml").read_text())
        starts.append((pd.Timestamp(meta["start"]) - START).total_seconds())
    return starts


# ----------------------------------------------------------------------------- round trip


def test_comma_csv_round_trip_reads_validates_and_keeps_values(tmp_path):
    table, out = write_comma_csv(tmp_path), tmp_path / "raw"
    assert run_import(table, write_mapping(tmp_path), out) == 0
    ids = campaign_ids(out)
    assert len(ids) == len(expected_cuts_s("speed_cycles")) + 1

    for cid in ids:
        raw = read_campaign(out / cid, max_alignment_gap_s=200.0)
        assert raw.problems == [], raw.problems
    tables, result = ingest_and_validate(out)
    assert tables["problems"].empty
    assert result.problems == (), [p.to_dict() for p in result.problems]

    source = logger_frame()
    samples = tables["samples"]
    starts = first_samples_s(out)
    absolute = samples["elapsed_s"] + samples["campaign_id"].map(
        dict(zip(ids, starts, strict=True))
    )
    np.testing.assert_allclose(absolute, source["time_s"])  # every sample once, in order
    assert (samples.groupby("campaign_id")["elapsed_s"].min() == 0.0).all()
    for sensor, column in (("T1", "t1"), ("T2", "t2"), ("T3", "t3")):
        np.testing.assert_allclose(samples[sensor], source[column], rtol=0, atol=1e-9)
    np.testing.assert_allclose(samples["T4"], (source["t4"] - 32.0) * 5.0 / 9.0, atol=1e-8)
    np.testing.assert_allclose(samples["disp_Z"], source["ch1"], atol=1e-9)
    np.testing.assert_allclose(samples["disp_X"], source["ch2"] * 1000.0, atol=1e-7)
    np.testing.assert_allclose(samples["rpm"], source["rpm"])
    assert "T5" not in samples.columns and "disp_ch3" not in samples.columns


def test_campaign_yaml_carries_mapping_metadata_and_source(tmp_path):
    table, out = write_comma_csv(tmp_path), tmp_path / "raw"
    run_import(table, write_mapping(tmp_path), out)
    meta = yaml.safe_load((out / "L01" / "campaign.yaml").read_text())
    assert meta["campaign_id"] == "L01" and meta["kind"] == "spindle_drift"
    assert meta["synthetic"] is False and meta["split"] == "train"
    assert meta["machine"] == "vmc-450"
    assert pd.Timestamp(meta["start"]) == START
    assert meta["sensors"]["T1"] == {"role": "spindle_front_bearing", "type": "DS18B20"}
    assert meta["sensors"]["T3"] == {"role": "other", "location": "column, left"}
    assert meta["sensors"]["T4"]["role"] == "ambient"
    assert meta["displacement"] == {
        "Z": {"probe": "eddy_current"},
        "X": {"probe": "eddy_current", "location": "spindle nose"},
    }
    assert "logger.csv" in meta["notes"] and "speed_cycles" in meta["notes"]
    assert "season" not in meta  # derived by the pipeline from start
    spindle = pd.read_csv(out / "L01" / "spindle.csv")
    assert list(spindle.columns) == ["elapsed_s", "rpm"]


@pytest.mark.parametrize("writer", [write_semicolon_csv, write_bom_crlf_csv, write_xlsx])
def test_other_formats_give_the_same_campaigns(tmp_path, writer):
    reference = tmp_path / "reference"
    run_import(write_comma_csv(tmp_path), write_mapping(tmp_path), reference)
    table, mapping = writer(tmp_path)
    out = tmp_path / "raw"
    assert run_import(table, mapping, out) == 0
    assert campaign_ids(out) == campaign_ids(reference)
    assert first_samples_s(out) == pytest.approx(first_samples_s(reference))
    for cid in campaign_ids(out):
        for name in ("temperature.csv", "displacement.csv", "spindle.csv"):
            pd.testing.assert_frame_equal(
                pd.read_csv(out / cid / name), pd.read_csv(reference / cid / name), atol=1e-9
            )
    _, result = ingest_and_validate(out)
    assert result.problems == ()


def test_input_table_is_byte_identical_after_import(tmp_path):
    for writer in (write_semicolon_csv, write_xlsx):
        table, mapping = writer(tmp_path)
        before = table.read_bytes()
        assert run_import(table, mapping, tmp_path / table.stem) == 0
        assert table.read_bytes() == before


# ----------------------------------------------------------------------------- cut rules


@pytest.mark.parametrize(
    "flags, expected",
    [
        ((), expected_cuts_s("speed_cycles")),
        (("--min-stop-min", "2"), expected_cuts_s("speed_cycles", 2.0)),
        (("--cut", "stops"), expected_cuts_s("stops")),
        # the record lasts 243 min: the last 3 min (9 samples) are too few for a campaign
        (("--cut", "fixed", "--window-h", "1"), [3600.0, 7200.0, 10800.0]),
    ],
)
def test_cut_points_are_where_the_rule_says(tmp_path, flags, expected):
    out = tmp_path / "raw"
    assert run_import(write_comma_csv(tmp_path), write_mapping(tmp_path), out, *flags) == 0
    assert first_samples_s(out) == pytest.approx([0.0, *expected])


def test_speed_cycle_campaigns_start_running_and_end_stopped(tmp_path):
    out = tmp_path / "raw"
    run_import(write_comma_csv(tmp_path), write_mapping(tmp_path), out)
    for cid in campaign_ids(out):
        rpm = pd.read_csv(out / cid / "spindle.csv")["rpm"]
        assert rpm.iloc[0] > 0 and rpm.iloc[-1] == 0


def test_cut_rule_from_mapping_and_flags_win(tmp_path):
    table = write_comma_csv(tmp_path)
    mapping = write_mapping(tmp_path, cut={"rule": "fixed", "window_h": 2})
    run_import(table, mapping, tmp_path / "a")
    assert first_samples_s(tmp_path / "a") == pytest.approx([0.0, 7200.0])  # 3 min left: kept
    run_import(table, mapping, tmp_path / "b", "--cut", "speed_cycles")
    assert first_samples_s(tmp_path / "b") == pytest.approx([0.0, *expected_cuts_s("speed_cycles")])


def test_leading_stop_stays_in_the_first_speed_cycle():
    elapsed = np.arange(30) * 60.0
    rpm = np.array([0.0] * 12 + [3000.0] * 6 + [0.0] * 12)
    parts = segments(elapsed, rpm, CutRule("speed_cycles", min_stop_min=10.0))
    assert [(p.first, p.stop) for p in parts] == [(0, 30)]
    rpm = np.concatenate([rpm, [3000.0] * 12])
    parts = segments(np.arange(42) * 60.0, rpm, CutRule("speed_cycles", min_stop_min=10.0))
    assert [(p.first, p.stop) for p in parts] == [(0, 30), (30, 42)]
    assert parts[1].stopped_before_s == pytest.approx(12 * 60.0)


def test_fixed_rule_without_window_is_a_user_error(tmp_path, capsys):
    code = run_import(
        write_comma_csv(tmp_path), write_mapping(tmp_path), tmp_path / "o", "--cut", "fixed"
    )
    assert code == 2
    assert "window_h" in capsys.readouterr().err


# ----------------------------------------------------------------------------- runs


def runs_of(out: Path):
    tables, result = ingest_and_validate(out)
    assert result.problems == ()
    spans = spans_from_tables(tables["campaigns"], tables["samples"])
    links, notes = candidate_links(spans, RunSettings())  # detection on, as in params.yaml
    return build_runs(spans, links, notes), tables["campaigns"].set_index("campaign_id")


def test_follows_chain_links_the_campaigns_into_one_run(tmp_path):
    out = tmp_path / "raw"
    run_import(write_comma_csv(tmp_path), write_mapping(tmp_path), out)
    ids = campaign_ids(out)
    runs, campaigns = runs_of(out)
    assert campaigns.loc[ids[0], "start_state"] == "cold"
    assert pd.isna(campaigns.loc[ids[0], "follows"])
    for previous, cid in zip(ids, ids[1:], strict=False):
        assert campaigns.loc[cid, "follows"] == previous
        assert campaigns.loc[cid, "start_state"] == "warm"
    assert len(runs) == 1 and runs[0].campaigns == tuple(ids) and runs[0].cold_start
    assert all(link.how == "declared" and link.contiguous for link in runs[0].links)
    assert all(link.gap_s == pytest.approx(INTERVAL_S) for link in runs[0].links)
    np.testing.assert_allclose(runs[0].offsets_s, [0.0, *expected_cuts_s("speed_cycles")])


def test_first_start_state_is_not_written_when_the_mapping_omits_it(tmp_path):
    out = tmp_path / "raw"
    run_import(write_comma_csv(tmp_path), write_mapping(tmp_path, campaign__start_state=None), out)
    meta = yaml.safe_load((out / "L01" / "campaign.yaml").read_text())
    assert "start_state" not in meta and "follows" not in meta


def test_a_long_enough_stop_starts_a_new_cold_run(tmp_path):
    out = tmp_path / "raw"
    # the stops before cycles 2 and 3 last 30 min; 0.4 h = 24 min: both start cold
    run_import(
        write_comma_csv(tmp_path), write_mapping(tmp_path), out, "--cold-after-stop-h", "0.4"
    )
    runs, campaigns = runs_of(out)
    assert [r.campaigns for r in runs] == [(cid,) for cid in campaign_ids(out)]
    assert (campaigns["start_state"] == "cold").all() and campaigns["follows"].isna().all()
    # 0.6 h = 36 min: no stop is that long, all one run again
    run_import(
        write_comma_csv(tmp_path),
        write_mapping(tmp_path),
        tmp_path / "b",
        "--cold-after-stop-h",
        "0.6",
    )
    assert len(runs_of(tmp_path / "b")[0]) == 1


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "changes, key, hint",
    [
        ({"temperatures__t2__role": "motor"}, "temperatures.t2.role", "spindle_motor"),
        ({"probes__ch2__unit": "inch"}, "probes.ch2.unit", "um, mm"),
        ({"probes__ch1__axis": "1Z"}, "probes.ch1.axis", "Z2"),
        ({"campaign__machine": None}, "campaign.machine", "write campaign.machine"),
        ({"time__start": None}, "time.start", "YYYY-MM-DDTHH:MM:SS"),
        ({"time__unit": "hours"}, "time.unit", "s, min, timestamp"),
        ({"table__delimiter": "|"}, "table.delimiter", "one of"),
        ({"campaign__colour": "red"}, "campaign.colour", "use only machine"),
        ({"probe": {"ch1": "Z"}}, "probe", "at the top level"),
        ({"temperatures__t3__role": "ambient"}, "temperatures.t4.role", "at most one"),
        ({"temperatures__t3__sensor": "T1"}, "temperatures.t3.sensor", "own sensor"),
        ({"ignore_columns": ["ch3", "t5", "t1"]}, "ignore_columns", "remove t1"),
        ({"cut__min_stop_min": -1}, "cut.min_stop_min", "at least 0"),
        ({"campaign__season": "monsoon"}, "campaign.season", "winter"),
        ({"cut__rul": "stops"}, "cut.rul", "use only rule, min_stop_min, window_h, stop_rpm"),
        ({"cut__rul": "stops"}, "cut.rul", "did you mean 'rule'?"),
        ({"table__header_row": 1.5}, "table.header_row", "not a whole number"),
        ({"campaign__synthetic": "no"}, "campaign.synthetic", "write campaign.synthetic: false"),
    ],
)
def test_mapping_errors_name_the_file_and_key(tmp_path, changes, key, hint):
    path = write_mapping(tmp_path, **changes)
    with pytest.raises(MappingError) as error:
        load_mapping(path)
    message = str(error.value)
    assert str(path) in message and f"key '{key}'" in message and hint in message


def test_the_documented_example_mapping_is_valid(tmp_path):
    doc = (REPO / "docs" / "import-logger.md").read_text(encoding="utf-8")
    example = doc.split("```yaml\n", 1)[1].split("```", 1)[0]
    path = tmp_path / "example.yaml"
    path.write_text(example, encoding="utf-8")
    mapping = load_mapping(path)
    assert mapping.table.delimiter == ";" and mapping.table.skip_after_header == 1
    assert [p.axis for p in mapping.probes] == ["Z", "X", "Z2"]
    assert mapping.probes[1].factor_um == 1000.0
    assert [s.role for s in mapping.sensors][-1] == "other"


def test_mapping_error_is_exit_code_2_without_traceback(tmp_path, capsys):
    mapping = write_mapping(tmp_path, temperatures__t2__role="motor")
    assert run_import(write_comma_csv(tmp_path), mapping, tmp_path / "raw") == 2
    err = capsys.readouterr().err
    assert "temperatures.t2.role" in err and "Traceback" not in err
    assert not (tmp_path / "raw").exists()


def test_unreadable_yaml_names_the_line(tmp_path):
    path = tmp_path / "mapping.yaml"
    path.write_text("time:\n  column: t\n  unit: [s\nspeed: {column: rpm}\n")
    with pytest.raises(MappingError, match=r"mapping\.yaml cannot be read as YAML at line \d"):
        load_mapping(path)


def test_unmapped_columns_are_an_error_unless_ignored(tmp_path):
    table = write_comma_csv(tmp_path)
    with pytest.raises(TableError, match=r"\['ch3', 't5'\] are neither mapped nor ignored") as e:
        read_logger_table(table, load_mapping(write_mapping(tmp_path, ignore_columns=None)))
    assert "ignore_columns: [ch3, t5]" in str(e.value)
    record = read_logger_table(table, load_mapping(write_mapping(tmp_path)))
    assert list(record.temperatures.columns) == ["T1", "T2", "T3", "T4"]


def test_missing_mapped_column_is_named(tmp_path):
    table = write_comma_csv(tmp_path, logger_frame().drop(columns="t3"))
    with pytest.raises(TableError, match=r"mapped column\(s\) \['t3'\] are not in the header"):
        read_logger_table(table, load_mapping(write_mapping(tmp_path)))


def test_non_numeric_cell_names_row_and_column_and_missing_values_accepts_it(tmp_path):
    frame = logger_frame().astype({"t2": object})
    frame.loc[41, "t2"] = "ERR"  # 0-based index 41 = data row 42 = line 43
    table = write_comma_csv(tmp_path, frame)
    with pytest.raises(TableError, match=r"column 't2', data row 42 \(line 43\): 'ERR' is not a"):
        read_logger_table(table, load_mapping(write_mapping(tmp_path)))
    mapping = load_mapping(write_mapping(tmp_path, table__missing_values=["ERR"]))
    record = read_logger_table(table, mapping)
    assert np.isnan(record.temperatures["T2"].iloc[41])
    assert record.temperatures["T2"].notna().sum() == len(frame) - 1


def test_preamble_and_blank_lines_keep_row_numbers(tmp_path):
    frame = logger_frame().astype({"t1": object})
    frame.loc[9, "t1"] = "n/a"  # data row 10 + 1 blank line before it
    lines = frame.to_csv(index=False).splitlines()
    text = ["Logger XYZ export", "interval: 20 s", *lines[:5], "", "," * 9, *lines[5:]]
    table = tmp_path / "preamble.csv"
    table.write_text("\n".join(text) + "\n")
    mapping = write_mapping(tmp_path, table__header_row=3)
    with pytest.raises(TableError, match=r"column 't1', data row 12 \(line 15\): 'n/a'"):
        read_logger_table(table, load_mapping(mapping))
    mapping = write_mapping(tmp_path, table__header_row=3, table__missing_values=["n/a"])
    record = read_logger_table(table, load_mapping(mapping))
    assert len(record.elapsed_s) == len(frame)
    assert record.data_rows[3:5].tolist() == [4, 7]


def test_short_rows_are_missing_readings(tmp_path):
    frame = logger_frame()
    lines = frame.to_csv(index=False).splitlines()
    lines[4] = lines[4].rsplit(",", 2)[0]  # data row 4 lacks t4 and t5
    table = tmp_path / "short.csv"
    table.write_text("\n".join(lines) + "\n")
    record = read_logger_table(table, load_mapping(write_mapping(tmp_path)))
    assert np.isnan(record.temperatures["T4"].iloc[3])
    assert record.temperatures["T4"].isna().sum() == 1
    assert record.temperatures["T3"].iloc[3] == frame["t3"].iloc[3]


def test_units_row_under_the_header_is_skipped(tmp_path):
    frame = logger_frame()
    lines = frame.to_csv(index=False).splitlines()
    units = ",".join(["s", "rpm", "um", "mm", "um", *["degC"] * 3, "degF", "degC"])
    frame.loc[2, "t3"] = np.nan
    table = tmp_path / "units.csv"
    table.write_text("\n".join([lines[0], units, *frame.to_csv(index=False).splitlines()[1:]]))
    with pytest.raises(TableError, match=r"column 'time_s', data row 1 \(line 2\): 's' is not"):
        read_logger_table(table, load_mapping(write_mapping(tmp_path)))
    mapping = load_mapping(write_mapping(tmp_path, table__skip_after_header=1))
    record = read_logger_table(table, mapping)
    assert len(record.elapsed_s) == len(frame) and record.data_rows[0] == 1
    assert np.isnan(record.temperatures["T3"].iloc[2])
    np.testing.assert_allclose(record.temperatures["T1"], frame["t1"])


def test_decimal_comma_under_a_point_mapping_says_what_to_set(tmp_path):
    path, _ = write_semicolon_csv(tmp_path)
    mapping = write_mapping(
        tmp_path,
        table__delimiter=";",
        time={"column": "Zeit", "unit": "timestamp", "format": "%d.%m.%Y %H:%M:%S"},
    )
    with pytest.raises(TableError, match=r"data row 1 \(line 2\).*set table: decimal: ','"):
        read_logger_table(path, load_mapping(mapping))


def test_times_not_increasing_name_the_row(tmp_path):
    frame = logger_frame()
    frame.loc[100, "time_s"] = frame.loc[99, "time_s"]
    with pytest.raises(TableError, match=r"column 'time_s', data row 101 \(line 102\).*sort"):
        read_logger_table(write_comma_csv(tmp_path, frame), load_mapping(write_mapping(tmp_path)))


def test_bad_timestamp_names_row_and_format(tmp_path):
    path, mapping = write_semicolon_csv(tmp_path)
    text = path.read_text().splitlines()
    text[5] = text[5].replace(".2024 ", "/2024 ", 1)  # line 6 = data row 5
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(text) + "\n")
    with pytest.raises(TableError, match=r"data row 5 \(line 6\).*'%d\.%m\.%Y %H:%M:%S'"):
        read_logger_table(bad, load_mapping(mapping))


def test_timestamps_with_changing_utc_offset_keep_a_continuous_time_base(tmp_path):
    frame = logger_frame().iloc[:10]
    stamps = pd.date_range("2024-03-31T01:58:00", periods=10, freq="20s", tz="Europe/Berlin")
    assert len(set(s.utcoffset() for s in stamps)) == 2  # crosses the DST change
    frame.insert(0, "stamp", [s.isoformat() for s in stamps])
    table = write_comma_csv(tmp_path, frame.drop(columns="time_s"))
    mapping = write_mapping(tmp_path, time={"column": "stamp", "unit": "timestamp"})
    record = read_logger_table(table, load_mapping(mapping))
    np.testing.assert_allclose(np.diff(record.elapsed_s), INTERVAL_S)
    assert record.start == pd.Timestamp("2024-03-31T01:58:00")


def test_existing_folders_are_not_overwritten_without_force(tmp_path, capsys):
    table, mapping, out = write_comma_csv(tmp_path), write_mapping(tmp_path), tmp_path / "raw"
    run_import(table, mapping, out)
    (out / "L02" / "campaign.yaml").write_text("edited by hand\n")
    assert run_import(table, mapping, out) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "L02" / "campaign.yaml").read_text() == "edited by hand\n"
    assert run_import(table, mapping, out, "--force") == 0
    assert yaml.safe_load((out / "L02" / "campaign.yaml").read_text())["campaign_id"] == "L02"


def test_id_prefix_flag_and_summary(tmp_path, capsys):
    out = tmp_path / "raw"
    assert (
        run_import(
            write_comma_csv(tmp_path), write_mapping(tmp_path), out, "--id-prefix", "VMC-D1-"
        )
        == 0
    )
    stdout = capsys.readouterr().out
    ids = campaign_ids(out)
    assert ids[0] == "VMC-D1-01" and all(cid in stdout for cid in ids)
    assert f"{len(ids)} campaign(s)" in stdout and "speed_cycles" in stdout


def test_xlsx_bad_cell_names_the_sheet_row(tmp_path):
    frame = logger_frame().iloc[:20]
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.append(["Logger export, machine vmc-450"])  # title row above the header
    sheet.append(list(frame.columns))
    for row in frame.itertuples(index=False):
        sheet.append([float(v) for v in row])
    sheet.cell(row=9, column=list(frame.columns).index("ch1") + 1, value="over")
    table = tmp_path / "titled.xlsx"
    book.save(table)
    mapping = write_mapping(tmp_path, table__header_row=2)
    with pytest.raises(TableError, match=r"column 'ch1', data row 7 \(sheet row 9\): 'over'"):
        read_logger_table(table, load_mapping(mapping))


def test_xlsx_date_cells_and_a_missing_sheet(tmp_path):
    table, _ = write_xlsx(tmp_path)
    mapping = write_mapping(
        tmp_path, table={"sheet": "Sheet9"}, time={"column": "Datum/Zeit", "unit": "timestamp"}
    )
    with pytest.raises(TableError, match="Sheet9"):
        read_logger_table(table, load_mapping(mapping))


def test_a_cut_never_leaves_fewer_samples_than_validate_needs():
    elapsed = np.arange(100) * 60.0
    rpm = np.where((np.arange(100) // 8) % 2 == 0, 3000.0, 0.0)  # 8 min running, 8 stopped
    parts = segments(elapsed, rpm, CutRule("fixed", window_h=0.1))  # 6-min windows
    assert all(p.stop - p.first >= MIN_SAMPLES for p in parts)
    assert parts[-1].stop == 100 and [p.first for p in parts][0] == 0


def test_cold_after_stop_with_the_stops_rule_is_refused(tmp_path, capsys):
    code = run_import(
        write_comma_csv(tmp_path),
        write_mapping(tmp_path),
        tmp_path / "o",
        "--cut",
        "stops",
        "--cold-after-stop-h",
        "1",
    )
    assert code == 2
    assert "cannot be used with the stops rule" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()

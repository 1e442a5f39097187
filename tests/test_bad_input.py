"""Every class of bad raw input: caught, exactly located, quarantined, raw files untouched.

Each case writes a raw folder with a good spindle campaign (K01), a good axis campaign (A01) and
one bad campaign (B01), runs the real ``ingest`` and ``validate`` stages in a copy laid out like
the repository (``params.yaml``, ``data/raw``), and asserts the failed check and its location
(campaign, file, row, column) in ``reports/validation.json``, that B01 is quarantined while K01
and A01 reach ``data/validated``, that no raw file changed (sha256) and that no traceback was
printed. Cases marked ``SUBPROCESS`` run the ``thermal`` commands as the user does; the others
call the stages' ``main`` in-process (same code, faster).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline import paths
from pipeline.stages import ingest, validate
from pipeline.validation.plausibility import CHECKS as PLAUSIBILITY_CHECKS
from pipeline.validation.texts import FALLBACK_TEXT, PROBLEM_TEXTS
from tests.helpers.raw_builders import write_axis_campaign, write_spindle_campaign
from tests.helpers.raw_edits import (
    drop_column,
    edit_rows,
    edit_yaml,
    map_column,
    read_table,
    replace_text,
    set_cell,
    write_table,
)

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
BAD = "B01"


def spindle(raw: Path, campaign_id: str = BAD, **kwargs) -> Path:
    """A good spindle campaign (realistic: the ambient sensor moves) to corrupt."""
    return write_spindle_campaign(raw, campaign_id, ambient_rise=1.0, seed=1, **kwargs)


def axis(raw: Path, campaign_id: str = BAD) -> Path:
    return write_axis_campaign(raw, campaign_id, seed=1)


def temperature(raw: Path) -> Path:
    return spindle(raw) / "temperature.csv"


def displacement(raw: Path) -> Path:
    return spindle(raw) / "displacement.csv"


def laser(raw: Path) -> Path:
    return axis(raw) / "laser.csv"


def yaml_of(raw: Path, function: Callable[[dict], None]) -> None:
    edit_yaml(spindle(raw) / "campaign.yaml", function)


# --------------------------------------------------------------------------- corruptions


def stuck(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    column = header.index("T1")
    for cells in rows[9:34]:  # rows 10-34: 25 samples, 75 min, while T2 and T3 rise
        cells[column] = rows[9][column]
    write_table(path, header, rows)


def spike(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    set_cell(path, 20, "T2", f"{float(rows[19][header.index('T2')]) + 10:.4f}")


def swap_rows(raw: Path) -> None:
    def swap(rows):
        rows[14], rows[15] = rows[15], rows[14]
        return rows

    edit_rows(temperature(raw), swap)


def duplicate_row(raw: Path) -> None:
    edit_rows(temperature(raw), lambda rows: [*rows[:15], list(rows[14]), *rows[15:]])


def fahrenheit(raw: Path) -> None:
    path = temperature(raw)
    for column in ("T1", "T2", "T3", "T4"):
        map_column(path, column, lambda c: c * 1.8 + 32.0, ".2f")


def millimetres(raw: Path) -> None:
    map_column(displacement(raw), "Z", lambda um: um / 1000.0, ".6f")


def minutes(raw: Path) -> None:
    folder = spindle(raw)
    for name in ("temperature.csv", "displacement.csv"):
        map_column(folder / name, "elapsed_s", lambda s: s / 60.0, "g")


def extra_column(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    write_table(path, [*header, "T9"], [[*cells, "21.5"] for cells in rows])


def semicolons(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    lines = [";".join(header)] + [";".join(c.replace(".", ",") for c in cells) for cells in rows]
    path.write_text("\n".join(lines) + "\n")


def header_only(name: str) -> Callable[[Path], None]:
    def corrupt(raw: Path) -> None:
        path = spindle(raw) / name
        path.write_text(path.read_text().splitlines()[0] + "\n")

    return corrupt


def malformed_yaml(raw: Path) -> None:
    replace_text(spindle(raw) / "campaign.yaml", "kind: spindle_drift", "kind: [spindle_drift")


def missing_key(key: str) -> Callable[[Path], None]:
    return lambda raw: yaml_of(raw, lambda meta: meta.pop(key))


def set_key(key: str, value: object) -> Callable[[Path], None]:
    return lambda raw: yaml_of(raw, lambda meta: meta.__setitem__(key, value))


def unknown_role(raw: Path) -> None:
    yaml_of(raw, lambda meta: meta["sensors"]["T2"].__setitem__("role", "spindle_nose"))


def empty_row(raw: Path) -> None:
    path = temperature(raw)
    header, _ = read_table(path)
    set_cell(path, 20, "elapsed_s", "")
    for column in header[1:]:
        set_cell(path, 20, column, "")


def cell(file: str, row: int, column: str, text: str, build=None) -> Callable[[Path], None]:
    def corrupt(raw: Path) -> None:
        folder = (build or spindle)(raw)
        set_cell(folder / file, row, column, text)

    return corrupt


def one_row(raw: Path) -> None:
    spindle(raw, n=1)


def no_yaml(raw: Path) -> None:
    (spindle(raw) / "campaign.yaml").unlink()


def random_bytes(raw: Path) -> None:
    temperature(raw).write_bytes(np.random.default_rng(3).bytes(4096))


def zip_file(raw: Path) -> None:
    path = temperature(raw)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("temperature.csv", path.read_text())
    path.write_bytes(buffer.getvalue())


def empty_direction(raw: Path) -> None:
    path = laser(raw)
    for row in (7, 8):
        set_cell(path, row, "direction", "")


def one_direction_pass(raw: Path) -> None:
    edit_rows(laser(raw), lambda rows: [cells for cells in rows if cells[1] != "4"])


def yaml_list(raw: Path) -> None:
    (spindle(raw) / "campaign.yaml").write_text("- campaign_id: B01\n- kind: spindle_drift\n")


def reserved_rpm(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    write_table(path, [*header, "rpm"], [[*cells, "4000"] for cells in rows])


def extra_cell(raw: Path) -> None:
    edit_rows(temperature(raw), lambda rows: [*rows[:9], [*rows[9], "1.0"], *rows[10:]])


def duplicate_column(raw: Path) -> None:
    path = temperature(raw)
    header, rows = read_table(path)
    write_table(path, [*header, "T2"], [[*cells, cells[2]] for cells in rows])


def latin1(raw: Path) -> None:
    path = temperature(raw)
    path.write_bytes(path.read_text().replace("T1", "T1 (°C)", 1).encode("latin-1"))


def mixed_axis_keys(raw: Path) -> None:
    yaml_of(raw, lambda meta: meta["displacement"].__setitem__(1, {"probe": "eddy_current"}))


def axis_as_text(raw: Path) -> None:
    edit_yaml(axis(raw) / "campaign.yaml", lambda meta: meta.__setitem__("axis", "Y"))


def sensor_named_rpm(raw: Path) -> None:
    yaml_of(raw, lambda meta: meta["sensors"].__setitem__("rpm", {"role": "other"}))


def spindle_log(content: bytes) -> Callable[[Path], None]:
    return lambda raw: (spindle(raw) / "spindle.csv").write_bytes(content)


# --------------------------------------------------------------------------- the corpus


@dataclass(frozen=True)
class Case:
    """One bad input: how to write it and the problem expected (check, file, row, column)."""

    name: str
    corrupt: Callable[[Path], None]
    check: str
    file: str
    row: int | None
    column: str | None
    subprocess: bool = False


T, D, L, Y = "temperature.csv", "displacement.csv", "laser.csv", "campaign.yaml"
CASES = [
    Case("01_ds18b20_85", cell(T, 12, "T2", "85.0000"), "ds18b20_power_on", T, 12, "T2"),
    Case("02_ds18b20_-127", cell(T, 12, "T2", "-127.0000"), "ds18b20_disconnected", T, 12, "T2"),
    Case("03_stuck_sensor", stuck, "stuck_sensor", T, 10, "T1"),
    Case("04_spike", spike, "spike", T, 20, "T2"),
    Case("05_time_not_monotonic", swap_rows, "time_increasing", T, 16, "elapsed_s"),
    Case("06_time_duplicated", duplicate_row, "time_increasing", T, 16, "elapsed_s"),
    Case("07_fahrenheit", fahrenheit, "temperature_unit", T, None, "T4"),
    Case("08_displacement_in_mm", millimetres, "displacement_unit", D, None, "Z"),
    Case("09_time_in_minutes", minutes, "time_unit", T, None, "elapsed_s"),
    Case(
        "10_sensor_column_missing",
        lambda raw: drop_column(temperature(raw), "T2"),
        "sensor_column_missing",
        T,
        None,
        "T2",
    ),
    Case("11_unknown_column", extra_column, "unknown_temperature_column", T, None, "T9"),
    Case("12_semicolons", semicolons, "semicolon_separated", T, None, None, subprocess=True),
    Case(
        "13_empty_file", lambda raw: temperature(raw).write_bytes(b""), "empty_file", T, None, None
    ),
    Case("14_header_only", header_only(T), "no_data_rows", T, None, None),
    Case("14_header_only_displacement", header_only(D), "no_data_rows", D, None, None),
    Case("15_malformed_yaml", malformed_yaml, "unreadable_yaml", Y, 2, None, subprocess=True),
    Case("16_missing_kind", missing_key("kind"), "missing_key", Y, None, "kind"),
    Case("16_missing_start", missing_key("start"), "missing_key", Y, None, "start"),
    Case("16_missing_sensors", missing_key("sensors"), "missing_key", Y, None, "sensors"),
    Case(
        "17_campaign_id_path",
        set_key("campaign_id", "../x"),
        "campaign_id_unsafe",
        Y,
        None,
        "campaign_id",
    ),
    Case(
        "18_campaign_id_other",
        set_key("campaign_id", "B02"),
        "campaign_id_mismatch",
        Y,
        None,
        "campaign_id",
    ),
    Case("19_unknown_role", unknown_role, "sensor_role_known", Y, None, "sensors.T2.role"),
    Case("20_empty_row", empty_row, "missing_value", T, 20, "elapsed_s"),
    Case("20_empty_time", cell(T, 20, "elapsed_s", ""), "missing_value", T, 20, "elapsed_s"),
    Case(
        "21_inf_temperature", cell(T, 12, "T2", "inf"), "not_finite", T, 12, "T2", subprocess=True
    ),
    Case("21_inf_displacement", cell(D, 12, "Z", "-inf"), "not_finite", D, 12, "Z"),
    Case(
        "21_inf_laser", cell(L, 3, "deviation_um", "inf", axis), "not_finite", L, 3, "deviation_um"
    ),
    Case("22_huge_temperature", cell(T, 12, "T2", "1e308"), "temperature_range", T, 12, "T2"),
    Case("22_huge_displacement", cell(D, 12, "Z", "1e308"), "displacement_range", D, 12, "Z"),
    Case(
        "22_huge_laser",
        cell(L, 3, "deviation_um", "1e308", axis),
        "laser_deviation_range",
        L,
        3,
        "deviation_um",
    ),
    Case("23_text_in_number", cell(T, 12, "T2", "ERR"), "not_a_number", T, 12, "T2"),
    Case("24_one_row", one_row, "too_few_samples", T, None, None),
    Case("25_no_campaign_yaml", no_yaml, "missing_file", Y, None, None),
    Case("26_random_bytes", random_bytes, "binary_file", T, None, None, subprocess=True),
    Case("26_zip_as_csv", zip_file, "binary_file", T, None, None),
    Case("27_laser_direction_empty", empty_direction, "missing_value", L, 7, "direction"),
    Case(
        "27_laser_deviation_empty",
        cell(L, 3, "deviation_um", "", axis),
        "missing_value",
        L,
        3,
        "deviation_um",
    ),
    Case(
        "27_laser_pass_one_direction", one_direction_pass, "laser_bidirectional", L, 11, "direction"
    ),
    Case("28_laser_run_empty", cell(L, 3, "run", "", axis), "laser_run_number", L, 3, "run"),
    Case("28_laser_run_fraction", cell(L, 3, "run", "2.5", axis), "laser_run_number", L, 3, "run"),
    Case(
        "28_laser_run_of_other_pass",
        cell(L, 3, "run", "5", axis),
        "laser_run_one_time",
        L,
        3,
        "elapsed_min",
    ),
    # shapes that used to raise inside ingest
    Case("yaml_is_a_list", yaml_list, "unreadable_yaml", Y, None, None),
    Case("sensors_as_list", set_key("sensors", ["T1", "T2"]), "wrong_type", Y, None, "sensors"),
    Case(
        "spindle_program_number",
        set_key("spindle_program", 5),
        "wrong_type",
        Y,
        None,
        "spindle_program",
    ),
    Case("axis_as_text", axis_as_text, "wrong_type", Y, None, "axis"),
    Case("misspelt_follows", set_key("follow", "A01"), "misspelt_key", Y, None, "follow"),
    Case("synthetic_as_text", set_key("synthetic", "maybe"), "wrong_type", Y, None, "synthetic"),
    Case("mixed_key_types", mixed_axis_keys, "displacement_axis_known", Y, None, "displacement"),
    Case("reserved_rpm_column", reserved_rpm, "reserved_column", T, None, "rpm", subprocess=True),
    Case("row_with_extra_cell", extra_cell, "field_count", T, 10, None),
    Case("column_twice", duplicate_column, "duplicate_column", T, None, "T2"),
    Case("latin1_text", latin1, "not_utf8", T, None, None),
    Case(
        "bom_and_nothing_else",
        lambda raw: temperature(raw).write_bytes(b"\xef\xbb\xbf"),
        "empty_file",
        T,
        None,
        None,
    ),
    Case("sensor_named_rpm", sensor_named_rpm, "reserved_column", Y, None, "sensors.rpm"),
    Case(
        "spindle_log_binary", spindle_log(b"\x00\x01\x02"), "binary_file", "spindle.csv", None, None
    ),
    Case(
        "spindle_log_without_rpm",
        spindle_log(b"elapsed_s,speed\n0,4000\n"),
        "missing_column",
        "spindle.csv",
        None,
        "rpm",
    ),
    Case(
        "spindle_program_nan_rpm",
        set_key("spindle_program", [{"from_min": 0, "rpm": np.nan}]),
        "bad_spindle_program",
        Y,
        None,
        "spindle_program",
    ),
    Case("laser_run_inf", cell(L, 2, "run", "inf", axis), "laser_run_number", L, 2, "run"),
    Case(
        "displacement_time_empty", cell(D, 5, "elapsed_s", ""), "missing_value", D, 5, "elapsed_s"
    ),
]


# --------------------------------------------------------------------------- running the stages


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """A folder laid out like the repository: params.yaml and data/raw with K01 and A01."""
    shutil.copy(REPO / "params.yaml", tmp_path / "params.yaml")
    raw = tmp_path / paths.RAW
    raw.mkdir(parents=True)
    spindle(raw, "K01")
    axis(raw, "A01")
    return tmp_path


def raw_hashes(root: Path) -> dict[str, str]:
    raw = root / paths.RAW
    return {
        str(p.relative_to(raw)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(raw.rglob("*"))
        if p.is_file()
    }


def thermal(root: Path, command: str) -> subprocess.CompletedProcess:
    """Run ``thermal <command>`` in ``root`` with the virtual environment's bin on PATH."""
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run(
        ["thermal", command], cwd=root, env=env, capture_output=True, text=True, timeout=300
    )


def run_stages(root: Path, monkeypatch, as_subprocess: bool) -> dict:
    """Run ingest then validate in ``root``; return reports/validation.json."""
    if as_subprocess:
        for command in ("ingest", "validate"):
            done = thermal(root, command)
            assert "Traceback" not in done.stderr, done.stderr
            assert done.returncode == 0, done.stderr
    else:
        monkeypatch.chdir(root)
        assert ingest.main([]) == 0
        assert validate.main([]) == 0
    return json.loads((root / paths.VALIDATION_REPORT).read_text())


def validated_ids(root: Path) -> set[str]:
    ids: set[str] = set()
    for folder in (paths.VALIDATED_SPINDLE, paths.VALIDATED_AXIS):
        ids |= set(pd.read_parquet(root / folder / paths.CAMPAIGNS_FILE)["campaign_id"])
    return ids


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_is_located_and_quarantined(case: Case, workdir: Path, monkeypatch):
    case.corrupt(workdir / paths.RAW)
    before = raw_hashes(workdir)
    report = run_stages(workdir, monkeypatch, case.subprocess)

    assert raw_hashes(workdir) == before
    located = [
        p
        for p in report["problems"]
        if (p["campaign"], p["check"], p["file"], p["row"], p["column"])
        == (BAD, case.check, case.file, case.row, case.column)
    ]
    assert located, json.dumps(report["problems"], indent=1)
    problem = located[0]
    assert problem["message"] and problem["action"]
    assert "failed the check" in FALLBACK_TEXT.message
    assert "failed the check" not in problem["message"]
    assert problem["line"] == (
        None if case.row is None else case.row + (0 if case.file.endswith(".yaml") else 1)
    )
    assert report["summary"]["quarantined"] == [BAD]
    assert set(report["summary"]["valid"]) == {"A01", "K01"}
    assert validated_ids(workdir) == {"A01", "K01"}


def _excel_export(source: Path, target: Path, campaign_id: str) -> None:
    """Copy a campaign folder as Excel writes it: UTF-8 BOM and CRLF line endings."""
    target.mkdir()
    for path in source.iterdir():
        text = path.read_text().replace(
            f"campaign_id: {source.name}", f"campaign_id: {campaign_id}"
        )
        target.joinpath(path.name).write_bytes(
            b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode()
        )


def test_29_excel_exports_with_bom_and_crlf_are_accepted(workdir: Path):
    raw = workdir / paths.RAW
    _excel_export(raw / "K01", raw / "K02", "K02")
    _excel_export(raw / "A01", raw / "A02", "A02")
    before = raw_hashes(workdir)
    report = run_stages(workdir, None, as_subprocess=True)

    assert raw_hashes(workdir) == before
    assert report["problems"] == [] and report["summary"]["quarantined"] == []
    for kind, plain, excel in (("spindle", "K01", "K02"), ("axis", "A01", "A02")):
        folder = workdir / paths.VALIDATED / kind
        for name in (paths.SAMPLES_FILE, *([paths.LASER_FILE] if kind == "axis" else [])):
            table = pd.read_parquet(folder / name)
            one = table.loc[table["campaign_id"] == plain].drop(columns="campaign_id")
            other = table.loc[table["campaign_id"] == excel].drop(columns="campaign_id")
            assert len(one) > 0
            pd.testing.assert_frame_equal(one.reset_index(drop=True), other.reset_index(drop=True))


def _warnings(report: dict, column: str) -> list[dict]:
    return [w for w in report["warnings"] if (w["campaign"], w["column"]) == (BAD, column)]


def _validated(root: Path) -> pd.DataFrame:
    samples = pd.read_parquet(root / paths.VALIDATED_SPINDLE / paths.SAMPLES_FILE)
    return samples.loc[samples["campaign_id"] == BAD].set_index("source_row")


def _between(path: Path, column: str, before: int, after: int, row: int) -> float:
    """The linear interpolation in elapsed_s of ``column`` at ``row`` from two rows of a CSV."""
    header, rows = read_table(path)
    t, x = header.index("elapsed_s"), header.index(column)
    times = [float(rows[r - 1][t]) for r in (before, after)]
    values = [float(rows[r - 1][x]) for r in (before, after)]
    return float(np.interp(float(rows[row - 1][t]), times, values))


def test_an_empty_cell_is_a_located_warning_bridged_in_the_validated_data(workdir, monkeypatch):
    """The contract: an empty temperature or displacement cell is a missing reading."""
    folder = spindle(workdir / paths.RAW)
    for row in (5, 6):  # two missing samples at 180 s: 540 s between the readings around them
        set_cell(folder / "temperature.csv", row, "T2", "")
    set_cell(folder / "displacement.csv", 9, "Z", "")
    before = raw_hashes(workdir)
    report = run_stages(workdir, monkeypatch, as_subprocess=False)

    assert raw_hashes(workdir) == before
    assert report["problems"] == [] and BAD in report["summary"]["valid"]
    [t2] = _warnings(report, "T2")
    assert (t2["file"], t2["row"], t2["line"], t2["rows"]) == ("temperature.csv", 5, 6, [5, 6])
    assert t2["handling"] == "bridged" and t2["gap_s"] == 540.0
    assert "B01/temperature.csv rows 5-6" in t2["message"]
    assert "bridged by linear interpolation in time between rows 4 and 7" in t2["message"]
    [z] = _warnings(report, "Z")
    assert (z["file"], z["row"], z["handling"]) == ("displacement.csv", 9, "bridged")
    bad = _validated(workdir)
    assert bad[["T2", "disp_Z"]].notna().all().all()
    for row in (5, 6):
        expected = _between(folder / "temperature.csv", "T2", 4, 7, row)
        assert bad.loc[row, "T2"] == pytest.approx(expected)
    expected = _between(folder / "displacement.csv", "Z", 8, 10, 9)
    assert bad.loc[9, "disp_Z"] == pytest.approx(expected)


@pytest.mark.parametrize("limit_s", [600.0, 900.0])
def test_a_gap_longer_than_the_limit_drops_its_samples(workdir, monkeypatch, limit_s):
    """Four missing samples at 180 s span 900 s: dropped under 600 s, bridged under 900 s."""
    params = workdir / "params.yaml"
    replace_text(params, "max_bridged_gap_s: 600.0", f"max_bridged_gap_s: {limit_s}")
    folder = spindle(workdir / paths.RAW)
    for row in (10, 11, 12, 13):
        set_cell(folder / "temperature.csv", row, "T1", "")
    set_cell(folder / "temperature.csv", 1, "T3", "")  # nothing before it to interpolate from
    report = run_stages(workdir, monkeypatch, as_subprocess=False)

    assert report["problems"] == []
    [gap] = _warnings(report, "T1")
    assert gap["rows"] == [10, 11, 12, 13] and gap["gap_s"] == 900.0
    [first] = _warnings(report, "T3")
    assert (first["row"], first["handling"], first["samples"]) == (1, "dropped", [1])
    assert "start of its record" in first["message"]
    kept = set(_validated(workdir).index)
    if limit_s < 900.0:
        assert gap["handling"] == "dropped" and gap["samples"] == [10, 11, 12, 13]
        assert f"longer than validate.max_bridged_gap_s = {limit_s:g} s" in gap["message"]
        assert kept == set(range(2, 41)) - {10, 11, 12, 13}
    else:
        assert gap["handling"] == "bridged" and "between rows 9 and 14" in gap["message"]
        assert kept == set(range(2, 41))


def _machines_workdir(workdir: Path, machine: str | None) -> None:
    """Add campaign B01 of ``machine`` (None: no machine: key) beside K01 and A01 of 'test'."""
    raw = workdir / paths.RAW
    if machine is None:
        yaml_of(raw, lambda meta: meta.pop("machine"))
    else:
        yaml_of(raw, lambda meta: meta.__setitem__("machine", machine))


def test_campaigns_of_two_machines_are_validated_each_of_its_machine(workdir, monkeypatch):
    _machines_workdir(workdir, "FL_THERMAL")
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    assert report["problems"] == []
    assert set(report["summary"]["valid"]) == {"A01", "B01", "K01"}
    campaigns = pd.read_parquet(workdir / paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    assert dict(zip(campaigns["campaign_id"], campaigns["machine"], strict=True)) == {
        "B01": "FL_THERMAL",
        "K01": "test",
    }


def test_a_campaign_without_machine_is_not_a_second_machine(workdir, monkeypatch):
    _machines_workdir(workdir, None)
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    assert set(report["summary"]["valid"]) == {"A01", "B01", "K01"}
    campaigns = pd.read_parquet(workdir / paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    assert set(campaigns["machine"]) == {"test"}  # the folder's one machine


def _only_problem(workdir: Path, monkeypatch) -> tuple[dict, dict]:
    """Run the stages; return the report and its one problem."""
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    [problem] = report["problems"]
    return report, problem


def test_with_two_machines_a_campaign_without_one_is_quarantined(workdir, monkeypatch):
    _machines_workdir(workdir, None)
    edit_yaml(workdir / paths.RAW / "A01" / "campaign.yaml", lambda m: m.update(machine="lathe"))
    report, problem = _only_problem(workdir, monkeypatch)
    assert (problem["campaign"], problem["check"], problem["column"]) == (
        "B01",
        "machine_unknown",
        "machine",
    )
    assert "'lathe', 'test'" in problem["message"] and "write machine:" in problem["action"]
    assert set(report["summary"]["valid"]) == {"A01", "K01"}


def test_a_campaign_following_one_of_another_machine_is_quarantined(workdir, monkeypatch):
    yaml_of(workdir / paths.RAW, lambda meta: meta.update(machine="FL_THERMAL", follows="K01"))
    _, problem = _only_problem(workdir, monkeypatch)
    assert (problem["campaign"], problem["check"], problem["column"]) == (
        "B01",
        "follows_other_machine",
        "follows",
    )
    assert "machine FL_THERMAL" in problem["message"] and "machine test" in problem["message"]


def test_yaml_dates_and_non_text_values_are_read(workdir: Path, monkeypatch):
    """Values YAML reads as dates or numbers inside mappings do not break ingest."""

    def add_dates(meta: dict) -> None:
        meta["displacement"]["Z"]["calibrated"] = pd.Timestamp("2015-01-01").date()
        meta["sensors"]["T1"]["location"] = 12

    yaml_of(workdir / paths.RAW, add_dates)
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    assert report["problems"] == []


def test_every_plausibility_check_has_a_text():
    # ingest's checks are covered by each case: their texts are never the fallback
    assert set(PLAUSIBILITY_CHECKS) - set(PROBLEM_TEXTS) == set()


def test_a_missing_raw_folder_is_a_message_not_a_traceback(tmp_path: Path):
    shutil.copy(REPO / "params.yaml", tmp_path / "params.yaml")
    done = thermal(tmp_path, "ingest")
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert "data/raw does not exist" in done.stderr and "thermal simulate" in done.stderr


def test_a_folder_of_bad_campaigns_only_fails_validate_with_a_message(tmp_path: Path):
    shutil.copy(REPO / "params.yaml", tmp_path / "params.yaml")
    random_bytes(tmp_path / paths.RAW)
    runs = [thermal(tmp_path, command) for command in ("ingest", "validate")]
    assert [r.returncode for r in runs] == [0, 1]
    assert all("Traceback" not in r.stderr for r in runs)
    assert "no valid campaign" in runs[1].stderr and "B01" in runs[1].stderr
    report = json.loads((tmp_path / paths.VALIDATION_REPORT).read_text())
    assert report["summary"] == {
        "campaigns": 1,
        "valid": [],
        "quarantined": [BAD],
        "machines": {BAD: "test"},
    }


def test_a_quiet_probe_beside_a_drifting_one_is_not_taken_for_millimetres(workdir, monkeypatch):
    """An X probe on a symmetric spindle barely moves while Z drifts: that is normal data."""
    folder = spindle(workdir / paths.RAW)
    path = folder / "displacement.csv"
    header, rows = read_table(path)
    quiet = np.random.default_rng(5).normal(0.0, 0.03, len(rows))
    rows = [[*cells, f"{x:.3f}"] for cells, x in zip(rows, quiet, strict=True)]
    write_table(path, [*header, "X"], rows)
    edit_yaml(folder / "campaign.yaml", lambda meta: meta["displacement"].__setitem__("X", {}))
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    assert report["problems"] == [] and report["summary"]["quarantined"] == []


def test_an_axis_campaign_with_a_temperature_row_per_pass_is_not_too_short(workdir, monkeypatch):
    """docs/import-rtl.md leaves temperature.csv to the user: one row per laser pass is enough."""
    raw = workdir / paths.RAW
    write_axis_campaign(raw, "A02", n=3, interval_s=7200.0, passes_min=(0.0, 120.0, 240.0))
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    assert "A02" in report["summary"]["valid"], report["problems"]


def test_a_csv_of_blank_cells_only_is_an_empty_file(workdir, monkeypatch):
    temperature(workdir / paths.RAW).write_text('""\n" "\n')
    report = run_stages(workdir, monkeypatch, as_subprocess=False)
    checks = {(p["campaign"], p["check"], p["file"]) for p in report["problems"]}
    assert (BAD, "empty_file", "temperature.csv") in checks
    assert report["summary"]["quarantined"] == [BAD]


def test_two_machines_written_alike_in_names_are_quarantined(workdir, monkeypatch):
    yaml_of(workdir / paths.RAW, lambda meta: meta.update(machine="test!"))  # "test" in names
    _, problem = _only_problem(workdir, monkeypatch)
    assert (problem["campaign"], problem["check"]) == ("B01", "machine_name_clash")
    assert "machine 'test!' of B01/campaign.yaml and machine test of" in problem["message"]

"""Tests of ``thermal import rtl`` (pipeline.importers): Renishaw .rtl files -> laser.csv.

The .rtl files are written here in the layout documented in ``docs/import-rtl.md`` (sections
HEADER / TARGET DATA / USER-TEXT / RUNS / DEVIATIONS / EOF, CRLF line ends, five targets per
line): three warm-up times, bidirectional, four runs per file.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import schemas
from pipeline.importers import rtl_import
from pipeline.importers.renishaw import RtlFormatError, read_rtl
from pipeline.io.reader import read_campaign
from pipeline.validation.laser_checks import validate_laser
from schemas.contract import LASER_COLUMNS
from tests.helpers.repo_params import validation_limits

TARGETS = (0.0, 55.0, 110.0, 165.0, 220.0, 275.0)  # mm; six targets wrap onto two lines
WARMUP = (0.0, 30.0, 75.0)  # min
DATES = ("2015-01-12 08:30:00", "2015-01-12 09:00:00", "2015-01-12 09:45:00")
DIRECTIONS = ("+", "-", "+", "-")
LIMITS = validation_limits()


def deviation(file_index: int, run: int, target: float, direction: str) -> float:
    """A deviation (um) distinct for every file, run and target."""
    return round(
        2.5 * file_index + 0.011 * target + 0.1 * run - (0.4 if direction == "-" else 0), 3
    )


def rtl_text(
    file_index: int,
    *,
    targets=TARGETS,
    directions=DIRECTIONS,
    date: str | None = None,
    extra_header: str = "",
) -> str:
    """The text of one .rtl file: every run visits all targets, '-' runs in reverse."""
    lines = ["HEADER::", "File type  : rtl", "Owner      : Renishaw", "Version no : 1", ""]
    lines += ["TARGET DATA::", "Filetype  : ISO", f"Target-count: {len(targets)}", "Targets :"]
    lines += [" ".join(f"{t:.3f}" for t in targets[i : i + 5]) for i in range(0, len(targets), 5)]
    lines += ["Flags: 0 0 2 0", extra_header, "USER-TEXT::", "Machine: vmc-450"]
    lines += [f"Date:{DATES[file_index] if date is None else date}", "Axis:Y", ""]
    lines += ["RUNS::", f"Run-count:{len(directions)}", "", "DEVIATIONS::", "Run Target Data:"]
    for run, direction in enumerate(directions, start=1):
        order = range(1, len(targets) + 1) if direction == "+" else range(len(targets), 0, -1)
        for index in order:
            value = deviation(file_index, run, targets[index - 1], direction)
            lines.append(f"{run}   {index}      {value:.3f}")
    lines += ["", "EOF::", ""]
    return "\r\n".join(lines)


def write_rtl(folder: Path, file_index: int, **kwargs) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"warmup_{file_index}.rtl"
    path.write_bytes(rtl_text(file_index, **kwargs).encode("ascii"))
    return path


@pytest.fixture
def rtl_files(tmp_path):
    return [write_rtl(tmp_path / "exports", i) for i in range(len(WARMUP))]


def run_import(files, out, *options):
    return rtl_import.main([*map(str, files), "--out", str(out), *options])


def warmup_options(values=WARMUP):
    return ["--warmup-min", *(f"{m:g}" for m in values)]


def line_of(path: Path, text: str) -> int:
    """1-based line number of the first line of ``path`` equal to ``text`` (stripped)."""
    lines = path.read_bytes().decode("ascii").splitlines()
    return next(i for i, line in enumerate(lines, start=1) if line.strip() == text)


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --------------------------------------------------------------------------- parser


def test_read_rtl_header_targets_and_runs(rtl_files):
    rtl = read_rtl(rtl_files[1])
    assert rtl.targets_mm == TARGETS
    assert rtl.fields["HEADER"]["file type"][0] == "rtl"
    assert rtl.fields["TARGET DATA"]["flags"][0] == "0 0 2 0"
    assert rtl.axis_label == "Y"
    assert rtl.measured_at().isoformat() == "2015-01-12T09:00:00"
    assert [run.number for run in rtl.runs] == [1, 2, 3, 4]
    assert [run.direction for run in rtl.runs] == list(DIRECTIONS)
    assert rtl.runs[1].target_mm == TARGETS[::-1]
    assert rtl.runs[1].deviation_um[0] == deviation(1, 2, TARGETS[-1], "-")
    assert rtl.sections == ("HEADER", "TARGET DATA", "USER-TEXT", "RUNS", "DEVIATIONS", "EOF")


def test_direction_follows_positions_not_target_numbers(tmp_path):
    """Targets listed high to low: increasing target numbers are a '-' run."""
    path = write_rtl(tmp_path, 0, targets=TARGETS[::-1], directions=("+", "-"))
    runs = read_rtl(path).runs
    assert [run.direction for run in runs] == ["-", "+"]
    assert runs[0].target_mm == TARGETS[::-1]


# --------------------------------------------------------------------------- laser.csv


def test_laser_csv_round_trip(rtl_files, tmp_path):
    out = tmp_path / "raw" / "A07"
    assert run_import(rtl_files, out, *warmup_options()) == 0
    laser = pd.read_csv(out / "laser.csv", dtype={"direction": str})
    assert tuple(laser.columns) == LASER_COLUMNS
    assert len(laser) == len(WARMUP) * len(DIRECTIONS) * len(TARGETS)
    runs = laser.groupby("run", sort=True)
    assert list(runs.groups) == list(range(1, 13))
    per_run = runs.agg(elapsed=("elapsed_min", "first"), direction=("direction", "first"))
    assert per_run["elapsed"].tolist() == [m for m in WARMUP for _ in DIRECTIONS]
    assert per_run["direction"].tolist() == list(DIRECTIONS) * len(WARMUP)
    for run, rows in runs:
        file_index, run_in_file = divmod(run - 1, len(DIRECTIONS))
        direction = DIRECTIONS[run_in_file]
        expected_targets = TARGETS if direction == "+" else TARGETS[::-1]
        assert tuple(rows["target_mm"]) == expected_targets
        expected = [deviation(file_index, run_in_file + 1, t, direction) for t in expected_targets]
        assert rows["deviation_um"].tolist() == expected
        assert (rows["elapsed_min"] == WARMUP[file_index]).all()


def test_runs_are_numbered_in_time_order_whatever_the_file_order(rtl_files, tmp_path):
    out = tmp_path / "raw" / "A08"
    shuffled = [rtl_files[2], rtl_files[0], rtl_files[1]]
    assert run_import(shuffled, out, *warmup_options((75, 0, 30))) == 0
    laser = pd.read_csv(out / "laser.csv")
    assert (
        laser.groupby("run")["elapsed_min"].first().tolist() == [0.0] * 4 + [30.0] * 4 + [75.0] * 4
    )
    cold_first = laser[laser["run"] == 1]["deviation_um"].iloc[0]
    assert cold_first == deviation(0, 1, TARGETS[0], "+")


def test_times_from_header_and_campaign_skeleton(rtl_files, tmp_path, capsys):
    out = tmp_path / "raw" / "A09"
    code = run_import(
        rtl_files[::-1],  # newest first: times are relative to the earliest file
        out,
        "--times-from-header",
        "--machine",
        "vmc-450",
        "--axis",
        "Y",
        "--stroke-mm",
        "280",
    )
    assert code == 0
    laser = pd.read_csv(out / "laser.csv")
    assert sorted(laser["elapsed_min"].unique()) == list(WARMUP)
    meta = yaml.safe_load((out / "campaign.yaml").read_text())
    assert meta["campaign_id"] == "A09"
    assert meta["kind"] == "axis_positioning"
    assert meta["axis"] == {"name": "Y", "stroke_mm": 280.0}
    assert meta["start"] == "2015-01-12T08:30:00"  # the Date of the cold file
    assert meta["sensors"] == {}
    message = capsys.readouterr().out
    assert "temperature.csv" in message and "sensors" in message


def test_missing_skeleton_options_name_the_keys_to_add(rtl_files, tmp_path, capsys):
    out = tmp_path / "raw" / "A10"
    assert run_import(rtl_files, out, *warmup_options(), "--axis", "Y") == 0
    assert not (out / "campaign.yaml").exists()
    message = capsys.readouterr().out
    for text in ("--machine", "--stroke-mm", "--start", "kind: axis_positioning", "temperature"):
        assert text in message


def test_imported_folder_reads_and_passes_the_laser_checks(rtl_files, tmp_path):
    out = tmp_path / "raw" / "A11"
    out.mkdir(parents=True)
    sensors = {"T1": {"role": "ball_screw", "type": "PT100"}, "T2": {"role": "ambient"}}
    meta = {
        "campaign_id": "A11",
        "kind": "axis_positioning",
        "machine": "vmc-450",
        "start": "2015-01-12T08:30:00",
        "sensors": sensors,
        "axis": {"name": "Y", "stroke_mm": 280},
    }
    (out / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    t = np.arange(0, 80 * 60 + 1, 300.0)
    pd.DataFrame({"elapsed_s": t, "T1": 20 + t / 1000, "T2": 20.0}).to_csv(
        out / "temperature.csv", index=False
    )
    before = {path: sha(path) for path in rtl_files}
    assert run_import(rtl_files, out, *warmup_options()) == 0
    assert {path: sha(path) for path in rtl_files} == before  # inputs byte-identical
    assert yaml.safe_load((out / "campaign.yaml").read_text()) == meta  # left unchanged
    raw = read_campaign(out, max_alignment_gap_s=60.0)
    assert raw.problems == []
    assert len(raw.laser) == 72
    assert validate_laser("A11", raw.laser, LIMITS) == []
    schemas.LaserModel.validate(raw.laser)


def test_existing_laser_csv_needs_force(rtl_files, tmp_path, capsys):
    out = tmp_path / "raw" / "A12"
    out.mkdir(parents=True)
    (out / "laser.csv").write_text("keep me\n")
    assert run_import(rtl_files, out, *warmup_options()) == 2
    assert (out / "laser.csv").read_text() == "keep me\n"
    assert "--force" in capsys.readouterr().err
    assert run_import(rtl_files, out, *warmup_options(), "--force") == 0
    assert pd.read_csv(out / "laser.csv").shape == (72, 5)


# --------------------------------------------------------------------------- errors


def test_truncated_file(rtl_files, tmp_path, capsys):
    text = rtl_files[1].read_bytes()
    truncated = tmp_path / "truncated.rtl"
    truncated.write_bytes(text[: text.index(b"3   1 ")])  # cut in run 3 of 4
    with pytest.raises(RtlFormatError) as caught:
        read_rtl(truncated)
    assert "truncated" in str(caught.value)
    assert caught.value.section == "DEVIATIONS"
    last_kept = f"2   1      {deviation(1, 2, TARGETS[0], '-'):.3f}"
    assert caught.value.line == line_of(truncated, last_kept)
    files = [rtl_files[0], truncated, rtl_files[2]]
    assert run_import(files, tmp_path / "raw" / "A13", *warmup_options()) == 2
    err = capsys.readouterr().err
    assert str(truncated) in err and "Traceback" not in err
    assert not (tmp_path / "raw" / "A13" / "laser.csv").exists()


def test_missing_section(rtl_files, tmp_path):
    text = rtl_files[0].read_bytes().decode("ascii")
    path = tmp_path / "no_runs.rtl"
    path.write_bytes(text.replace("RUNS::\r\nRun-count:4\r\n", "").encode("ascii"))
    with pytest.raises(RtlFormatError, match=r"section RUNS:: is missing") as caught:
        read_rtl(path)
    assert str(path) in str(caught.value)


def test_non_numeric_deviation_names_file_and_line(rtl_files, tmp_path, capsys):
    text = rtl_files[0].read_bytes().decode("ascii")
    original = f"2   4      {deviation(0, 2, TARGETS[3], '-'):.3f}"
    path = tmp_path / "bad_value.rtl"
    path.write_bytes(text.replace(original, "2   4      n/a").encode("ascii"))
    line = line_of(path, "2   4      n/a")
    with pytest.raises(RtlFormatError) as caught:
        read_rtl(path)
    message = str(caught.value)
    assert f"{path} (line {line}, section DEVIATIONS)" in message
    assert "deviation 'n/a' is not a number" in message
    assert run_import([path, *rtl_files[1:]], tmp_path / "raw" / "A14", *warmup_options()) == 2
    assert f"line {line}" in capsys.readouterr().err


def test_run_neither_increasing_nor_decreasing(rtl_files, tmp_path):
    lines = rtl_files[0].read_bytes().decode("ascii").split("\r\n")
    first = lines.index(f"3   1      {deviation(0, 3, TARGETS[0], '+'):.3f}")
    lines[first + 2], lines[first + 3] = lines[first + 3], lines[first + 2]  # targets 3 and 4
    path = tmp_path / "zigzag.rtl"
    path.write_bytes("\r\n".join(lines).encode("ascii"))
    with pytest.raises(RtlFormatError, match="neither increasing nor decreasing") as caught:
        read_rtl(path)
    assert caught.value.line == first + 1
    assert "run 3" in str(caught.value)


def test_declared_non_metric_unit_is_refused(tmp_path):
    path = write_rtl(tmp_path, 0, extra_header="Units : inch")
    with pytest.raises(RtlFormatError, match="only metric files"):
        read_rtl(path)


def test_decimal_comma_target_is_refused(rtl_files, tmp_path):
    text = rtl_files[0].read_bytes().decode("ascii")
    path = tmp_path / "comma.rtl"
    path.write_bytes(text.replace("55.000", "55,000", 1).encode("ascii"))
    with pytest.raises(RtlFormatError, match=r"decimal comma") as caught:
        read_rtl(path)
    assert caught.value.section == "TARGET DATA"


def test_user_errors_exit_2_with_one_paragraph(rtl_files, tmp_path, capsys):
    out = tmp_path / "raw" / "A15"
    cases = [
        (warmup_options((10, 30, 75)), "cold pass"),
        (warmup_options((0, 30)), "3 .rtl files but 2"),
        (warmup_options((0, 30, 30)), "both have elapsed_min 30"),
    ]
    for options, expected in cases:
        assert run_import(rtl_files, out, *options) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1
    one_way = write_rtl(tmp_path / "one_way", 0, directions=("+", "+"))
    assert run_import([one_way, *rtl_files[1:]], out, *warmup_options()) == 2
    assert "both directions" in capsys.readouterr().err
    other = write_rtl(tmp_path / "other", 0, targets=(0.0, 50.0, 100.0))
    assert run_import([other, *rtl_files[1:]], out, *warmup_options()) == 2
    assert "same targets" in capsys.readouterr().err
    no_date = write_rtl(tmp_path / "no_date", 0, date="12/01/2015")
    assert run_import([no_date, *rtl_files[1:]], out, "--times-from-header") == 2
    assert "--warmup-min" in capsys.readouterr().err
    assert run_import(rtl_files, tmp_path / "bad id!", *warmup_options()) == 2
    assert run_import(rtl_files, out) == 2  # neither --warmup-min nor --times-from-header
    assert not out.exists()


def test_other_campaign_kind_is_refused(rtl_files, tmp_path, capsys):
    out = tmp_path / "raw" / "K01"
    out.mkdir(parents=True)
    (out / "campaign.yaml").write_text("campaign_id: K01\nkind: spindle_drift\n")
    assert run_import(rtl_files, out, *warmup_options()) == 2
    assert "spindle_drift" in capsys.readouterr().err
    assert not (out / "laser.csv").exists()

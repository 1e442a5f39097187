"""Read one campaign folder of the raw contract (version 1) into tidy frames.

The contract (``docs/data-contract.md``) is a public interface: ``campaign.yaml`` plus
``temperature.csv`` (every campaign), ``displacement.csv`` (spindle drift), optional
``spindle.csv`` and ``laser.csv`` (axis positioning). Reading never fails on bad content: every
problem found becomes a :class:`Problem` naming the file, row and column, and the rest of the
campaign is still read, so that the validation stage can report all problems of a campaign at once.
Raw files are only ever opened for reading. Files are opened and split into cells by
:mod:`pipeline.io.files`, ``campaign.yaml`` is read by :mod:`pipeline.io.metadata` (its
``heat_loads:`` checked by :mod:`pipeline.io.heat_loads`); the texts of the problems are those
of :mod:`pipeline.validation.texts`.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from pipeline.io.files import MAX_REPORTED_ROWS, Report, read_csv_cells
from pipeline.io.heat_loads import check_heat_loads
from pipeline.io.metadata import campaign_row, read_metadata
from pipeline.validation.texts import word
from schemas.contract import CONTRACT_FILES, LASER_COLUMNS
from schemas.vocabulary import SAMPLE_BASE_COLUMNS, is_displacement_name

LOGGER = logging.getLogger(__name__)

RESERVED_COLUMNS = frozenset(SAMPLE_BASE_COLUMNS)


@dataclass(frozen=True)
class Problem:
    """One problem found while reading a campaign.

    Attributes
    ----------
    campaign_id : str
        The campaign folder name.
    file : str
        File inside the folder (``campaign.yaml``, ``temperature.csv``, ...).
    row : int or None
        1-based data row (the header is not counted; the editor line is ``row + 1``).
    column : str or None
        Column (CSV) or key (YAML) concerned.
    check : str
        Short identifier of the failed check.
    problem : str
        What is wrong.
    action : str
        What the user should do.
    """

    campaign_id: str
    file: str
    row: int | None
    column: str | None
    check: str
    problem: str
    action: str


@dataclass
class RawCampaign:
    """Everything read from one campaign folder.

    Attributes
    ----------
    metadata : dict or None
        One row of the campaigns table, or None when ``campaign.yaml`` is unreadable.
    samples : DataFrame or None
        Temperatures, speed (rpm) and displacement (um) on the temperature time base.
    laser : DataFrame or None
        Laser-interferometer runs (axis positioning).
    problems : list of Problem
        Everything that is wrong with the folder.
    """

    metadata: dict[str, Any] | None = None
    samples: pd.DataFrame | None = None
    laser: pd.DataFrame | None = None
    problems: list[Problem] = field(default_factory=list)


def read_campaign(folder: Path, max_alignment_gap_s: float) -> RawCampaign:
    """Read a campaign folder of the raw contract.

    Parameters
    ----------
    folder : Path
        ``<raw dir>/<campaign_id>/``.
    max_alignment_gap_s : float
        Seconds; a temperature instant further than this from every displacement sample gets
        no displacement (NaN) instead of an interpolated one.

    Returns
    -------
    RawCampaign
        The tables read and the problems found; never raises on bad content.
    """
    result = RawCampaign()
    report = _reporter(folder.name, result.problems)
    meta_raw = read_metadata(folder / "campaign.yaml", report)
    if meta_raw is None:
        return result
    result.metadata = campaign_row(folder, meta_raw, report)
    check_heat_loads(json.loads(result.metadata["heat_loads_json"]), report)
    kind = result.metadata["kind"]
    for name in CONTRACT_FILES.get(kind, ("temperature.csv",)):
        if not (folder / name).is_file():
            report(name, None, None, "missing_file", kind=kind)

    temperature = _read_numeric_csv(folder / "temperature.csv", report, _reserved_temperature)
    if temperature is None:
        return result
    samples = temperature.copy()
    samples.insert(0, "campaign_id", folder.name)
    samples.insert(3, "rpm", _speed(folder, result.metadata, samples["elapsed_s"], report))
    if kind == "spindle_drift" and (folder / "displacement.csv").is_file():
        displacement = _read_numeric_csv(folder / "displacement.csv", report, _reserved_other)
        if displacement is not None:
            samples = _align_displacement(samples, displacement, max_alignment_gap_s, report)
    result.samples = samples
    if kind == "axis_positioning" and (folder / "laser.csv").is_file():
        result.laser = _read_laser(folder / "laser.csv", folder.name, report)
    return result


def problems_frame(problems: list[Problem]) -> pd.DataFrame:
    """Tabulate problems as the ``problems`` table (``row`` as nullable Int64)."""
    columns = [f.name for f in Problem.__dataclass_fields__.values()]
    frame = pd.DataFrame([asdict(p) for p in problems], columns=columns)
    frame["row"] = frame["row"].astype("Int64")
    return frame.astype({c: "str" for c in columns if c != "row"})


def _reporter(campaign_id: str, problems: list[Problem]) -> Report:
    """Return the :data:`pipeline.io.files.Report` that appends to ``problems``.

    Without ``problem``/``action`` the texts are those of the check in
    :mod:`pipeline.validation.texts`, filled with the campaign, file, column, row, ``where``
    (``K01/temperature.csv row 3 (line 4)``; a campaign.yaml row is its line) and ``fields``.
    """

    def report(
        file: str,
        row: int | None,
        column: str | None,
        check: str,
        problem: str | None = None,
        action: str | None = None,
        **fields: Any,
    ) -> None:
        if problem is None or action is None:
            where = f"{campaign_id}/{file}"
            if row is not None:
                line = row if file.endswith(".yaml") else row + 1
                where += f" row {row} (line {line})"
            problem, action = word(
                check,
                {
                    "campaign": campaign_id,
                    "file": file,
                    "column": column or "?",
                    "rows": "" if row is None else f"row {row}",
                    "where": where,
                    **fields,
                },
            )
        problems.append(Problem(campaign_id, file, row, column, check, problem, action))

    return report


def _reserved_temperature(column: str) -> bool:
    return column in RESERVED_COLUMNS or column.startswith("disp_")


def _reserved_other(column: str) -> bool:
    return column == "source_row"


def _read_numeric_csv(path: Path, report: Report, reserved: Callable[[str], bool]):
    """Read a CSV whose columns are all numeric; bad cells become NaN and problems.

    Returns a frame ``source_row, elapsed_s, <other columns in file order>`` (float64), or
    None when the file is absent or unreadable or has no ``elapsed_s`` column. Columns whose
    name is ``reserved`` by the pipeline are reported (``reserved_column``) and left out.
    """
    if not path.is_file():
        return None
    text = read_csv_cells(path, report)
    if text is None:
        return None
    if "elapsed_s" not in text.columns:
        report(
            path.name,
            None,
            "elapsed_s",
            "missing_column",
            header=",".join(text.columns),
            expected="elapsed_s (seconds since start:) as the first column",
        )
        return None
    frame = pd.DataFrame({"source_row": np.arange(1, len(text) + 1, dtype=np.int64)})
    for column in text.columns:
        if column != "elapsed_s" and reserved(column):
            report(path.name, None, column, "reserved_column", name=column)
            continue
        frame[column] = _numbers(text[column], path.name, column, report)
    others = [c for c in frame.columns if c not in ("source_row", "elapsed_s")]
    return frame.loc[:, ["source_row", "elapsed_s", *others]]


def _numbers(cells: pd.Series, file: str, column: str, report: Report) -> np.ndarray:
    """Return the numbers of a column of text cells (float64; empty and bad cells NaN).

    A cell that is not a number is reported as ``not_a_number``, an infinite one (``inf``,
    ``1e999``) as ``not_finite``; an empty cell is a missing reading.
    """
    empty = (cells == "").to_numpy()
    values = pd.to_numeric(cells.to_numpy(dtype=object), errors="coerce").astype(np.float64)
    for index in np.flatnonzero(np.isnan(values) & ~empty)[:MAX_REPORTED_ROWS]:
        report(file, int(index) + 1, column, "not_a_number", value=repr(cells.iloc[index]))
    infinite = np.isinf(values)
    for index in np.flatnonzero(infinite)[:MAX_REPORTED_ROWS]:
        report(file, int(index) + 1, column, "not_finite", value=repr(cells.iloc[index]))
    values[infinite] = np.nan
    return values


def _speed(folder: Path, meta: dict[str, Any], elapsed_s: pd.Series, report) -> np.ndarray:
    """Spindle speed (rpm) at each instant: the measured log if present, else the program."""
    log = _read_numeric_csv(folder / "spindle.csv", report, _reserved_other)
    if log is not None and "rpm" not in log.columns:
        report(
            "spindle.csv",
            None,
            "rpm",
            "missing_column",
            header=",".join(log.columns[1:]),
            expected="the header elapsed_s,rpm",
        )
    elif log is not None:
        order = np.argsort(log["elapsed_s"].to_numpy(), kind="stable")
        times = log["elapsed_s"].to_numpy()[order]
        rpm = log["rpm"].to_numpy()[order]
        index = np.clip(np.searchsorted(times, elapsed_s.to_numpy(), side="right") - 1, 0, None)
        return rpm[index]
    speed = np.full(len(elapsed_s), np.nan)
    minutes = elapsed_s.to_numpy() / 60.0
    for number, segment in enumerate(json.loads(meta["spindle_program_json"]), start=1):
        try:
            begin = float(segment["from_min"])
            end = float(segment.get("to_min", np.inf))
            rpm = float(segment["rpm"])
            if not (np.isfinite(begin) and np.isfinite(rpm)):
                raise ValueError("not finite")
        except (AttributeError, KeyError, TypeError, ValueError):
            report(
                "campaign.yaml",
                None,
                "spindle_program",
                "bad_spindle_program",
                number=number,
                entry=segment,
            )
            continue
        speed[(minutes >= begin) & (minutes < end)] = rpm
    return speed


def _align_displacement(
    samples: pd.DataFrame, displacement: pd.DataFrame, max_gap_s: float, report
) -> pd.DataFrame:
    """Interpolate each displacement axis (um) linearly onto the temperature instants.

    Rows without a time are reported (``missing_value``) and left out; without any timed row
    the samples get no displacement column (validation reports the declared axes as missing).
    A missing reading (empty cell) is not interpolated across here: an instant next to it gets
    no displacement and ``disp_<A>_source_row`` names the empty row, so that ``validate``
    reports the gap and bridges or drops it (``validate.max_bridged_gap_s``). An instant outside
    the displacement record, or further than ``max_gap_s`` from it, has no source row.
    """
    untimed = displacement["elapsed_s"].isna().to_numpy()
    for row in displacement.loc[untimed, "source_row"].head(MAX_REPORTED_ROWS):
        report("displacement.csv", int(row), "elapsed_s", "missing_value")
    displacement = displacement.loc[~untimed]
    if displacement.empty:
        return samples
    times = displacement["elapsed_s"].to_numpy()
    if np.any(np.diff(times) <= 0):
        row = int(displacement["source_row"].iloc[int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1])
        report("displacement.csv", row, "elapsed_s", "time_not_increasing")
    order = np.argsort(times, kind="stable")
    times, rows = times[order], displacement["source_row"].to_numpy()[order]
    target = samples["elapsed_s"].to_numpy()
    nearest = _nearest_index(times, target)
    exact = times[nearest] == target
    outside = ~(np.abs(times[nearest] - target) <= max_gap_s)
    outside |= (target < times[0]) | (target > times[-1])
    # the other end of the interval [times[j], times[j + 1]] holding each target
    other = np.where(times[nearest] > target, nearest - 1, nearest + 1).clip(0, len(times) - 1)
    aligned = samples.copy()
    for axis in [c for c in displacement.columns if c not in ("elapsed_s", "source_row")]:
        if not is_displacement_name(axis):
            report("displacement.csv", None, axis, "unknown_axis")
            continue
        values = displacement[axis].to_numpy()[order]
        # np.interp gives NaN wherever an end of the interval is a missing reading
        column = np.interp(target, times, values, left=np.nan, right=np.nan)
        column[exact] = values[nearest][exact]
        column[outside] = np.nan
        empty_end = np.where(np.isnan(values[nearest]) | exact, nearest, other)
        source = np.where(np.isnan(column), rows[empty_end], rows[nearest])
        aligned[f"disp_{axis}"] = column
        aligned[f"disp_{axis}_source_row"] = pd.array(source, dtype="Int64")
        aligned.loc[outside, f"disp_{axis}_source_row"] = pd.NA
    return aligned


def _nearest_index(sorted_times: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Return the index of the nearest of ``sorted_times`` (non-empty) to each target."""
    right = np.clip(np.searchsorted(sorted_times, target), 0, len(sorted_times) - 1)
    left = np.clip(right - 1, 0, None)
    use_left = np.abs(sorted_times[left] - target) <= np.abs(sorted_times[right] - target)
    return np.where(use_left, left, right)


def _read_laser(path: Path, campaign_id: str, report) -> pd.DataFrame | None:
    """Read laser.csv into the laser table (None when unreadable or lacking columns).

    Numbers as in :func:`_numbers`; a run that is not a whole number is reported
    (``laser_run_number``) and becomes -1; an empty direction is missing (validation reports it).
    """
    text = read_csv_cells(path, report)
    if text is None:
        return None
    missing = [c for c in LASER_COLUMNS if c not in text.columns]
    if missing:
        expected = "the header " + ",".join(LASER_COLUMNS)
        report(
            path.name,
            None,
            ",".join(missing),
            "missing_column",
            header=",".join(text.columns),
            expected=expected,
        )
        return None
    frame = pd.DataFrame(
        {
            "campaign_id": campaign_id,
            "source_row": np.arange(1, len(text) + 1, dtype=np.int64),
        }
    )
    for column in ("elapsed_min", "target_mm", "deviation_um"):
        frame[column] = _numbers(text[column], path.name, column, report)
    frame["run"] = _run_numbers(text["run"], path.name, report)
    frame["direction"] = text["direction"].where(text["direction"] != "")
    return frame.loc[:, ["campaign_id", "source_row", *LASER_COLUMNS]]


def _run_numbers(cells: pd.Series, file: str, report: Report) -> np.ndarray:
    """Return the run numbers (int64); a cell that is not a whole number is reported, -1."""
    values = pd.to_numeric(cells.to_numpy(dtype=object), errors="coerce").astype(np.float64)
    whole = np.isfinite(values) & (np.abs(values) < 2.0**53)
    whole[whole] = values[whole] == np.round(values[whole])
    for index in np.flatnonzero(~whole)[:MAX_REPORTED_ROWS]:
        value = cells.iloc[index]
        report(
            file, int(index) + 1, "run", "laser_run_number", value=repr(value) if value else "empty"
        )
    return np.where(whole, values, -1).astype(np.int64)

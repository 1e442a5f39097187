"""Read one campaign folder of the raw contract (version 1) into tidy frames.

The contract (``data-contract.md``) is a public interface: ``campaign.yaml`` plus
``temperature.csv`` (every campaign), ``displacement.csv`` (spindle drift), optional
``spindle.csv`` and ``laser.csv`` (axis positioning). Reading never fails on bad content: every
problem found becomes a :class:`Problem` naming the file, row and column, and the rest of the
campaign is still read, so that the validation stage can report all problems of a campaign at once.
Raw files are only ever opened for reading.
"""

from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from schemas.vocabulary import is_displacement_name

LOGGER = logging.getLogger(__name__)

CONTRACT_FILES = {
    "spindle_drift": ("temperature.csv", "displacement.csv"),
    "axis_positioning": ("temperature.csv", "laser.csv"),
}
LASER_COLUMNS = ("elapsed_min", "run", "direction", "target_mm", "deviation_um")
RESERVED_COLUMNS = frozenset({"campaign_id", "source_row", "elapsed_s", "rpm"})
SEASON_BY_MONTH = {
    12: "winter", 1: "winter", 2: "winter",
    3: "spring", 4: "spring", 5: "spring",
    6: "summer", 7: "summer", 8: "summer",
    9: "autumn", 10: "autumn", 11: "autumn",
}  # fmt: skip


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
    campaign_id = folder.name
    result = RawCampaign()

    def report(file: str, row: int | None, column: str | None, check: str, problem: str,
               action: str) -> None:  # fmt: skip
        result.problems.append(Problem(campaign_id, file, row, column, check, problem, action))

    meta_raw = _read_yaml(folder / "campaign.yaml", report)
    if meta_raw is None:
        return result
    result.metadata = _campaign_row(folder, meta_raw, report)
    kind = result.metadata["kind"]
    for name in CONTRACT_FILES.get(kind, ("temperature.csv",)):
        if not (folder / name).is_file():
            report(name, None, None, "missing_file",
                   f"{name} is missing; a {kind} campaign needs it",
                   f"add {folder / name} in the raw contract format")  # fmt: skip

    temperature = _read_numeric_csv(folder / "temperature.csv", report)
    if temperature is None:
        return result
    sensor_columns = [c for c in temperature.columns if c not in ("elapsed_s", "source_row")]
    for column in sensor_columns:
        if column in RESERVED_COLUMNS or column.startswith("disp_"):
            report("temperature.csv", None, column, "reserved_column",
                   f"temperature column name '{column}' is reserved by the pipeline",
                   "rename the sensor in temperature.csv and campaign.yaml")  # fmt: skip
    samples = temperature.copy()
    samples.insert(0, "campaign_id", campaign_id)
    samples.insert(3, "rpm", _speed(folder, result.metadata, samples["elapsed_s"], report))
    if kind == "spindle_drift" and (folder / "displacement.csv").is_file():
        displacement = _read_numeric_csv(folder / "displacement.csv", report)
        if displacement is not None:
            samples = _align_displacement(samples, displacement, max_alignment_gap_s, report)
    result.samples = samples
    if kind == "axis_positioning" and (folder / "laser.csv").is_file():
        result.laser = _read_laser(folder / "laser.csv", campaign_id, report)
    return result


def problems_frame(problems: list[Problem]) -> pd.DataFrame:
    """Tabulate problems as the ``problems`` table (``row`` as nullable Int64)."""
    columns = [f.name for f in Problem.__dataclass_fields__.values()]
    frame = pd.DataFrame([asdict(p) for p in problems], columns=columns)
    frame["row"] = frame["row"].astype("Int64")
    return frame.astype({c: "str" for c in columns if c != "row"})


def _read_yaml(path: Path, report) -> dict[str, Any] | None:
    if not path.is_file():
        report(path.name, None, None, "missing_file", "campaign.yaml is missing",
               f"add {path} (see data-contract.md) or remove the folder")  # fmt: skip
        return None
    try:
        content = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        mark = getattr(error, "problem_mark", None)
        row = None if mark is None else mark.line + 1
        report(path.name, row, None, "unreadable_yaml", f"campaign.yaml cannot be parsed: {error}",
               "fix the YAML syntax at the line given")  # fmt: skip
        return None
    if not isinstance(content, dict):
        report(path.name, None, None, "unreadable_yaml", "campaign.yaml is not a mapping",
               "write the keys of data-contract.md (campaign_id, kind, sensors, ...)")  # fmt: skip
        return None
    return content


def _campaign_row(folder: Path, meta: dict[str, Any], report) -> dict[str, Any]:
    campaign_id = folder.name
    declared = str(meta.get("campaign_id", ""))
    if declared != campaign_id:
        report("campaign.yaml", None, "campaign_id", "campaign_id_mismatch",
               f"campaign_id '{declared}' differs from the folder name '{campaign_id}'",
               f"set campaign_id: {campaign_id} or rename the folder")  # fmt: skip
    kind = str(meta.get("kind", ""))
    if kind not in CONTRACT_FILES:
        report("campaign.yaml", None, "kind", "unknown_kind",
               f"kind '{kind}' is not one of {sorted(CONTRACT_FILES)}",
               "set kind: spindle_drift or kind: axis_positioning")  # fmt: skip
    start = pd.to_datetime(str(meta.get("start", "")), errors="coerce")
    if pd.isna(start):
        report("campaign.yaml", None, "start", "bad_start",
               f"start '{meta.get('start')}' is not an ISO 8601 date-time",
               "write start: YYYY-MM-DDTHH:MM:SS (local time of the first sample)")  # fmt: skip
    season = meta.get("season")
    season_derived = season is None
    if season_derived:
        season = SEASON_BY_MONTH[start.month] if not pd.isna(start) else ""
    axis = meta.get("axis") or {}
    sensors = meta.get("sensors") or {}
    if not isinstance(sensors, dict) or not sensors:
        report("campaign.yaml", None, "sensors", "no_sensors",
               "campaign.yaml declares no temperature sensors",
               "list every temperature.csv column under sensors: with its role")  # fmt: skip
        sensors = {}
    return {
        "campaign_id": campaign_id,
        "kind": kind,
        "machine": str(meta.get("machine", "")),
        "start": start if pd.isna(start) or start.tzinfo is None else start.tz_localize(None),
        "season": str(season),
        "season_derived": bool(season_derived),
        "synthetic": bool(meta.get("synthetic", False)),
        "split": str(meta.get("split", "train")),
        "start_state": _optional_text(meta.get("start_state")),
        "follows": _optional_text(meta.get("follows")),
        "axis_name": str(axis["name"]) if "name" in axis else None,
        "stroke_mm": float(axis.get("stroke_mm", np.nan)),
        "sensors_json": json.dumps(
            {str(k): (v or {}) for k, v in sensors.items()}, sort_keys=True, default=str
        ),
        "displacement_json": json.dumps(meta.get("displacement") or {}, sort_keys=True),
        "spindle_program_json": json.dumps(meta.get("spindle_program") or [], sort_keys=True),
        "has_spindle_log": (folder / "spindle.csv").is_file(),
        "source_dir": str(folder),
    }


def _optional_text(value: Any) -> str | None:
    """Return a yaml value as stripped text, None when absent or empty."""
    return None if value is None or str(value).strip() == "" else str(value).strip()


def _read_text_csv(path: Path, report) -> pd.DataFrame | None:
    """Read a CSV as text cells (empty cells stay empty); None and a problem if unreadable."""
    try:
        return pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as error:
        report(path.name, None, None, "unreadable_csv", f"{path.name} cannot be parsed: {error}",
               "save it as comma-separated UTF-8 with one header row")  # fmt: skip
        return None


def _read_numeric_csv(path: Path, report) -> pd.DataFrame | None:
    """Read a CSV whose columns are all numeric; non-numeric cells become NaN and problems."""
    if not path.is_file():
        return None
    text = _read_text_csv(path, report)
    if text is None:
        return None
    if "elapsed_s" not in text.columns:
        report(path.name, None, "elapsed_s", "missing_column",
               f"{path.name} has no elapsed_s column (header: {list(text.columns)})",
               "make elapsed_s (seconds since start) the first column")  # fmt: skip
        return None
    frame = pd.DataFrame({"source_row": np.arange(1, len(text) + 1, dtype=np.int64)})
    for column in text.columns:
        values = pd.to_numeric(text[column].str.strip().replace("", np.nan), errors="coerce")
        bad = values.isna() & (text[column].str.strip() != "")
        for index in np.flatnonzero(bad.to_numpy())[:20]:
            report(path.name, int(index) + 1, column, "not_a_number",
                   f"'{text[column].iloc[index]}' is not a number",
                   "write a number, or leave the cell empty for a missing reading")  # fmt: skip
        frame[column] = values.astype(np.float64)
    return frame.loc[:, ["source_row", "elapsed_s", *[c for c in text.columns if c != "elapsed_s"]]]


def _speed(folder: Path, meta: dict[str, Any], elapsed_s: pd.Series, report) -> np.ndarray:
    """Spindle speed (rpm) at each instant: the measured log if present, else the program."""
    log = _read_numeric_csv(folder / "spindle.csv", report)
    if log is not None and "rpm" in log.columns and len(log):
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
        except (KeyError, TypeError, ValueError):
            report("campaign.yaml", number, "spindle_program", "bad_spindle_program",
                   f"spindle_program entry {number} ({segment}) lacks a numeric from_min or rpm",
                   "write entries as {from_min: 0, to_min: 240, rpm: 4000}")  # fmt: skip
            continue
        speed[(minutes >= begin) & (minutes < end)] = rpm
    return speed


def _align_displacement(samples: pd.DataFrame, displacement: pd.DataFrame, max_gap_s: float,
                        report) -> pd.DataFrame:  # fmt: skip
    """Interpolate each displacement axis (um) linearly onto the temperature instants."""
    times = displacement["elapsed_s"].to_numpy()
    if np.any(np.diff(times) <= 0):
        row = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 2
        report(
            "displacement.csv",
            row,
            "elapsed_s",
            "time_not_increasing",
            "elapsed_s is not strictly increasing",
            "sort the rows by time, remove duplicates",
        )
    order = np.argsort(times, kind="stable")
    times, rows = times[order], displacement["source_row"].to_numpy()[order]
    target = samples["elapsed_s"].to_numpy()
    nearest = _nearest_index(times, target)
    too_far = np.abs(times[nearest] - target) > max_gap_s if len(times) else np.ones(len(target))
    aligned = samples.copy()
    for axis in [c for c in displacement.columns if c not in ("elapsed_s", "source_row")]:
        if not is_displacement_name(axis):
            report(
                "displacement.csv",
                None,
                axis,
                "unknown_axis",
                f"displacement column '{axis}' is not an axis name (X, Y, Z, or letters and "
                "digits starting with a letter, e.g. Z2)",
                "name displacement columns X, Y, Z (or e.g. Z2) as declared under displacement:",
            )
            continue
        values = displacement[axis].to_numpy()[order]
        valid = ~np.isnan(values)
        column = np.full(len(target), np.nan)
        if valid.sum() >= 2:
            column = np.interp(target, times[valid], values[valid], left=np.nan, right=np.nan)
        elif valid.sum() == 1:
            column = np.where(target == times[valid][0], values[valid][0], np.nan)
        column[too_far] = np.nan
        aligned[f"disp_{axis}"] = column
        aligned[f"disp_{axis}_source_row"] = pd.array(
            np.where(too_far, 0, rows[nearest]), dtype="Int64"
        )
        aligned.loc[too_far, f"disp_{axis}_source_row"] = pd.NA
    return aligned


def _nearest_index(sorted_times: np.ndarray, target: np.ndarray) -> np.ndarray:
    if len(sorted_times) == 0:
        return np.zeros(len(target), dtype=int)
    right = np.clip(np.searchsorted(sorted_times, target), 0, len(sorted_times) - 1)
    left = np.clip(right - 1, 0, None)
    use_left = np.abs(sorted_times[left] - target) <= np.abs(sorted_times[right] - target)
    return np.where(use_left, left, right)


def _read_laser(path: Path, campaign_id: str, report) -> pd.DataFrame | None:
    text = _read_text_csv(path, report)
    if text is None:
        return None
    missing = [c for c in LASER_COLUMNS if c not in text.columns]
    if missing:
        report(path.name, None, ",".join(missing), "missing_column",
               f"laser.csv lacks columns {missing} (header: {list(text.columns)})",
               f"write the header {','.join(LASER_COLUMNS)}")  # fmt: skip
        return None
    frame = pd.DataFrame({
        "campaign_id": campaign_id,
        "source_row": np.arange(1, len(text) + 1, dtype=np.int64),
    })  # fmt: skip
    for column in ("elapsed_min", "run", "target_mm", "deviation_um"):
        values = pd.to_numeric(text[column].str.strip().replace("", np.nan), errors="coerce")
        for index in np.flatnonzero(values.isna().to_numpy())[:20]:
            report(path.name, int(index) + 1, column, "not_a_number",
                   f"'{text[column].iloc[index]}' is not a number",
                   "every laser.csv cell must hold a number (direction: + or -)")  # fmt: skip
        frame[column] = values.astype(np.float64)
    frame["direction"] = text["direction"].str.strip().astype("str")
    frame["run"] = frame["run"].fillna(-1).astype(np.int64)
    return frame.loc[:, ["campaign_id", "source_row", *LASER_COLUMNS]]

"""The ``validate`` stage: Pandera checks per campaign; quarantine every campaign with a problem.

``thermal validate`` reads ``data/ingested/*.parquet``, validates each campaign lazily against
the models of :mod:`schemas` (its sensor map and displacement axes added per campaign), turns
every failure case and every ingest problem into a problem naming campaign, file, row (1-based
data row), line, column and check, and writes

- ``data/validated/spindle/{campaigns,samples}.parquet`` and
  ``data/validated/axis/{campaigns,samples,laser}.parquet``: the ingested tables restricted to
  the valid campaigns (samples columns without data for them dropped);
- ``reports/validation.json``: ``{"summary": {"campaigns", "valid", "quarantined"},
  "problems": [{"campaign", "file", "row", "line", "column", "check", "value", "message",
  "action"}]}``.

A campaign with any problem is left out and logged as a warning; the stage fails only when no
campaign is valid. Raw files are never touched. Functions other than :func:`main` are pure.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pandera.errors import SchemaErrors

from pipeline import paths
from pipeline.config import load_section
from schemas import (
    DATAFRAME_CHECK_COLUMNS,
    CampaignsModel,
    SensorsModel,
    ValidationLimits,
    campaign_samples_schema,
    laser_schema,
    parse_json,
)
from schemas import checks as check_functions
from schemas.vocabulary import (
    AMBIENT_ROLE,
    AXIS_KIND,
    DISPLACEMENT_AXES,
    DISPLACEMENT_COLUMN_RE,
    DISPLACEMENT_ROW_COLUMN_RE,
    SAMPLE_BASE_COLUMNS,
    SENSOR_ROLES,
    SPINDLE_KIND,
    displacement_row_column,
)

logger = logging.getLogger(__name__)

CAMPAIGN_FILE = "campaign.yaml"
TEMPERATURE_FILE = "temperature.csv"
DISPLACEMENT_FILE = "displacement.csv"
LASER_FILE = "laser.csv"

RERUN = "then rerun dvc repro"

FOLLOW_ON_CHECKS = frozenset(
    {"no_samples", "no_laser", "sensor_column_missing", "displacement_column_missing"}
)
"""Problems that only repeat a file-level ingest problem (missing/unreadable file)."""

OUTPUT_FILES = {
    "campaigns": paths.CAMPAIGNS_FILE,
    "samples": paths.SAMPLES_FILE,
    "laser": paths.LASER_FILE,
}


class NoValidCampaignError(RuntimeError):
    """Raised when every campaign is quarantined (or there is none)."""


@dataclass(frozen=True)
class Problem:
    """One entry of ``reports/validation.json``.

    ``row`` is the 1-based data row of ``file`` (the first of a group of consecutive rows; the
    message names them all), None for campaign-level problems; ``line`` is ``row + 1``.
    """

    campaign: str
    file: str
    row: int | None
    column: str | None
    check: str
    value: Any
    message: str
    action: str

    @property
    def line(self) -> int | None:
        """File line of ``row`` (the header is line 1)."""
        return None if self.row is None else self.row + 1

    def to_dict(self) -> dict[str, Any]:
        """Return the report entry (JSON-ready)."""
        return {
            "campaign": self.campaign,
            "file": self.file,
            "row": self.row,
            "line": self.line,
            "column": self.column,
            "check": self.check,
            "value": self.value,
            "message": self.message,
            "action": self.action,
        }


@dataclass(frozen=True)
class ValidationResult:
    """Outcome of :func:`validate_tables`.

    Attributes
    ----------
    campaigns : tuple of str
        Every campaign id seen in any ingested table, sorted.
    problems : tuple of Problem
        Every problem, grouped by campaign.
    """

    campaigns: tuple[str, ...]
    problems: tuple[Problem, ...]

    @property
    def quarantined(self) -> list[str]:
        """Campaigns with at least one problem, sorted."""
        return sorted({p.campaign for p in self.problems})

    @property
    def valid(self) -> list[str]:
        """Campaigns without any problem, sorted."""
        bad = set(self.quarantined)
        return [c for c in self.campaigns if c not in bad]


@dataclass(frozen=True)
class ProblemText:
    """How a check's failures are reported.

    ``message``/``action``/``column`` are ``str.format`` templates over the fields of a
    problem (see :func:`_render`). ``row_level=False`` reports the problem without a row;
    ``collapse=True`` merges all failures of the check in a campaign into one problem.
    """

    message: str
    action: str
    column: str | None = None
    row_level: bool = True
    collapse: bool = False


PROBLEM_TEXTS: dict[str, ProblemText] = {
    # ---- temperature.csv / displacement.csv (samples)
    "sensor_column_missing": ProblemText(
        "sensor {column} is declared under sensors: in {campaign}/campaign.yaml but "
        "{campaign}/temperature.csv has no column {column}, or none of its cells has a reading",
        "add the readings of {column} to {campaign}/temperature.csv, or remove {column} from "
        f"sensors: in {{campaign}}/campaign.yaml, {RERUN}",
    ),
    "unknown_temperature_column": ProblemText(
        "{campaign}/temperature.csv has a column {column} that is not declared under sensors: "
        "in {campaign}/campaign.yaml",
        "declare {column} (with its role) under sensors: in {campaign}/campaign.yaml, or delete "
        f"the column from {{campaign}}/temperature.csv, {RERUN}",
    ),
    "displacement_column_missing": ProblemText(
        "axis {axis} is declared under displacement: in {campaign}/campaign.yaml but "
        "{campaign}/displacement.csv has no column {axis}, or none of its cells has a reading",
        "add the {axis} readings to {campaign}/displacement.csv, or remove {axis} from "
        f"displacement: in {{campaign}}/campaign.yaml, {RERUN}",
        column="{axis}",
    ),
    "unknown_displacement_column": ProblemText(
        "{campaign}/displacement.csv has readings in column {axis} but displacement: in "
        "{campaign}/campaign.yaml does not declare axis {axis}",
        "declare {axis} under displacement: in {campaign}/campaign.yaml (e.g. "
        f"{{axis}}: {{{{probe: eddy_current}}}}), or delete the column, {RERUN}",
        column="{axis}",
    ),
    "time_increasing": ProblemText(
        "elapsed_s does not increase at {where}: {value} s follows {previous} s",
        "make elapsed_s strictly increasing in {campaign}/{file} (remove the duplicated or "
        f"out-of-order {{rows}}), {RERUN}",
    ),
    "sampling_interval": ProblemText(
        "the sampling interval before {where} is {value} s, more than "
        "{interval_tolerance_pct} % away from the campaign's median interval {median_interval} s "
        "(dropped or extra samples)",
        "check the logger around {rows} of {campaign}/{file}: add the missing instants with "
        "empty cells or remove the extra rows; if the sampling is irregular on purpose, raise "
        f"validate.interval_tolerance in params.yaml; {RERUN}",
    ),
    "temperature_range": ProblemText(
        "{column} reads {value} degC at {where}, outside the physical range "
        "{temperature_low} to {temperature_high} degC",
        "check sensor {column} and its unit (degC); replace the impossible readings of {column} "
        f"in {{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "ds18b20_power_on": ProblemText(
        "{column} reads {value} degC at {where}: the DS18B20 power-on reset value, not a "
        "measurement",
        "replace the {value} readings of {column} in {campaign}/{file} {rows} with empty cells "
        f"(sensor power-on value) or fix the logger, {RERUN}",
    ),
    "ds18b20_disconnected": ProblemText(
        "{column} reads {value} degC at {where}: the DS18B20 'device not found' code (sensor "
        "disconnected or wiring fault)",
        "check the wiring of {column}; replace the {value} readings of {column} in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "stuck_sensor": ProblemText(
        "{column} repeats {value} degC for {n_rows} samples in a row at {where} while another "
        "sensor changed by {stuck_min_other_change} degC or more: the sensor is stuck",
        "check sensor {column} and its logger channel; replace its readings in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "spike": ProblemText(
        "{column} jumps to {value} degC at {where}, more than {spike_threshold} degC away from "
        "both neighbouring readings",
        "replace the spike of {column} in {campaign}/{file} {rows} with an empty cell (and check "
        f"the sensor's wiring), {RERUN}",
    ),
    "displacement_range": ProblemText(
        "displacement {axis} reads {value} um at {where}, outside the probe range "
        "{displacement_low} to {displacement_high} um",
        "check probe {axis} (gap, range, unit um); replace the out-of-range readings in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
        column="{axis}",
    ),
    "missing_value": ProblemText(
        "{column} is empty at {where}",
        f"fill in {{column}} in {{campaign}}/{{file}} {{rows}} or delete the row, {RERUN}",
    ),
    "no_samples": ProblemText(
        "{campaign}/temperature.csv has no data rows",
        f"add the temperature log to data/raw/{{campaign}}/temperature.csv, {RERUN}",
        row_level=False,
    ),
    # ---- laser.csv
    "no_laser": ProblemText(
        "{campaign} is an axis_positioning campaign but {campaign}/laser.csv has no data rows",
        f"add the laser interferometer runs to data/raw/{{campaign}}/laser.csv, {RERUN}",
        row_level=False,
    ),
    "laser_direction": ProblemText(
        "direction {value} at {where} is neither '+' nor '-'",
        f"write + or - in the direction column of {{campaign}}/{{file}} {{rows}}, {RERUN}",
    ),
    "laser_run_one_direction": ProblemText(
        "run {run} mixes directions: direction {value} at {where} differs from most rows of the "
        "run (a run goes one way; a bidirectional pass is two runs)",
        "give every row of run {run} in {campaign}/{file} the same direction, or number the "
        f"reverse rows ({{rows}}) as a run of their own, {RERUN}",
    ),
    "laser_run_one_time": ProblemText(
        "run {run} has more than one elapsed_min: {value} min at {where} differs from most rows "
        "of the run",
        f"give every row of run {{run}} in {{campaign}}/{{file}} the same elapsed_min, {RERUN}",
    ),
    "laser_elapsed_nonnegative": ProblemText(
        "elapsed_min is negative ({value} min) at {where}",
        f"correct elapsed_min (minutes since start:) in {{campaign}}/{{file}} {{rows}}, {RERUN}",
    ),
    "laser_cold_run": ProblemText(
        "{campaign}/laser.csv has no run at elapsed_min 0: the cold-machine run carries the "
        "geometric error",
        "add the cold run (elapsed_min 0) to {campaign}/laser.csv, or correct the elapsed_min of "
        f"the run measured on the cold machine to 0, {RERUN}",
        row_level=False,
    ),
    "laser_bidirectional": ProblemText(
        "the pass at elapsed_min {elapsed_min} has only '{direction}' runs; each pass needs a "
        "'+' and a '-' run (the pass starts at {where})",
        "add the missing direction of the pass at elapsed_min {elapsed_min} to "
        "{campaign}/laser.csv, or correct the elapsed_min of its other run so that both runs "
        f"agree, {RERUN}",
    ),
    "laser_target_set": ProblemText(
        "target {value} mm of run {run} at {where} matches no target of the reference (cold) run "
        "within {laser_target_tolerance} mm",
        "measure every run at the same targets: correct target_mm in {campaign}/{file} {rows}, "
        "or raise validate.laser_target_tolerance_mm in params.yaml if the positions scatter "
        f"by design, {RERUN}",
    ),
    "laser_target_missing": ProblemText(
        "run {run} ('{direction}', elapsed_min {elapsed_min}) starting at {where} lacks the "
        "target(s) {value} mm of the reference (cold) run",
        "add the missing targets to run {run} in {campaign}/{file}, or remove the incomplete "
        f"run, {RERUN}",
    ),
    # ---- campaign.yaml
    "metadata_missing": ProblemText(
        "{yaml_key}: is missing or empty in {campaign}/campaign.yaml",
        f"add {{yaml_key}}: to {{campaign}}/campaign.yaml (see data-contract.md), {RERUN}",
        column="{yaml_key}",
    ),
    "kind_known": ProblemText(
        "kind {value} in {campaign}/campaign.yaml is not one of spindle_drift, axis_positioning",
        f"set kind: to spindle_drift or axis_positioning in {{campaign}}/campaign.yaml, {RERUN}",
        column="kind",
    ),
    "split_known": ProblemText(
        "split {value} in {campaign}/campaign.yaml is not train or validation",
        f"set split: to train or validation in {{campaign}}/campaign.yaml (or delete it: the "
        f"default is train), {RERUN}",
        column="split",
    ),
    "season_known": ProblemText(
        "season {value} in {campaign}/campaign.yaml is not spring, summer, autumn or winter",
        "correct season: in {campaign}/campaign.yaml, or delete it to derive the season from "
        f"start:, {RERUN}",
        column="season",
    ),
    "campaign_id_format": ProblemText(
        "campaign_id {value} has characters other than letters, digits, '-' and '_'",
        f"rename the folder data/raw/{{campaign}} and its campaign_id:, {RERUN}",
        column="campaign_id",
    ),
    "campaign_id_unique": ProblemText(
        "campaign_id {value} is used by more than one campaign (this one in {source_dir})",
        f"give every campaign folder its own id (campaign_id: = folder name), {RERUN}",
        column="campaign_id",
    ),
    "stroke_positive": ProblemText(
        "axis stroke_mm {value} in {campaign}/campaign.yaml is not positive",
        f"set axis: stroke_mm: to the travel of the axis in mm in {{campaign}}/campaign.yaml, "
        f"{RERUN}",
        column="axis.stroke_mm",
    ),
    "json_readable": ProblemText(
        "the {yaml_key}: block of {campaign}/campaign.yaml was not stored as valid JSON by "
        "ingest (value {value})",
        "check the {yaml_key}: block of {campaign}/campaign.yaml; if it is correct this is an "
        f"ingest bug (data/ingested/campaigns.parquet, column {{column}}), {RERUN}",
        column="{yaml_key}",
    ),
    "sensors_declared": ProblemText(
        "{campaign}/campaign.yaml declares no temperature sensor under sensors:",
        "add one entry per temperature.csv column under sensors: in {campaign}/campaign.yaml "
        f"(e.g. T1: {{{{role: spindle_front_bearing}}}}), {RERUN}",
        column="sensors",
    ),
    "displacement_declared": ProblemText(
        "{campaign} is a spindle_drift campaign but its campaign.yaml declares no axis under "
        "displacement:",
        "add the probe axes under displacement: in {campaign}/campaign.yaml (e.g. "
        f"Z: {{{{probe: eddy_current}}}}), {RERUN}",
        column="displacement",
    ),
    "displacement_axis_known": ProblemText(
        "displacement: in {campaign}/campaign.yaml names an axis other than X, Y, Z ({value})",
        f"use only X, Y or Z as displacement axes in {{campaign}}/campaign.yaml, {RERUN}",
        column="displacement",
    ),
    "axis_declared": ProblemText(
        "{campaign} is an axis_positioning campaign but its campaign.yaml has no axis: name:",
        f"add axis: {{{{name: <X|Y|Z>, stroke_mm: <travel>}}}} to {{campaign}}/campaign.yaml, "
        f"{RERUN}",
        column="axis.name",
    ),
    "sensor_role_known": ProblemText(
        "sensor {sensor} in {campaign}/campaign.yaml has role {value}, which is not in the "
        "closed vocabulary (" + ", ".join(SENSOR_ROLES) + ")",
        "set role: of {sensor} in {campaign}/campaign.yaml to one of the roles (other for "
        f"anything else), {RERUN}",
        column="sensors.{sensor}.role",
    ),
    "single_ambient": ProblemText(
        "sensors {value} of {campaign}/campaign.yaml all have role ambient; at most one sensor "
        "of a campaign may be ambient",
        "keep role: ambient only on the sensor that measures the air around the machine and give "
        f"the others their real role (or other) in {{campaign}}/campaign.yaml, {RERUN}",
        column="sensors",
        collapse=True,
    ),
    "campaign_metadata_missing": ProblemText(
        "{campaign} has {file} data but no campaign metadata (campaign.yaml missing or unreadable)",
        f"add a valid data/raw/{{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
        collapse=True,
    ),
}

FALLBACK_TEXT = ProblemText(
    "{column} failed the check {check} at {where} (value {value})",
    "the ingested tables must follow schemas/ingested.py: check thermal ingest's output "
    f"(data/ingested/*.parquet) and the files of data/raw/{{campaign}}, {RERUN}",
)
"""Used for Pandera's own checks (dtype, uniqueness, ...) that have no entry above."""


# --------------------------------------------------------------------------- parameters


def limits_from_params(section: Mapping[str, Any]) -> ValidationLimits:
    """Build the check limits from the ``validate:`` section of ``params.yaml``.

    Parameters
    ----------
    section : mapping
        Keys are the fields of :class:`schemas.ValidationLimits` (all required).

    Returns
    -------
    ValidationLimits

    Raises
    ------
    ValueError
        Naming the missing, unknown or malformed ``validate.<key>``.
    """
    names = list(ValidationLimits.__dataclass_fields__)
    missing = [n for n in names if n not in section]
    unknown = sorted(set(section) - set(names))
    if missing or unknown:
        raise ValueError(
            f"params.yaml validate: missing keys {missing}, unknown keys {unknown}; "
            f"the section needs exactly {names}"
        )
    values: dict[str, Any] = {}
    for name in names:
        raw = section[name]
        try:
            if name.endswith("_range_degC") or name.endswith("_range_um"):
                low, high = (float(v) for v in raw)
                if not low < high:
                    raise ValueError("low must be below high")
                values[name] = (low, high)
            elif name == "stuck_min_samples":
                values[name] = int(raw)
            else:
                values[name] = float(raw)
        except (TypeError, ValueError) as err:
            raise ValueError(
                f"params.yaml validate.{name} = {raw!r} is not valid ({err}); use "
                + ("[low, high]" if "_range_" in name else "a number")
            ) from err
    return ValidationLimits(**values)


# --------------------------------------------------------------------------- failures -> problems


class _Fields(dict):
    """Template fields; an unknown field renders as '?' instead of failing."""

    def __missing__(self, key: str) -> str:
        return "?"


@dataclass(frozen=True)
class _Finding:
    """One failing cell/row/column before grouping and rendering."""

    campaign: str
    file: str
    check: str
    column: str | None
    row: int | None
    value: Any
    fields: dict[str, Any] = field(default_factory=dict)


def _plain(value: Any) -> Any:
    """Return ``value`` as a JSON-ready Python object (missing -> None)."""
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if value is None or value is pd.NA or value is pd.NaT:
        return None
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def _text(value: Any) -> str:
    """Render a value for a message: strings quoted, lists comma-separated."""
    if isinstance(value, list):
        return ", ".join(_text(v) for v in value)
    if isinstance(value, str):
        return repr(value)
    if value is None:
        return "empty"
    return str(value)


def _field_text(value: Any) -> str:
    """Render a context field (run, direction, sensor, ...) for a message, unquoted."""
    value = _plain(value)
    if isinstance(value, list):
        return ", ".join(_field_text(v) for v in value)
    return "empty" if value is None else str(value)


def _rows_text(rows: list[int]) -> str:
    """Return ``row 3`` or ``rows 1-2`` for a run of consecutive 1-based data rows."""
    first, last = rows[0], rows[-1]
    if first == last:
        return f"row {first}"
    return f"rows {first}-{last}"


def _lines_text(rows: list[int]) -> str:
    first, last = rows[0] + 1, rows[-1] + 1
    return f"line {first}" if first == last else f"lines {first}-{last}"


def _limit_fields(limits: ValidationLimits) -> dict[str, Any]:
    return {
        "temperature_low": limits.temperature_range_degC[0],
        "temperature_high": limits.temperature_range_degC[1],
        "interval_tolerance_pct": round(100 * limits.interval_tolerance, 6),
        "stuck_min_samples": limits.stuck_min_samples,
        "stuck_min_other_change": limits.stuck_min_other_change_degC,
        "spike_threshold": limits.spike_threshold_degC,
        "displacement_low": limits.displacement_range_um[0],
        "displacement_high": limits.displacement_range_um[1],
        "laser_target_tolerance": limits.laser_target_tolerance_mm,
    }


def _render(group: list[_Finding], limits: ValidationLimits) -> Problem:
    """Turn a group of findings (same campaign, file, check, column) into one problem."""
    first = group[0]
    text = PROBLEM_TEXTS.get(first.check, FALLBACK_TEXT)
    rows = [f.row for f in group if f.row is not None] if text.row_level else []
    values: list[Any] = []
    for finding in group:
        value = _plain(finding.value)
        if value not in values:
            values.append(value)
    value = values[0] if len(values) == 1 else values
    location = f"{first.campaign}/{first.file}"
    where = f"{location} {_rows_text(rows)} ({_lines_text(rows)})" if rows else location
    fields = _Fields(
        {
            **_limit_fields(limits),
            **{k: _field_text(v) for k, v in first.fields.items()},
            "campaign": first.campaign,
            "file": first.file,
            "column": first.column if first.column is not None else "?",
            "check": first.check,
            "value": _text(value),
            "rows": _rows_text(rows) if rows else "",
            "where": where,
            "n_rows": len(group),
        }
    )
    column = text.column.format_map(fields) if text.column else first.column
    return Problem(
        campaign=first.campaign,
        file=first.file,
        row=rows[0] if rows else None,
        column=column,
        check=first.check,
        value=value,
        message=text.message.format_map(fields),
        action=text.action.format_map(fields),
    )


def _problems(findings: Iterable[_Finding], limits: ValidationLimits) -> list[Problem]:
    """Group consecutive rows of the same campaign/file/check/column and render them.

    Identical findings (e.g. several temperature rows pointing at one displacement row) are
    reported once; checks with ``collapse`` give one problem per campaign.
    """
    unique: dict[tuple, _Finding] = {}
    for f in findings:
        key = (f.campaign, f.file, f.check, f.column, f.row, repr(_plain(f.value)))
        unique.setdefault(key, f)

    def order(f: _Finding) -> tuple:
        return (f.campaign, f.file, f.check, f.column or "", -1 if f.row is None else f.row)

    groups: list[list[_Finding]] = []
    for f in sorted(unique.values(), key=order):
        text = PROBLEM_TEXTS.get(f.check, FALLBACK_TEXT)
        if groups:
            last = groups[-1][-1]
            same = (last.campaign, last.file, last.check) == (f.campaign, f.file, f.check)
            if same and text.collapse:
                groups[-1].append(f)
                continue
            if (
                same
                and last.column == f.column
                and f.row is not None
                and last.row is not None
                and f.row == last.row + 1
            ):
                groups[-1].append(f)
                continue
        groups.append([f])
    return [_render(g, limits) for g in groups]


def _failures(err: SchemaErrors) -> list[tuple[str, str | None, int | None, Any]]:
    """Normalise Pandera's failure cases to ``(check, column, index, value)`` tuples.

    Handles the three shapes Pandera produces: column checks (one row per failing cell),
    row-wise dataframe checks (one row per cell of each failing row: reduced to the column the
    check is about, :data:`schemas.DATAFRAME_CHECK_COLUMNS`), and wide dataframe checks
    returning a boolean frame (failure case ``{column: value}``). Column presence checks carry
    the column name as failure case.
    """
    out: list[tuple[str, str | None, int | None, Any]] = []
    seen: set[tuple] = set()
    for rec in err.failure_cases.itertuples(index=False):
        check, column, value = str(rec.check), rec.column, rec.failure_case
        index = None if rec.index is None or pd.isna(rec.index) else int(rec.index)
        column = None if column is None or pd.isna(column) else str(column)
        if check in ("column_in_dataframe", "column_in_schema"):
            items = [(check, str(value), None, value)]
        elif isinstance(value, dict):
            items = [(check, str(c), index, v) for c, v in value.items()]
        elif check in DATAFRAME_CHECK_COLUMNS:
            items = [(check, DATAFRAME_CHECK_COLUMNS[check], index, None)]
        else:
            items = [(check, column, index, value)]
        for item in items:
            key = item[:3]
            if key not in seen:
                seen.add(key)
                out.append(item)
    return out


def _cell(frame: pd.DataFrame, index: int | None, column: str | None, default: Any) -> Any:
    if index is None or column is None or column not in frame.columns:
        return default
    return frame.at[index, column]


def _findings(
    err: SchemaErrors,
    frame: pd.DataFrame,
    *,
    campaigns: list[str],
    locate: Callable[[str, str | None, int | None], tuple[str, str, int | None, dict]],
    details: Callable[[str, int | None], dict[str, Any]] | None = None,
) -> list[_Finding]:
    """Turn a lazy validation error on ``frame`` into findings.

    Parameters
    ----------
    err : SchemaErrors
    frame : DataFrame
        The validated frame, with a 0..n-1 index.
    campaigns : list of str
        Campaigns a table-wide failure (no row) is charged to.
    locate : callable
        ``(check, column, index) -> (check id, file, row, extra fields)``: renames Pandera's
        structural checks and maps the frame index to the source file row.
    details : callable, optional
        ``(check, index) -> fields`` computed from the frame for some checks; a ``value`` field
        replaces the failing value.
    """
    out = []
    for check, column, index, failure_value in _failures(err):
        check_id, file, row, extra = locate(check, column, index)
        value = _cell(frame, index, column, failure_value)
        fields = dict(frame.loc[index].items()) if index is not None else {}
        fields.update(extra)
        detail = details(check_id, index) if details is not None else {}
        value = detail.pop("value", value)
        fields.update(detail)
        row_campaign = _cell(frame, index, "campaign_id", None)
        for campaign in [row_campaign] if row_campaign is not None else campaigns:
            out.append(_Finding(str(campaign), file, check_id, column, row, value, fields))
    return out


def _row(value: Any) -> int | None:
    return None if value is None or pd.isna(value) else int(value)


# --------------------------------------------------------------------------- campaign metadata


def sensor_table(campaigns: pd.DataFrame) -> pd.DataFrame:
    """Return the sensor maps of all campaigns as one long table (:class:`SensorsModel`).

    Parameters
    ----------
    campaigns : DataFrame
        Ingested campaigns (``campaign_id``, ``sensors_json``).

    Returns
    -------
    DataFrame
        Columns ``campaign_id, sensor, role, location, type`` (str; a missing role is ``""``,
        missing location/type are missing). Campaigns whose map is not a JSON object are left
        out (``json_readable`` / ``sensors_declared`` report them).
    """
    records: list[dict[str, Any]] = []
    for campaign_id, text in zip(campaigns["campaign_id"], campaigns["sensors_json"], strict=True):
        sensors = parse_json(text)
        if not isinstance(sensors, dict):
            continue
        for name, spec in sensors.items():
            spec = spec if isinstance(spec, dict) else {}
            records.append(
                {
                    "campaign_id": str(campaign_id),
                    "sensor": str(name),
                    "role": "" if spec.get("role") is None else str(spec["role"]),
                    "location": None if spec.get("location") is None else str(spec["location"]),
                    "type": None if spec.get("type") is None else str(spec["type"]),
                }
            )
    columns = ["campaign_id", "sensor", "role", "location", "type"]
    return pd.DataFrame(
        {c: pd.Series([r[c] for r in records], dtype="str") for c in columns}, columns=columns
    )


def validate_campaign_table(campaigns: pd.DataFrame, limits: ValidationLimits) -> list[Problem]:
    """Check campaign metadata and sensor maps (file ``campaign.yaml``).

    Checks: ``kind_known``, ``split_known``, ``season_known``, ``campaign_id_format``,
    ``campaign_id_unique``, ``stroke_positive``, ``json_readable``, ``sensors_declared``,
    ``displacement_declared``, ``displacement_axis_known``, ``axis_declared``,
    ``sensor_role_known``, ``single_ambient`` (plus Pandera's column/dtype checks).

    Parameters
    ----------
    campaigns : DataFrame
        Ingested campaigns, one row per campaign.
    limits : ValidationLimits
        Used for message fields only.

    Returns
    -------
    list of Problem
    """
    if campaigns.empty:
        return []
    frame = campaigns.reset_index(drop=True)
    ids = [str(c) for c in frame["campaign_id"]] if "campaign_id" in frame else []
    yaml_keys = {"axis_name": "axis.name", "stroke_mm": "axis.stroke_mm"}

    def locate(check: str, column: str | None, index: int | None):
        key = yaml_keys.get(column or "", (column or "").removesuffix("_json"))
        check_id = "metadata_missing" if check == "not_nullable" else check
        return check_id, CAMPAIGN_FILE, None, {"yaml_key": key}

    findings: list[_Finding] = []
    try:
        CampaignsModel.validate(frame, lazy=True)
    except SchemaErrors as err:
        findings += _findings(err, frame, campaigns=ids, locate=locate)

    if {"campaign_id", "sensors_json"} <= set(frame.columns):
        sensors = sensor_table(frame)

        def ambient_details(check: str, index: int | None) -> dict[str, Any]:
            if check != "single_ambient" or index is None:
                return {}
            same = sensors["campaign_id"] == sensors.at[index, "campaign_id"]
            names = sensors.loc[same & (sensors["role"] == AMBIENT_ROLE), "sensor"]
            return {"value": [str(n) for n in names]}

        try:
            SensorsModel.validate(sensors, lazy=True)
        except SchemaErrors as err:
            findings += _findings(
                err,
                sensors,
                campaigns=ids,
                locate=lambda check, column, index: (check, CAMPAIGN_FILE, None, {}),
                details=ambient_details,
            )
    return _problems(findings, limits)


# --------------------------------------------------------------------------- samples


def _declared_axes(campaign: Mapping[str, Any]) -> list[str]:
    axes = parse_json(campaign.get("displacement_json"))
    if not isinstance(axes, dict):
        return []
    return [str(a) for a in axes if str(a) in DISPLACEMENT_AXES]


def _sensor_map(campaign: Mapping[str, Any]) -> dict[str, Any]:
    sensors = parse_json(campaign.get("sensors_json"))
    return {str(k): v for k, v in sensors.items()} if isinstance(sensors, dict) else {}


def campaign_samples(samples: pd.DataFrame, campaign_id: str) -> pd.DataFrame:
    """Return one campaign's samples in file order, with only the columns holding its data.

    Parameters
    ----------
    samples : DataFrame
        Ingested samples of all campaigns (union of their columns).
    campaign_id : str

    Returns
    -------
    DataFrame
        Rows of the campaign sorted by ``source_row``, index 0..n-1; the base columns plus every
        temperature / displacement column with at least one value for this campaign.
    """
    rows = samples.loc[samples["campaign_id"] == campaign_id].sort_values("source_row")
    rows = rows.reset_index(drop=True)
    keep = [c for c in rows.columns if c in SAMPLE_BASE_COLUMNS or rows[c].notna().any()]
    return rows[keep]


def validate_samples(
    campaign: Mapping[str, Any], samples: pd.DataFrame, limits: ValidationLimits
) -> list[Problem]:
    """Validate one campaign's samples against its sensor map and displacement axes.

    Checks (ids): ``sensor_column_missing``, ``unknown_temperature_column``,
    ``displacement_column_missing``, ``unknown_displacement_column``, ``time_increasing``,
    ``sampling_interval``, ``temperature_range``, ``ds18b20_power_on``,
    ``ds18b20_disconnected``, ``stuck_sensor``, ``spike``, ``displacement_range``,
    ``missing_value``, ``no_samples``.

    Parameters
    ----------
    campaign : mapping
        The campaign's row of the campaigns table (``campaign_id``, ``kind``, ``sensors_json``,
        ``displacement_json``).
    samples : DataFrame
        Ingested samples (any campaigns; only this campaign's rows are used).
    limits : ValidationLimits

    Returns
    -------
    list of Problem
        Files ``temperature.csv`` (rows = ``source_row``) and ``displacement.csv`` (rows =
        ``disp_<A>_source_row``).
    """
    campaign_id = str(campaign["campaign_id"])
    frame = campaign_samples(samples, campaign_id)
    if frame.empty:
        return _problems(
            [_Finding(campaign_id, TEMPERATURE_FILE, "no_samples", None, None, None)], limits
        )
    schema = campaign_samples_schema(
        str(campaign.get("kind")), _sensor_map(campaign), _declared_axes(campaign), limits
    )

    def locate(check: str, column: str | None, index: int | None):
        match = DISPLACEMENT_COLUMN_RE.match(column or "") or DISPLACEMENT_ROW_COLUMN_RE.match(
            column or ""
        )
        if match:
            axis = match.group(1)
            row = _row(_cell(frame, index, displacement_row_column(axis), None))
            renamed = {
                "column_in_dataframe": "displacement_column_missing",
                "column_in_schema": "unknown_displacement_column",
            }
            return renamed.get(check, check), DISPLACEMENT_FILE, row, {"axis": axis}
        renamed = {
            "column_in_dataframe": "sensor_column_missing",
            "column_in_schema": "unknown_temperature_column",
        }
        if column in SAMPLE_BASE_COLUMNS:
            renamed = {}
        renamed["not_nullable"] = "missing_value"
        row = _row(_cell(frame, index, "source_row", None))
        return renamed.get(check, check), TEMPERATURE_FILE, row, {}

    def details(check: str, index: int | None) -> dict[str, Any]:
        if index is None or index == 0 or check not in ("time_increasing", "sampling_interval"):
            return {}
        elapsed = frame["elapsed_s"]
        previous = float(elapsed.iloc[index - 1])
        if check == "time_increasing":
            return {"previous": previous}
        return {
            "value": round(float(elapsed.iloc[index]) - previous, 9),  # the interval, s
            "median_interval": round(check_functions.median_interval(elapsed), 9),
        }

    try:
        schema.validate(frame, lazy=True)
    except SchemaErrors as err:
        findings = _findings(err, frame, campaigns=[campaign_id], locate=locate, details=details)
        # a disp_<A>_source_row column only accompanies disp_<A>: report the axis once
        findings = [
            f
            for f in findings
            if not (
                f.check == "unknown_displacement_column"
                and DISPLACEMENT_ROW_COLUMN_RE.match(f.column or "")
            )
        ]
        return _problems(findings, limits)
    return []


# --------------------------------------------------------------------------- laser


def validate_laser(
    campaign_id: str, laser: pd.DataFrame, limits: ValidationLimits
) -> list[Problem]:
    """Validate the laser runs of one axis_positioning campaign (file ``laser.csv``).

    Checks (ids): ``laser_direction`` (only '+'/'-'), ``laser_run_one_direction``,
    ``laser_run_one_time``, ``laser_elapsed_nonnegative``, ``laser_cold_run`` (a run at
    elapsed_min 0), ``laser_bidirectional`` (both directions at each elapsed_min),
    ``laser_target_set`` / ``laser_target_missing`` (every run measures the targets of the cold
    run within ``laser_target_tolerance_mm``), ``missing_value``, ``no_laser``.

    Parameters
    ----------
    campaign_id : str
    laser : DataFrame
        Ingested laser rows (any campaigns; only this campaign's rows are used).
    limits : ValidationLimits

    Returns
    -------
    list of Problem
        Rows are laser.csv data rows (``source_row``).
    """
    frame = laser.loc[laser["campaign_id"] == campaign_id].sort_values("source_row")
    frame = frame.reset_index(drop=True)
    if frame.empty:
        return _problems([_Finding(campaign_id, LASER_FILE, "no_laser", None, None, None)], limits)

    def locate(check: str, column: str | None, index: int | None):
        check_id = "missing_value" if check == "not_nullable" else check
        return check_id, LASER_FILE, _row(_cell(frame, index, "source_row", None)), {}

    def details(check: str, index: int | None) -> dict[str, Any]:
        if check != "laser_target_missing" or index is None:
            return {}
        run = int(frame.at[index, "run"])
        missing = check_functions.missing_targets(frame, run, limits.laser_target_tolerance_mm)
        return {"value": missing}

    try:
        laser_schema(limits).validate(frame, lazy=True)
    except SchemaErrors as err:
        findings = _findings(err, frame, campaigns=[campaign_id], locate=locate, details=details)
        return _problems(findings, limits)
    return []


# --------------------------------------------------------------------------- all tables


def problems_from_ingest(problems: pd.DataFrame) -> list[Problem]:
    """Turn the rows of ``problems.parquet`` into report problems (one each, text kept)."""
    out = []
    for rec in problems.to_dict("records"):
        column = rec.get("column")
        out.append(
            Problem(
                campaign=str(rec["campaign_id"]),
                file=str(rec["file"]),
                row=_row(rec.get("row")),
                column=None if column is None or pd.isna(column) else str(column),
                check=str(rec["check"]),
                value=None,
                message=str(rec["problem"]),
                action=str(rec["action"]),
            )
        )
    return out


def validate_tables(
    campaigns: pd.DataFrame,
    samples: pd.DataFrame,
    laser: pd.DataFrame,
    problems: pd.DataFrame,
    limits: ValidationLimits,
) -> ValidationResult:
    """Validate every campaign of the ingested tables.

    Parameters
    ----------
    campaigns, samples, laser, problems : DataFrame
        The four tables written by ``ingest`` (``data/ingested/*.parquet``).
    limits : ValidationLimits

    Returns
    -------
    ValidationResult
        All problems: ingest's, campaign.yaml's, samples' (every campaign) and laser's
        (axis_positioning campaigns). :data:`FOLLOW_ON_CHECKS` are left out when ingest
        already reported a file-level problem (no row) with that file, e.g. a missing file.
        A campaign with data but no campaigns row and no ingest problem gets
        ``campaign_metadata_missing``.
    """
    found = problems_from_ingest(problems)
    unreadable = {(p.campaign, p.file) for p in found if p.row is None}
    found += validate_campaign_table(campaigns, limits)
    for campaign in campaigns.to_dict("records"):
        campaign_id = str(campaign["campaign_id"])
        own = validate_samples(campaign, samples, limits)
        if campaign.get("kind") == AXIS_KIND:
            own += validate_laser(campaign_id, laser, limits)
        found += [
            p
            for p in own
            if not (p.check in FOLLOW_ON_CHECKS and (p.campaign, p.file) in unreadable)
        ]
    known = {str(c) for c in campaigns["campaign_id"]} | {p.campaign for p in found}
    orphans = [
        _Finding(str(c), file, "campaign_metadata_missing", None, None, None)
        for table, file in ((samples, TEMPERATURE_FILE), (laser, LASER_FILE))
        for c in pd.unique(table["campaign_id"])
        if str(c) not in known
    ]
    found += _problems(orphans, limits)
    all_ids = known | {f.campaign for f in orphans}
    ordered = sorted(found, key=lambda p: p.campaign)  # stable: keeps the order within one
    return ValidationResult(campaigns=tuple(sorted(all_ids)), problems=tuple(ordered))


def drop_empty_columns(samples: pd.DataFrame) -> pd.DataFrame:
    """Return ``samples`` without temperature/displacement columns that hold no value."""
    keep = [c for c in samples.columns if c in SAMPLE_BASE_COLUMNS or samples[c].notna().any()]
    return samples[keep]


def select_valid(
    campaigns: pd.DataFrame,
    samples: pd.DataFrame,
    laser: pd.DataFrame,
    valid: Iterable[str],
) -> dict[str, dict[str, pd.DataFrame]]:
    """Split the valid campaigns' rows into the spindle and axis outputs.

    Parameters
    ----------
    campaigns, samples, laser : DataFrame
        Ingested tables.
    valid : iterable of str
        Campaign ids to keep.

    Returns
    -------
    dict
        ``{"spindle": {"campaigns", "samples"}, "axis": {"campaigns", "samples", "laser"}}``:
        the rows of the valid campaigns of that kind, in their ingested order; samples columns
        without any value for the kept campaigns are dropped (the base columns stay).
    """
    valid = set(valid)
    out: dict[str, dict[str, pd.DataFrame]] = {}
    for name, kind in (("spindle", SPINDLE_KIND), ("axis", AXIS_KIND)):
        kept = campaigns.loc[campaigns["campaign_id"].isin(valid) & (campaigns["kind"] == kind)]
        ids = set(kept["campaign_id"])
        tables = {
            "campaigns": kept.reset_index(drop=True),
            "samples": drop_empty_columns(
                samples.loc[samples["campaign_id"].isin(ids)].reset_index(drop=True)
            ),
        }
        if kind == AXIS_KIND:
            tables["laser"] = laser.loc[laser["campaign_id"].isin(ids)].reset_index(drop=True)
        out[name] = tables
    return out


def build_report(result: ValidationResult) -> dict[str, Any]:
    """Return the content of ``reports/validation.json``."""
    return {
        "summary": {
            "campaigns": len(result.campaigns),
            "valid": result.valid,
            "quarantined": result.quarantined,
        },
        "problems": [p.to_dict() for p in result.problems],
    }


def require_valid(result: ValidationResult, report_path: Path | str) -> None:
    """Raise :class:`NoValidCampaignError` (naming the report) when no campaign is valid."""
    if not result.campaigns:
        raise NoValidCampaignError(
            "validate: no campaign found in data/ingested; add campaign folders under "
            f"data/raw/ (see data-contract.md) and rerun dvc repro (report: {report_path})"
        )
    if not result.valid:
        raise NoValidCampaignError(
            f"validate: no valid campaign: all {len(result.campaigns)} campaigns are quarantined "
            f"({', '.join(result.quarantined)}); see {report_path} for every problem and what to "
            "do, fix the raw files and rerun dvc repro"
        )


def quarantine_summary(result: ValidationResult, campaign_id: str) -> str:
    """Return a one-line summary of a quarantined campaign's problems, for the log."""
    own = [p for p in result.problems if p.campaign == campaign_id]
    counts: dict[str, int] = {}
    for p in own:
        label = f"{p.check} ({p.file}{' ' + p.column if p.column else ''})"
        counts[label] = counts.get(label, 0) + 1
    parts = [f"{label} x{n}" if n > 1 else label for label, n in counts.items()]
    return f"{len(own)} problem(s): " + "; ".join(parts)


# --------------------------------------------------------------------------- I/O


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise FileNotFoundError(f"{path} not found; run the ingest stage first (dvc repro)")
    return pd.read_parquet(path)


def main(argv: list[str] | None = None) -> int:
    """Run the validate stage; return 0, or 1 when no campaign is valid.

    Reads ``params.yaml`` ``validate:`` and ``data/ingested/*.parquet``; writes
    ``data/validated/{spindle,axis}/*.parquet`` and ``reports/validation.json``.
    """
    parser = argparse.ArgumentParser(
        prog="thermal validate",
        description="Validate the ingested campaigns (Pandera); quarantine every campaign with "
        f"a problem; write data/validated/ and {paths.VALIDATION_REPORT}.",
    )
    parser.parse_args(argv)
    limits = limits_from_params(load_section("validate"))
    campaigns = _read(paths.INGESTED_CAMPAIGNS)
    samples = _read(paths.INGESTED_SAMPLES)
    laser = _read(paths.INGESTED_LASER)
    problems = _read(paths.INGESTED_PROBLEMS)

    result = validate_tables(campaigns, samples, laser, problems, limits)
    for campaign_id in result.quarantined:
        logger.warning(
            "campaign %s quarantined: %s; see %s",
            campaign_id,
            quarantine_summary(result, campaign_id),
            paths.VALIDATION_REPORT,
        )
    paths.VALIDATION_REPORT.parent.mkdir(parents=True, exist_ok=True)
    paths.VALIDATION_REPORT.write_text(
        json.dumps(build_report(result), indent=2, ensure_ascii=False) + "\n", encoding="utf-8"
    )
    try:
        require_valid(result, paths.VALIDATION_REPORT)
    except NoValidCampaignError as err:
        logger.error("%s", err)
        return 1

    outputs = select_valid(campaigns, samples, laser, result.valid)
    for name, directory in (("spindle", paths.VALIDATED_SPINDLE), ("axis", paths.VALIDATED_AXIS)):
        directory.mkdir(parents=True, exist_ok=True)
        for table, frame in outputs[name].items():
            frame.to_parquet(directory / OUTPUT_FILES[table], index=False)
    logger.info(
        "validate: %d of %d campaigns valid (%s); %d quarantined; report %s",
        len(result.valid),
        len(result.campaigns),
        ", ".join(result.valid),
        len(result.quarantined),
        paths.VALIDATION_REPORT,
    )
    return 0

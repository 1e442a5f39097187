"""Group findings into problems and word them with the check's text.

Consecutive rows of the same campaign, file, check and column become one :class:`Problem`
whose message names the whole run of rows; the limits of ``params.yaml`` are available to the
templates of :mod:`pipeline.validation.texts`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd

from pipeline.validation.findings import Finding
from pipeline.validation.problems import Problem
from pipeline.validation.texts import TemplateFields, text_for
from schemas import ValidationLimits


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


def span_text(noun: str, first: int, last: int) -> str:
    """Return ``row 3`` or ``rows 1-2`` (``noun`` "row"/"line") for a run of numbers."""
    return f"{noun} {first}" if first == last else f"{noun}s {first}-{last}"


def _limit_fields(limits: ValidationLimits) -> dict[str, Any]:
    """Return the template fields of the check limits (units as in the messages)."""
    return {
        "temperature_low": limits.temperature_range_degC[0],
        "temperature_high": limits.temperature_range_degC[1],
        "interval_tolerance_pct": round(100 * limits.interval_tolerance, 6),
        "stuck_min_other_change": limits.stuck_min_other_change_degC,
        "stuck_min_minutes": f"{limits.stuck_min_minutes:g}",
        "spike_threshold": limits.spike_threshold_degC,
        "displacement_low": limits.displacement_range_um[0],
        "displacement_high": limits.displacement_range_um[1],
        "laser_target_tolerance": limits.laser_target_tolerance_mm,
        "laser_deviation_low": limits.laser_deviation_range_um[0],
        "laser_deviation_high": limits.laser_deviation_range_um[1],
        "min_samples": limits.min_samples,
        "air_temperature_max": limits.air_temperature_max_degC,
        "displacement_min_span": limits.displacement_min_span_um,
        "min_program_coverage_pct": round(100 * limits.min_program_coverage, 6),
        "max_bridged_gap_s": f"{limits.max_bridged_gap_s:g}",
    }


def render(group: list[Finding], limits: ValidationLimits) -> Problem:
    """Turn a group of findings (same campaign, file, check, column) into one problem.

    Parameters
    ----------
    group : list of Finding
        Non-empty, in row order; the first finding's context fields are used.
    limits : ValidationLimits
        Message fields only.

    Returns
    -------
    Problem
        ``row`` is the group's first row (None when the check is not row-level); ``value`` the
        single distinct value, or the list of distinct values in order.
    """
    first = group[0]
    text = text_for(first.check)
    rows = [f.row for f in group if f.row is not None] if text.row_level else []
    values: list[Any] = []
    for finding in group:
        value = _plain(finding.value)
        if value not in values:
            values.append(value)
    value = values[0] if len(values) == 1 else values
    location = f"{first.campaign}/{first.file}"
    rows_text = span_text("row", rows[0], rows[-1]) if rows else ""
    if rows:
        where = f"{location} {rows_text} ({span_text('line', rows[0] + 1, rows[-1] + 1)})"
    else:
        where = location
    fields = TemplateFields(
        {
            **_limit_fields(limits),
            **{k: _field_text(v) for k, v in first.fields.items()},
            "campaign": first.campaign,
            "file": first.file,
            "column": first.column if first.column is not None else "?",
            "check": first.check,
            "value": _text(value),
            "rows": rows_text,
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


def problems_from_findings(findings: Iterable[Finding], limits: ValidationLimits) -> list[Problem]:
    """Group consecutive rows of the same campaign/file/check/column and render them.

    Identical findings (e.g. several temperature rows pointing at one displacement row) are
    reported once; checks with ``collapse`` give one problem per campaign.

    Parameters
    ----------
    findings : iterable of Finding
    limits : ValidationLimits
        Message fields only.

    Returns
    -------
    list of Problem
        Sorted by campaign, file, check, column and row.
    """
    unique: dict[tuple, Finding] = {}
    for f in findings:
        key = (f.campaign, f.file, f.check, f.column, f.row, repr(_plain(f.value)))
        unique.setdefault(key, f)

    def order(f: Finding) -> tuple:
        return (f.campaign, f.file, f.check, f.column or "", -1 if f.row is None else f.row)

    groups: list[list[Finding]] = []
    for f in sorted(unique.values(), key=order):
        if groups:
            last = groups[-1][-1]
            same = (last.campaign, last.file, last.check) == (f.campaign, f.file, f.check)
            if same and text_for(f.check).collapse:
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
    return [render(g, limits) for g in groups]

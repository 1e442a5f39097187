"""Validate one campaign's samples (files ``temperature.csv`` and ``displacement.csv``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pandas as pd
from pandera.errors import SchemaErrors

from pipeline.validation.findings import Finding, cell, findings_from_errors
from pipeline.validation.problems import DISPLACEMENT_FILE, TEMPERATURE_FILE, Problem, row_number
from pipeline.validation.rendering import problems_from_findings
from pipeline.validation.tables import campaign_samples
from schemas import ValidationLimits, campaign_samples_schema, parse_json
from schemas import checks as check_functions
from schemas.vocabulary import (
    DISPLACEMENT_COLUMN_RE,
    DISPLACEMENT_ROW_COLUMN_RE,
    SAMPLE_BASE_COLUMNS,
    displacement_row_column,
    is_displacement_name,
)

_DISPLACEMENT_CHECK_IDS = {
    "column_in_dataframe": "displacement_column_missing",
    "column_in_schema": "unknown_displacement_column",
}
"""Pandera's column presence checks on ``disp_<A>`` columns -> problem ids."""

_TEMPERATURE_CHECK_IDS = {
    "column_in_dataframe": "sensor_column_missing",
    "column_in_schema": "unknown_temperature_column",
    "not_nullable": "missing_value",
}
"""Pandera's structural checks on temperature columns -> problem ids."""

_BASE_CHECK_IDS = {"not_nullable": "missing_value"}
"""Pandera's structural checks on the base columns (``elapsed_s``, ...) -> problem ids."""


def _declared_axes(campaign: Mapping[str, Any]) -> list[str]:
    """Return the validly named axes declared under ``displacement:``, in yaml order."""
    axes = parse_json(campaign.get("displacement_json"))
    if not isinstance(axes, dict):
        return []
    return [str(a) for a in axes if is_displacement_name(a)]


def _sensor_map(campaign: Mapping[str, Any]) -> dict[str, Any]:
    """Return the sensor map ``{name: {role, location, type}}`` (empty when unreadable)."""
    sensors = parse_json(campaign.get("sensors_json"))
    return {str(k): v for k, v in sensors.items()} if isinstance(sensors, dict) else {}


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
        return problems_from_findings(
            [Finding(campaign_id, TEMPERATURE_FILE, "no_samples")], limits
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
            row = row_number(cell(frame, index, displacement_row_column(axis)))
            return _DISPLACEMENT_CHECK_IDS.get(check, check), DISPLACEMENT_FILE, row, {"axis": axis}
        check_ids = _BASE_CHECK_IDS if column in SAMPLE_BASE_COLUMNS else _TEMPERATURE_CHECK_IDS
        row = row_number(cell(frame, index, "source_row"))
        return check_ids.get(check, check), TEMPERATURE_FILE, row, {}

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
        findings = findings_from_errors(
            err, frame, campaigns=[campaign_id], locate=locate, details=details
        )
        # a disp_<A>_source_row column only accompanies disp_<A>: report the axis once
        findings = [
            f
            for f in findings
            if not (
                f.check == "unknown_displacement_column"
                and DISPLACEMENT_ROW_COLUMN_RE.match(f.column or "")
            )
        ]
        return problems_from_findings(findings, limits)
    return []

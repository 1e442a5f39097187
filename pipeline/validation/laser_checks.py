"""Validate the laser runs of one axis_positioning campaign (file ``laser.csv``)."""

from __future__ import annotations

from typing import Any

import pandas as pd
from pandera.errors import SchemaErrors

from pipeline.validation.findings import Finding, cell, findings_from_errors
from pipeline.validation.problems import LASER_FILE, Problem, row_number
from pipeline.validation.rendering import problems_from_findings
from pipeline.validation.tables import campaign_rows
from schemas import ValidationLimits, laser_schema
from schemas import checks as check_functions


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
    frame = campaign_rows(laser, campaign_id)
    if frame.empty:
        return problems_from_findings([Finding(campaign_id, LASER_FILE, "no_laser")], limits)

    def locate(check: str, column: str | None, index: int | None):
        check_id = "missing_value" if check == "not_nullable" else check
        return check_id, LASER_FILE, row_number(cell(frame, index, "source_row")), {}

    def details(check: str, index: int | None) -> dict[str, Any]:
        if check != "laser_target_missing" or index is None:
            return {}
        run = int(frame.at[index, "run"])
        missing = check_functions.missing_targets(frame, run, limits.laser_target_tolerance_mm)
        return {"value": missing}

    try:
        laser_schema(limits).validate(frame, lazy=True)
    except SchemaErrors as err:
        findings = findings_from_errors(
            err, frame, campaigns=[campaign_id], locate=locate, details=details
        )
        return problems_from_findings(findings, limits)
    return []

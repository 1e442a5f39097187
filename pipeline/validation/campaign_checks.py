"""Validate the campaign metadata and sensor maps (file ``campaign.yaml``)."""

from __future__ import annotations

from typing import Any

import pandas as pd
from pandera.errors import SchemaErrors

from pipeline.validation.findings import Finding, findings_from_errors
from pipeline.validation.problems import CAMPAIGN_FILE, Problem
from pipeline.validation.rendering import problems_from_findings
from schemas import CampaignsModel, SensorsModel, ValidationLimits, parse_json
from schemas.vocabulary import AMBIENT_ROLE

_YAML_KEYS = {"axis_name": "axis.name", "stroke_mm": "axis.stroke_mm"}
"""campaigns columns whose campaign.yaml key is not the column name (minus ``_json``)."""


def _optional_text(value: Any) -> str | None:
    return None if value is None else str(value)


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
                    "role": _optional_text(spec.get("role")) or "",
                    "location": _optional_text(spec.get("location")),
                    "type": _optional_text(spec.get("type")),
                }
            )
    columns = ["campaign_id", "sensor", "role", "location", "type"]
    return pd.DataFrame(
        {c: pd.Series([r[c] for r in records], dtype="str") for c in columns}, columns=columns
    )


def _locate_campaign(check: str, column: str | None, index: int | None):
    key = _YAML_KEYS.get(column or "", (column or "").removesuffix("_json"))
    check_id = "metadata_missing" if check == "not_nullable" else check
    return check_id, CAMPAIGN_FILE, None, {"yaml_key": key}


def _locate_sensor(check: str, column: str | None, index: int | None):
    return check, CAMPAIGN_FILE, None, {}


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

    findings: list[Finding] = []
    try:
        CampaignsModel.validate(frame, lazy=True)
    except SchemaErrors as err:
        findings += findings_from_errors(err, frame, campaigns=ids, locate=_locate_campaign)

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
            findings += findings_from_errors(
                err, sensors, campaigns=ids, locate=_locate_sensor, details=ambient_details
            )
    return problems_from_findings(findings, limits)

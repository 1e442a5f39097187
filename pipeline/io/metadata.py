"""Read ``campaign.yaml`` of a campaign folder into one row of the campaigns table.

Never raises on content: a missing or unreadable file, a missing required key
(``missing_key``), a value of the wrong type or a misspelt key (``wrong_type``,
``misspelt_key``: checked on the model of :mod:`pipeline.io.campaign_file`), an id that is not
a plain name (``campaign_id_unsafe``) or differs from the folder, an unknown kind or a start
that is not ISO 8601 become problems through ``report`` (:data:`pipeline.io.files.Report`); the
row is still built, a value of the wrong type left empty, so that validation can report every
problem of the campaign at once.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from pipeline.io.campaign_file import file_problems
from pipeline.io.files import Report, read_text
from schemas.contract import CONTRACT_FILES
from schemas.vocabulary import CAMPAIGN_ID_RE, SAMPLE_BASE_COLUMNS, SEASON_OF_MONTH

REQUIRED_KEYS = {
    "campaign_id": "campaign_id: <the folder name>",
    "kind": "kind: spindle_drift or kind: axis_positioning",
    "start": "start: YYYY-MM-DDTHH:MM:SS, the local time of the first sample",
    "sensors": "one entry per temperature.csv column under sensors:, e.g. "
    "T1: {role: spindle_front_bearing}",
}
"""Keys every campaign.yaml must have, with the hint the ``missing_key`` problem gives."""


def read_metadata(path: Path, report: Report) -> dict[str, Any] | None:
    """Return the mapping of ``campaign.yaml``, or None after reporting why there is none."""
    if not path.is_file():
        report(
            path.name,
            None,
            None,
            "missing_file",
            "campaign.yaml is missing",
            f"add {path} (see docs/data-contract.md) or remove the folder",
        )
        return None
    text = read_text(path, report)
    if text is None:
        return None
    try:
        content = yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "context_mark", None) or getattr(error, "problem_mark", None)
        row = None if mark is None else mark.line + 1
        parts = (getattr(error, "context", None), getattr(error, "problem", None))
        detail = "; ".join(p for p in parts if p) or " ".join(str(error).split())
        report(path.name, row, None, "unreadable_yaml", error=detail)
        return None
    if not isinstance(content, dict):
        report(
            path.name,
            None,
            None,
            "unreadable_yaml",
            "campaign.yaml is not a mapping",
            "write the keys of docs/data-contract.md (campaign_id, kind, sensors, ...)",
        )
        return None
    return content


def campaign_row(folder: Path, meta: dict[str, Any], report: Report) -> dict[str, Any]:
    """Return the campaigns-table row of a campaign from its ``campaign.yaml`` mapping.

    Parameters
    ----------
    folder : Path
        The campaign folder; its name is the campaign id.
    meta : dict
        The parsed ``campaign.yaml``.
    report : callable
        Receives every problem found (file ``campaign.yaml``, row None, column = the key).

    Returns
    -------
    dict
        The columns of :class:`schemas.CampaignsModel`; a missing or malformed value is left
        empty (``""``, NaT, NaN, ``{}``) for validation to report as well.
    """
    campaign_id = folder.name
    for key, hint in REQUIRED_KEYS.items():
        if meta.get(key) is None:
            report("campaign.yaml", None, key, "missing_key", hint=hint)
    file_problems(meta, report)
    _check_campaign_id(campaign_id, meta.get("campaign_id"), report)
    kind = "" if meta.get("kind") is None else str(meta["kind"])
    if kind and kind not in CONTRACT_FILES:
        report("campaign.yaml", None, "kind", "unknown_kind", value=repr(kind))
    start = parse_start(meta.get("start"))
    if meta.get("start") is not None and pd.isna(start):
        report("campaign.yaml", None, "start", "bad_start", value=repr(meta.get("start")))
    season = meta.get("season")
    season_derived = season is None
    if season_derived:
        season = SEASON_OF_MONTH[start.month] if not pd.isna(start) else ""
    sensors = _sensors(meta, report)
    axis = _typed(meta, "axis", dict) or {}
    return {
        "campaign_id": campaign_id,
        "kind": kind,
        "machine": _optional_text(meta.get("machine")) or "",  # optional: "" when not given
        "start": start,
        "season": str(season),
        "season_derived": bool(season_derived),
        "synthetic": bool(_typed(meta, "synthetic", bool)),
        "split": str(meta.get("split", "train")),
        "start_state": _optional_text(meta.get("start_state")),
        "follows": _optional_text(meta.get("follows")),
        "axis_name": None if axis.get("name") is None else str(axis["name"]),
        "stroke_mm": _stroke(axis),
        "sensors_json": to_json(sensors),
        "displacement_json": to_json(_entries(_typed(meta, "displacement", dict) or {})),
        "spindle_program_json": to_json(_typed(meta, "spindle_program", list) or []),
        "heat_loads_json": to_json(_typed(meta, "heat_loads", list) or []),
        "has_spindle_log": (folder / "spindle.csv").is_file(),
        "source_dir": str(folder),
    }


def parse_start(value: Any) -> pd.Timestamp:
    """Return ``start:`` as a naive timestamp (local time), NaT unless it is ISO 8601.

    YAML gives an unquoted date-time as a ``datetime`` and a date as a ``date`` (midnight);
    text must be ISO 8601 (words such as "now" are not accepted); a time zone is dropped.
    """
    try:
        if isinstance(value, str):
            value = dt.datetime.fromisoformat(value.strip())
        if not isinstance(value, dt.date):
            return pd.NaT
        start = pd.Timestamp(value)
    except (ValueError, OverflowError):
        return pd.NaT
    return start if start.tzinfo is None else start.tz_localize(None)


def to_json(value: Any) -> str:
    """Return a yaml value as JSON text: keys as text, dates and other objects as text."""
    return json.dumps(_plain(value), sort_keys=True)


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, str | int | float | bool):
        return value
    return str(value)


def _check_campaign_id(campaign_id: str, declared: Any, report: Report) -> None:
    if declared is None:
        return
    if not CAMPAIGN_ID_RE.match(str(declared)):
        report("campaign.yaml", None, "campaign_id", "campaign_id_unsafe", value=repr(declared))
    elif str(declared) != campaign_id:
        report("campaign.yaml", None, "campaign_id", "campaign_id_mismatch", value=repr(declared))


def _typed(meta: dict[str, Any], key: str, kind: type) -> Any:
    """Return ``meta[key]`` if it is of type ``kind``, else None (a wrong type is reported)."""
    value = meta.get(key)
    return value if isinstance(value, kind) else None


def _sensors(meta: dict[str, Any], report: Report) -> dict[str, Any]:
    """Return the sensor map ``{name: {role, location, type}}`` (names as text)."""
    sensors = _typed(meta, "sensors", dict)
    if sensors is None:
        return {}
    if not sensors:
        report("campaign.yaml", None, "sensors", "no_sensors")
    out = _entries(sensors)
    for name in [n for n in out if n in SAMPLE_BASE_COLUMNS or n.startswith("disp_")]:
        report("campaign.yaml", None, f"sensors.{name}", "reserved_column", name=name)
        del out[name]
    return out


def _entries(mapping: dict) -> dict[str, dict]:
    """Return ``{name: entry}`` with text names; an entry that is not a mapping is empty."""
    return {str(name): entry if isinstance(entry, dict) else {} for name, entry in mapping.items()}


def _stroke(axis: dict[str, Any]) -> float:
    """Return ``axis: stroke_mm:`` in mm (NaN when absent or not a finite number)."""
    value = axis.get("stroke_mm")
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        return float("nan")
    return float(value)


def _optional_text(value: Any) -> str | None:
    """Return a yaml value as stripped text, None when absent or empty."""
    return None if value is None or str(value).strip() == "" else str(value).strip()

"""Campaign-level plausibility of one campaign's samples: enough of them, in the contract's units.

A campaign logged in the wrong unit passes every per-reading check (68-100 degF are inside the
physical range of degC, 0.001-0.05 mm inside the probe range in um), so each unit is checked on
the whole campaign instead. Checks (ids, limits of ``params.yaml`` ``validate:``):

- ``too_few_samples``: a spindle_drift campaign with fewer than ``min_samples`` temperature rows
  (nothing to model); the unit checks are then skipped. An axis_positioning campaign may have a
  temperature row per laser pass only: its structure is checked by the laser checks.
- ``temperature_unit`` (degF for degC): the campaign's air reference -- the median reading of
  its ambient sensor, or without one the median of its coolest sensor -- is above
  ``air_temperature_max_degC`` (45). A warm machine does not trip it: its spindle and motor may
  run at 40-60 degC, but the air (and the coolest part of the structure) stays below 45 degC
  even in a summer workshop, whereas a 20 degC workshop reads 68 degF. A workshop colder than
  7 degC (45 degF) logged in degF is not detected. Without an ambient sensor, a campaign whose
  every sensor stays above 45 degC (a warm stretch logged by spindle sensors only) is taken for
  degF: give the air sensor the role ambient.
- ``displacement_unit`` (mm for um): every declared displacement axis spans less than
  ``displacement_min_span_um`` (0.2 um) peak to peak while a temperature sensor rose (max - min)
  by ``unit_check_min_rise_degC`` (2 K) or more. A heating machine drifts by micrometres to tens
  of micrometres along its main axis (and an eddy-current probe's noise alone spans more than
  0.2 um); the same drift in mm spans 0.001-0.2. One quiet probe beside a moving one (an X probe
  on a symmetric spindle) is normal and passes; a campaign whose every probe reads a constant
  fails it as well.
- ``time_unit`` (minutes for seconds): for a campaign without ``spindle.csv``, the samples span
  (last - first ``elapsed_s``) less than ``min_program_coverage`` (25 %) of the finite part of
  its ``spindle_program`` (the largest ``to_min``, or the ``from_min`` of the open-ended last
  entry): a log in minutes spans 1/60 of the program. A log cut short before a quarter of its
  program fails it too (correct the program to what ran).

DS18B20 fault codes are left out of the statistics (they are reported by their own checks).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from pipeline.validation.findings import Finding
from pipeline.validation.problems import DISPLACEMENT_FILE, TEMPERATURE_FILE, Problem
from pipeline.validation.rendering import problems_from_findings
from pipeline.validation.tables import campaign_samples
from schemas import ValidationLimits, parse_json
from schemas.vocabulary import (
    AMBIENT_ROLE,
    SPINDLE_KIND,
    displacement_column,
    uses_ds18b20_codes,
)

CHECKS = ("too_few_samples", "temperature_unit", "displacement_unit", "time_unit")
"""The check ids of this module."""


def validate_plausibility(
    campaign: Mapping[str, Any], samples: pd.DataFrame, limits: ValidationLimits
) -> list[Problem]:
    """Check the sample count and the units of one campaign (see the module docstring).

    Parameters
    ----------
    campaign : mapping
        The campaign's row of the campaigns table (``campaign_id``, ``sensors_json``,
        ``displacement_json``, ``spindle_program_json``, ``has_spindle_log``).
    samples, limits : DataFrame, ValidationLimits
        As for :func:`pipeline.validation.sample_checks.validate_samples`.

    Returns
    -------
    list of Problem
        Campaign-level (row None); none when the campaign has no samples (``no_samples``).
    """
    campaign_id = str(campaign["campaign_id"])
    frame = campaign_samples(samples, campaign_id)
    if frame.empty:
        return []
    if campaign.get("kind") == SPINDLE_KIND and len(frame) < limits.min_samples:
        found = [Finding(campaign_id, TEMPERATURE_FILE, "too_few_samples", value=len(frame))]
        return problems_from_findings(found, limits)
    sensors = parse_json(campaign.get("sensors_json"))
    readings = _readings(frame, sensors if isinstance(sensors, dict) else {}, limits)
    found = [
        *_temperature_unit(campaign_id, readings, sensors, limits),
        *_displacement_unit(campaign_id, frame, readings, campaign, limits),
        *_time_unit(campaign_id, frame, campaign, limits),
    ]
    return problems_from_findings(found, limits)


def _readings(frame: pd.DataFrame, sensors: dict, limits: ValidationLimits) -> pd.DataFrame:
    """Return the declared sensors' readings (degC), DS18B20 fault codes as missing."""
    out = {}
    for name, spec in sensors.items():
        if str(name) not in frame.columns:
            continue
        values = frame[str(name)].astype(float)
        sensor_type = spec.get("type") if isinstance(spec, dict) else None
        if uses_ds18b20_codes(sensor_type):
            values = values.where(~values.isin(list(limits.ds18b20_codes)))
        out[str(name)] = values
    return pd.DataFrame(out, index=frame.index)


def _temperature_unit(
    campaign_id: str, readings: pd.DataFrame, sensors: Any, limits: ValidationLimits
) -> list[Finding]:
    medians = readings.median().dropna()
    if medians.empty:
        return []
    roles = {str(n): (s.get("role") if isinstance(s, dict) else None) for n, s in sensors.items()}
    ambient = [name for name in medians.index if roles.get(name) == AMBIENT_ROLE]
    if ambient:
        name, basis = ambient[0], "the ambient sensor"
    else:
        name, basis = str(medians.idxmin()), "the coolest sensor; no sensor has role ambient"
    value = float(medians[name])
    if value <= limits.air_temperature_max_degC:
        return []
    fields = {"basis": basis}
    return [
        Finding(
            campaign_id, TEMPERATURE_FILE, "temperature_unit", name, None, round(value, 4), fields
        )
    ]


def _displacement_unit(
    campaign_id: str,
    frame: pd.DataFrame,
    readings: pd.DataFrame,
    campaign: Mapping[str, Any],
    limits: ValidationLimits,
) -> list[Finding]:
    rise = float((readings.max() - readings.min()).max()) if not readings.empty else np.nan
    axes = parse_json(campaign.get("displacement_json"))
    if not isinstance(axes, dict) or not rise >= limits.unit_check_min_rise_degC:
        return []
    spans = {}
    for axis in map(str, axes):
        column = displacement_column(axis)
        if column in frame.columns and frame[column].notna().sum() >= 2:
            spans[axis] = float(frame[column].max() - frame[column].min())
    if not spans or max(spans.values()) >= limits.displacement_min_span_um:
        return []
    return [
        Finding(
            campaign_id,
            DISPLACEMENT_FILE,
            "displacement_unit",
            axis,
            None,
            round(span, 6),
            {"axis": axis, "rise": round(rise, 2)},
        )
        for axis, span in spans.items()
    ]


def _program_minutes(program_json: object) -> float:
    """Return the end of the finite part of a ``spindle_program`` in minutes (NaN if none).

    It is the largest ``to_min``, or ``from_min`` of an entry without one (the open-ended last
    entry); entries that are not mappings of numbers are skipped (ingest reports them).
    """
    program = parse_json(program_json) if isinstance(program_json, str) else None
    ends = []
    for entry in program if isinstance(program, list) else []:
        if not isinstance(entry, dict):
            continue
        end = entry.get("to_min", entry.get("from_min"))
        if isinstance(end, int | float) and not isinstance(end, bool) and np.isfinite(end):
            ends.append(float(end))
    return max(ends) if ends else float("nan")


def _time_unit(
    campaign_id: str, frame: pd.DataFrame, campaign: Mapping[str, Any], limits: ValidationLimits
) -> list[Finding]:
    if bool(campaign.get("has_spindle_log")):
        return []
    program_min = _program_minutes(campaign.get("spindle_program_json"))
    elapsed = frame["elapsed_s"].astype(float)
    span_min = float(elapsed.max() - elapsed.min()) / 60.0
    if not program_min > 0 or not span_min < limits.min_program_coverage * program_min:
        return []
    steps = elapsed.diff()
    fields = {
        "program_min": f"{program_min:g}",
        "median_interval": f"{float(steps[steps > 0].median()):g}",
    }
    return [
        Finding(
            campaign_id,
            TEMPERATURE_FILE,
            "time_unit",
            "elapsed_s",
            None,
            round(span_min, 3),
            fields,
        )
    ]

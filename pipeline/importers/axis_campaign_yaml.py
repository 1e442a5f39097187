"""The ``campaign.yaml`` skeleton of an ``axis_positioning`` campaign (raw contract version 1).

Only what an importer of laser runs knows is written: id, kind, machine, start and the axis
block. The temperature sensors are left empty with a comment, because they come from the
user's ``temperature.csv``; the validate stage reports ``no_sensors`` until they are listed.
"""

from __future__ import annotations

from datetime import datetime

import yaml

from schemas.vocabulary import AXIS_KIND

SKELETON_OPTIONS = {
    "machine": "--machine",
    "axis": "--axis",
    "stroke_mm": "--stroke-mm",
    "start": "--start",
}
"""Values the skeleton needs and the command-line option giving each."""

SENSORS_COMMENT = """\
# sensors: one entry per column of temperature.csv (degC), which you must add yourself with
# elapsed_s counted from `start`; roles from docs/data-contract.md, e.g.
#   T1: {role: ball_screw, type: DS18B20}
#   T2: {role: ambient, type: DS18B20}
sensors: {}
"""


def skeleton_text(
    campaign_id: str, machine: str, axis: str, stroke_mm: float, start: datetime, source: str
) -> str:
    """Return the text of a ``campaign.yaml`` skeleton for an axis_positioning campaign.

    Parameters
    ----------
    campaign_id : str
        The campaign folder name.
    machine : str
        Free text naming the machine tool.
    axis : str
        Axis measured by the laser (e.g. ``Y``).
    stroke_mm : float, mm
        Travel of the axis.
    start : datetime
        Local time of the cold laser run (``elapsed_min`` 0) and of the first temperature sample.
    source : str
        What the skeleton was written from (one comment line).

    Returns
    -------
    str
        YAML text ending with the commented, empty ``sensors:`` block.
    """
    meta = {
        "campaign_id": campaign_id,
        "kind": AXIS_KIND,
        "machine": machine,
        "start": start.isoformat(timespec="seconds"),
        "synthetic": False,
        "axis": {"name": axis, "stroke_mm": float(stroke_mm)},
    }
    header = f"# Skeleton written by `thermal import rtl` from {source}.\n"
    return header + yaml.safe_dump(meta, sort_keys=False) + SENSORS_COMMENT


def keys_to_add(campaign_id: str, missing: list[str]) -> str:
    """Return the sentence telling the user which ``campaign.yaml`` keys to write by hand.

    Parameters
    ----------
    campaign_id : str
        The campaign folder name.
    missing : list of str
        Keys of :data:`SKELETON_OPTIONS` that were not given.

    Returns
    -------
    str
        One paragraph naming the keys and the options that would write them.
    """
    options = ", ".join(SKELETON_OPTIONS[key] for key in missing)
    return (
        f"no campaign.yaml was written because {options} {'was' if len(missing) == 1 else 'were'}"
        f" not given: rerun with them, or write campaign.yaml yourself with campaign_id: "
        f"{campaign_id}, kind: {AXIS_KIND}, machine, start (ISO 8601 local time of the cold run), "
        "axis: {name, stroke_mm} and sensors (see docs/data-contract.md)"
    )

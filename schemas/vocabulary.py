"""Closed vocabularies and column names of the raw campaign contract (``docs/data-contract.md``).

Every model in :mod:`schemas` and every stage that builds or reads these tables uses these
names, so a change to the contract is made here once.
"""

from __future__ import annotations

import re

KINDS = ("spindle_drift", "axis_positioning")
"""Known campaign kinds (``kind:`` in campaign.yaml)."""

SPINDLE_KIND, AXIS_KIND = KINDS

SPLITS = ("train", "validation")
"""Known values of ``split:`` in campaign.yaml."""

START_STATES = ("cold", "warm")
"""Known values of ``start_state:`` in campaign.yaml: at rest in equilibrium with the air when
the first sample was taken, or not (it ran, or stopped too shortly before)."""

SEASONS = ("spring", "summer", "autumn", "winter")
"""Known values of ``season:`` in campaign.yaml (or derived from ``start``)."""

SEASON_OF_MONTH = {
    12: "winter",
    1: "winter",
    2: "winter",
    3: "spring",
    4: "spring",
    5: "spring",
    6: "summer",
    7: "summer",
    8: "summer",
    9: "autumn",
    10: "autumn",
    11: "autumn",
}
"""The season of a calendar month (northern hemisphere): a campaign's season when campaign.yaml
gives ``start`` but no ``season``."""

STRUCTURE_ROLES = (
    "spindle_front_bearing",
    "spindle_rear_bearing",
    "spindle_motor",
    "headstock",
    "column_front",
    "column_rear",
    "bed",
    "ball_screw",
)
"""Roles that are parts of the machine's structure (spindle bearings and motor, headstock,
column, bed, ball screw): a node each of the physical twin's thermal network and the parts a
``heat_loads:`` entry of campaign.yaml may heat. ``nut``, ``coolant``, ``ambient`` and
``other`` are not."""

SENSOR_ROLES = (*STRUCTURE_ROLES, "nut", "coolant", "ambient", "other")
"""Closed vocabulary of sensor roles; at most one sensor per campaign is ``ambient``."""

AMBIENT_ROLE = "ambient"

DIRECTIONS = ("+", "-")
"""Laser run directions."""

DISPLACEMENT_AXES = ("X", "Y", "Z")
"""The machine axes a displacement probe usually measures along (sign: positive = tool away from
the table / workpiece). Other probes (a second Z probe, a tilt pair...) may be declared under any
name of letters and digits starting with a letter (:func:`is_displacement_name`), e.g. ``Z2``;
their sign is the user's."""

CAMPAIGN_ID_RE = re.compile(r"^[A-Za-z0-9_-]+$")
"""A campaign id (= its folder name): letters, digits, '-' and '_' only, so never a path."""

DISPLACEMENT_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9]{0,15}$")

DS18B20_TYPE = "DS18B20"
"""Sensor type whose fault codes (85.0 power-on, -127 disconnected) are checked."""

SAMPLE_BASE_COLUMNS = ("campaign_id", "source_row", "elapsed_s", "rpm")
"""Columns every samples table starts with; the rest are temperatures and displacements."""

DISPLACEMENT_COLUMN_RE = re.compile(r"^disp_([A-Za-z][A-Za-z0-9]{0,15})$")
DISPLACEMENT_ROW_COLUMN_RE = re.compile(r"^disp_([A-Za-z][A-Za-z0-9]{0,15})_source_row$")


def is_displacement_name(name: object) -> bool:
    """Return True for a valid displacement column name: X, Y, Z, or e.g. ``Z2``, ``Xrear``."""
    return bool(DISPLACEMENT_NAME_RE.match(str(name)))


def displacement_column(axis: str) -> str:
    """Return the samples column holding the displacement along ``axis`` (um)."""
    return f"disp_{axis}"


def displacement_row_column(axis: str) -> str:
    """Return the samples column holding the displacement.csv data row of ``disp_<axis>``."""
    return f"disp_{axis}_source_row"


def is_displacement_column(column: str) -> bool:
    """Return True for ``disp_<A>`` and ``disp_<A>_source_row`` columns."""
    return bool(DISPLACEMENT_COLUMN_RE.match(column) or DISPLACEMENT_ROW_COLUMN_RE.match(column))


def temperature_columns(columns) -> list[str]:
    """Return the temperature columns of a samples table, in table order.

    Parameters
    ----------
    columns : iterable of str
        Column names of a samples table (``campaign_id, source_row, elapsed_s, rpm``, one column
        per temperature sensor, then ``disp_<A>`` / ``disp_<A>_source_row`` per axis).

    Returns
    -------
    list of str
        Every column that is neither a base column nor a displacement column.
    """
    return [
        str(c) for c in columns if c not in SAMPLE_BASE_COLUMNS and not is_displacement_column(c)
    ]


def uses_ds18b20_codes(sensor_type: object) -> bool:
    """Return True when the DS18B20 fault codes apply to a sensor of this ``type:``.

    They apply to DS18B20 sensors and, conservatively, to sensors whose type is not given.
    """
    if sensor_type is None or (isinstance(sensor_type, float) and sensor_type != sensor_type):
        return True
    return str(sensor_type).strip().upper() == DS18B20_TYPE

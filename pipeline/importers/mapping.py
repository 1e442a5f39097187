"""Read and check the mapping file of ``thermal import logger`` (docs/import-logger.md).

The mapping file (YAML) says how a data logger's wide table maps onto the raw campaign contract:
how to read the table (``table:``), which column is the time (``time:``) and the spindle speed
(``speed:``), which columns are displacement probes (``probes:``) and temperatures
(``temperatures:``) under which contract names and units, which columns to leave out
(``ignore_columns:``), the campaign metadata (``campaign:``) and how to cut the record into
campaigns (``cut:``). Every problem raises :class:`MappingError` naming the file and the key and
saying what to write.
"""

from __future__ import annotations

import codecs
import datetime as dt
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from pipeline.importers.cutting import RULES, CutRule
from pipeline.io.reader import RESERVED_COLUMNS
from schemas.vocabulary import (
    AMBIENT_ROLE,
    CAMPAIGN_ID_RE,
    SEASONS,
    SENSOR_ROLES,
    SPLITS,
    START_STATES,
    is_displacement_name,
)

TIME_UNITS = {"s": 1.0, "min": 60.0, "timestamp": None}
"""Time column units and their length in seconds (a timestamp is a date-time)."""

PROBE_UNITS = {"um": 1.0, "mm": 1000.0}
"""Displacement units and their length in micrometres."""

TEMPERATURE_UNITS = ("degC", "degF")

DELIMITERS = (",", ";", "\t")
DECIMALS = (".", ",")
SENSOR_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

TOP_LEVEL = "the top level"
TOP_KEYS = ("table", "time", "speed", "probes", "temperatures", "ignore_columns", "campaign", "cut")
TABLE_KEYS = (
    "delimiter",
    "decimal",
    "encoding",
    "sheet",
    "header_row",
    "skip_after_header",
    "missing_values",
)
TIME_KEYS = ("column", "unit", "format", "start", "date_column")
PROBE_KEYS = ("axis", "unit", "probe", "location")
SENSOR_KEYS = ("sensor", "role", "location", "type", "unit")
CAMPAIGN_KEYS = ("machine", "id_prefix", "split", "season", "synthetic", "start_state")
CUT_KEYS = ("rule", "min_stop_min", "window_h", "stop_rpm", "cold_after_stop_h")


class MappingError(ValueError):
    """A mapping file that cannot be used; the message names the file and key and the fix."""


@dataclass(frozen=True)
class TableOptions:
    """How the table is read.

    Attributes
    ----------
    delimiter : str
        CSV field separator: ``,``, ``;`` or a tab.
    decimal : str
        Decimal mark of numbers written as text: ``.`` or ``,``.
    encoding : str
        Text encoding of a CSV; ``utf-8`` also reads a file that starts with a byte-order mark.
    sheet : str or None
        XLSX sheet name; None: the first sheet.
    header_row : int
        1-based line (CSV) or sheet row (XLSX) of the header; the lines above it are skipped.
    skip_after_header : int
        Lines right under the header that are not data (units, channel descriptions).
    missing_values : tuple of str
        Cell texts that mean "no reading", besides an empty cell.
    """

    delimiter: str = ","
    decimal: str = "."
    encoding: str = "utf-8"
    sheet: str | None = None
    header_row: int = 1
    skip_after_header: int = 0
    missing_values: tuple[str, ...] = ()


@dataclass(frozen=True)
class TimeSpec:
    """The time column.

    Attributes
    ----------
    column : str
    unit : str
        ``s`` or ``min`` (time since ``start``) or ``timestamp`` (a local date-time).
    format : str or None
        ``strftime`` format of the timestamps; None: ISO 8601.
    start : pandas.Timestamp or None
        Local date-time of time 0 (``s`` and ``min`` only).
    date_column : str or None
        A separate date column, joined to ``column`` with a space before parsing (timestamp).
    """

    column: str
    unit: str
    format: str | None = None
    start: pd.Timestamp | None = None
    date_column: str | None = None


@dataclass(frozen=True)
class ProbeSpec:
    """A displacement probe column.

    Attributes
    ----------
    column : str
        Column of the table.
    axis : str
        Contract displacement name (X, Y, Z, or e.g. Z2).
    factor_um : float
        Micrometres per table unit (1 for um, 1000 for mm).
    probe, location : str or None
        Written under ``displacement:`` when given.
    """

    column: str
    axis: str
    factor_um: float = 1.0
    probe: str | None = None
    location: str | None = None


@dataclass(frozen=True)
class SensorSpec:
    """A temperature column.

    Attributes
    ----------
    column : str
        Column of the table.
    sensor : str
        Contract sensor name (e.g. T1).
    role : str
        One of ``SENSOR_ROLES``.
    unit : str
        ``degC`` or ``degF`` (converted to degC).
    location, type : str or None
        Written under ``sensors:`` when given.
    """

    column: str
    sensor: str
    role: str = "other"
    unit: str = "degC"
    location: str | None = None
    type: str | None = None


@dataclass(frozen=True)
class CampaignSpec:
    """Metadata written into every campaign.yaml.

    Attributes
    ----------
    machine : str
    id_prefix : str or None
        Campaign ids are the prefix and a number (``L01``, ``L02``...); may come from the
        command line instead.
    split : str
    season : str or None
        None: derived from each campaign's start by the pipeline.
    synthetic : bool
    start_state : str or None
        ``cold`` or ``warm`` for the first campaign; None: not written (unknown).
    """

    machine: str
    id_prefix: str | None = None
    split: str = "train"
    season: str | None = None
    synthetic: bool = False
    start_state: str | None = None


@dataclass(frozen=True)
class LoggerMapping:
    """Everything the mapping file says.

    Attributes
    ----------
    path : Path
        The mapping file (for messages).
    table : TableOptions
    time : TimeSpec
    speed_column : str
        Spindle speed column, rpm.
    probes : tuple of ProbeSpec
    sensors : tuple of SensorSpec
    ignore_columns : tuple of str
        Columns of the table deliberately left out.
    campaign : CampaignSpec
    cut : CutRule
    """

    path: Path
    table: TableOptions
    time: TimeSpec
    speed_column: str
    probes: tuple[ProbeSpec, ...]
    sensors: tuple[SensorSpec, ...]
    ignore_columns: tuple[str, ...]
    campaign: CampaignSpec
    cut: CutRule

    def mapped_columns(self) -> list[str]:
        """Every table column the mapping reads (time, date, speed, probes, temperatures)."""
        time = [self.time.column] + ([self.time.date_column] if self.time.date_column else [])
        return [
            *time,
            self.speed_column,
            *(p.column for p in self.probes),
            *(s.column for s in self.sensors),
        ]


class _Checker:
    """Raise :class:`MappingError` naming the mapping file and the key."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, problem: str, action: str) -> MappingError:
        return MappingError(f"mapping file {self.path}, key '{key}': {problem}; {action}")

    def section(self, value: Any, key: str, allowed: tuple[str, ...]) -> dict[str, Any]:
        """Return ``value`` as a dict with only ``allowed`` keys (None: empty)."""
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(
                key,
                f"expected a mapping of keys, found {value!r}",
                f"write {key}: followed by indented keys ({', '.join(allowed)})",
            )
        unknown = [str(k) for k in value if str(k) not in allowed]
        if unknown:
            raise self.fail(
                f"{key}.{unknown[0]}" if key != TOP_LEVEL else unknown[0],
                f"unknown key(s) {unknown} {'at' if key == TOP_LEVEL else 'under'} {key}",
                f"use only {', '.join(allowed)} (check the spelling)",
            )
        return {str(k): v for k, v in value.items()}

    def text(self, value: Any, key: str, what: str, required: bool = False) -> str | None:
        if value is None or (isinstance(value, str) and not value.strip()):
            if required:
                raise self.fail(key, "missing", f"write {key}: {what}")
            return None
        if isinstance(value, Mapping | list | bool):
            raise self.fail(key, f"expected text, found {value!r}", f"write {key}: {what}")
        return str(value).strip()

    def choice(self, value: Any, key: str, choices, default: str | None) -> str | None:
        if value is None:
            return default
        if str(value) not in choices:
            raise self.fail(
                key,
                f"'{value}' is not one of {list(choices)}",
                f"write {key}: followed by one of {', '.join(map(str, choices))}",
            )
        return str(value)

    def number(
        self, value: Any, key: str, default: float | None, minimum: float, strict: bool = False
    ) -> float | None:
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"'{value}' is not a number", f"write {key}: followed by a number")
        if value < minimum or (strict and value == minimum):
            bound = f"more than {minimum:g}" if strict else f"at least {minimum:g}"
            raise self.fail(key, f"{value} is out of range", f"write a number {bound}")
        return float(value)


def load_mapping(path: Path) -> LoggerMapping:
    """Read and check a mapping file.

    Parameters
    ----------
    path : Path
        The YAML mapping file.

    Returns
    -------
    LoggerMapping

    Raises
    ------
    MappingError
        When the file is missing or unreadable, or a key is missing, unknown or malformed.
    """
    check = _Checker(path)
    if not path.is_file():
        raise MappingError(
            f"mapping file {path} does not exist; write one (see "
            "docs/import-logger.md) and pass it with --mapping"
        )
    try:
        content = yaml.safe_load(path.read_text(encoding="utf-8-sig"))
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        mark = getattr(error, "problem_mark", None)
        where = "" if mark is None else f" at line {mark.line + 1}"
        raise MappingError(
            f"mapping file {path} cannot be read as YAML{where}: {error}; fix the syntax there "
            '(quote values such as "," or ";")'
        ) from None
    top = check.section(content if content is not None else {}, TOP_LEVEL, TOP_KEYS)
    for required in ("time", "speed", "probes", "temperatures", "campaign"):
        if top.get(required) is None:
            raise check.fail(
                required,
                "missing",
                f"add a {required}: section (see the example in docs/import-logger.md)",
            )
    mapping = LoggerMapping(
        path=path,
        table=_table(check, top.get("table")),
        time=_time(check, top["time"]),
        speed_column=_speed(check, top["speed"]),
        probes=_probes(check, top.get("probes")),
        sensors=_sensors(check, top["temperatures"]),
        ignore_columns=_ignore(check, top.get("ignore_columns")),
        campaign=_campaign(check, top["campaign"]),
        cut=_cut(check, top.get("cut")),
    )
    _check_columns_once(check, mapping)
    return mapping


def _table(check: _Checker, value: Any) -> TableOptions:
    section = check.section(value, "table", TABLE_KEYS)
    encoding = check.text(section.get("encoding"), "table.encoding", "utf-8") or "utf-8"
    try:
        codecs.lookup(encoding)
    except LookupError:
        raise check.fail(
            "table.encoding",
            f"'{encoding}' is not a known text encoding",
            "write utf-8 (default), cp1252 or latin-1",
        ) from None
    missing = section.get("missing_values") or []
    if not isinstance(missing, list) or not all(isinstance(m, str | int | float) for m in missing):
        raise check.fail(
            "table.missing_values",
            f"expected a list of texts, found {missing!r}",
            'write e.g. missing_values: ["---", "ERR"]',
        )
    return TableOptions(
        delimiter=check.choice(section.get("delimiter"), "table.delimiter", DELIMITERS, ","),
        decimal=check.choice(section.get("decimal"), "table.decimal", DECIMALS, "."),
        encoding=encoding,
        sheet=check.text(section.get("sheet"), "table.sheet", "the sheet name"),
        header_row=_whole(check, section.get("header_row"), "table.header_row", 1, 1),
        skip_after_header=_whole(
            check, section.get("skip_after_header"), "table.skip_after_header", 0, 0
        ),
        missing_values=tuple(str(m).strip() for m in missing),
    )


def _whole(check: _Checker, value: Any, key: str, default: int, minimum: int) -> int:
    number = check.number(value, key, default, minimum)
    if not float(number).is_integer():
        raise check.fail(key, f"{number:g} is not a whole number", "write a line count")
    return int(number)


def _time(check: _Checker, value: Any) -> TimeSpec:
    section = check.section(value, "time", TIME_KEYS)
    column = check.text(section.get("column"), "time.column", "the time column's header", True)
    unit = check.choice(section.get("unit"), "time.unit", tuple(TIME_UNITS), None)
    if unit is None:
        raise check.fail(
            "time.unit",
            "missing",
            "write unit: s, unit: min (time since start:) or unit: timestamp",
        )
    start = section.get("start")
    if unit == "timestamp":
        if start is not None:
            raise check.fail(
                "time.start",
                "a timestamp column carries its own date-time",
                "delete time.start, or use unit: s / min",
            )
    else:
        for key in ("format", "date_column"):
            if section.get(key) is not None:
                raise check.fail(
                    f"time.{key}",
                    f"{key} only applies to unit: timestamp",
                    f"delete time.{key}, or set unit: timestamp",
                )
        start = _start(check, start)
    return TimeSpec(
        column=column,
        unit=unit,
        format=check.text(section.get("format"), "time.format", 'e.g. "%d.%m.%Y %H:%M:%S"'),
        start=start,
        date_column=check.text(section.get("date_column"), "time.date_column", "its header"),
    )


def _start(check: _Checker, value: Any) -> pd.Timestamp:
    action = "write time.start: YYYY-MM-DDTHH:MM:SS, the local date-time of time 0"
    if value is None:
        raise check.fail(
            "time.start", "missing (a time in s or min needs a date-time origin)", action
        )
    if isinstance(value, dt.date) and not isinstance(value, dt.datetime):
        raise check.fail("time.start", f"{value} has no time of day", action)
    start = pd.to_datetime(str(value), errors="coerce")
    if pd.isna(start) or start.tzinfo is not None:
        problem = "has a UTC offset" if not pd.isna(start) else "is not an ISO 8601 date-time"
        raise check.fail("time.start", f"'{value}' {problem}", action)
    return start


def _speed(check: _Checker, value: Any) -> str:
    section = check.section(value, "speed", ("column", "unit"))
    check.choice(section.get("unit"), "speed.unit", ("rpm",), "rpm")
    return check.text(section.get("column"), "speed.column", "the spindle speed column (rpm)", True)


def _entries(check: _Checker, value: Any, key: str, short: str) -> dict[str, Any]:
    """Column -> entry; an entry may be a bare name (``t1: T1``) standing for ``{short: T1}``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise check.fail(
            key,
            f"expected column: entry pairs, found {value!r}",
            f"write one line per table column, e.g. t1: {{{short}: T1}}",
        )
    return {str(k).strip(): v if isinstance(v, Mapping) else {short: v} for k, v in value.items()}


def _probes(check: _Checker, value: Any) -> tuple[ProbeSpec, ...]:
    probes = []
    for column, raw in _entries(check, value, "probes", "axis").items():
        key = f"probes.{column}"
        entry = check.section(raw, key, PROBE_KEYS)
        axis = check.text(entry.get("axis"), f"{key}.axis", "X, Y, Z or e.g. Z2", True)
        if not is_displacement_name(axis):
            raise check.fail(
                f"{key}.axis",
                f"'{axis}' is not a displacement axis name",
                "write X, Y, Z, or letters and digits starting with a letter "
                "(e.g. Z2), at most 16 characters",
            )
        unit = check.choice(entry.get("unit"), f"{key}.unit", tuple(PROBE_UNITS), "um")
        probes.append(
            ProbeSpec(
                column=column,
                axis=axis,
                factor_um=PROBE_UNITS[unit],
                probe=check.text(entry.get("probe"), f"{key}.probe", "e.g. eddy_current"),
                location=check.text(entry.get("location"), f"{key}.location", "where it measures"),
            )
        )
    if not probes:
        raise check.fail(
            "probes",
            "no probe column is mapped (a spindle drift campaign needs a displacement)",
            "map at least one column, e.g. ch1: {axis: Z}",
        )
    _unique(check, "probes", [(p.column, p.axis) for p in probes], "axis")
    return tuple(probes)


def _sensors(check: _Checker, value: Any) -> tuple[SensorSpec, ...]:
    sensors = []
    for column, raw in _entries(check, value, "temperatures", "sensor").items():
        key = f"temperatures.{column}"
        entry = check.section(raw, key, SENSOR_KEYS)
        name = check.text(entry.get("sensor"), f"{key}.sensor", "the contract name, e.g. T1", True)
        if not SENSOR_NAME_RE.match(name) or name in RESERVED_COLUMNS or name.startswith("disp_"):
            raise check.fail(
                f"{key}.sensor",
                f"'{name}' cannot be a sensor name",
                "write letters, digits and '_' starting with a letter (e.g. T1), "
                f"not {sorted(RESERVED_COLUMNS)} nor disp_...",
            )
        sensors.append(
            SensorSpec(
                column=column,
                sensor=name,
                role=check.choice(entry.get("role"), f"{key}.role", SENSOR_ROLES, "other"),
                unit=check.choice(entry.get("unit"), f"{key}.unit", TEMPERATURE_UNITS, "degC"),
                location=check.text(entry.get("location"), f"{key}.location", "where it is"),
                type=check.text(entry.get("type"), f"{key}.type", "e.g. DS18B20 or PT100"),
            )
        )
    if not sensors:
        raise check.fail(
            "temperatures",
            "no temperature column is mapped",
            "map at least one column, e.g. t1: {sensor: T1, role: ambient}",
        )
    _unique(check, "temperatures", [(s.column, s.sensor) for s in sensors], "sensor")
    ambient = [s.column for s in sensors if s.role == AMBIENT_ROLE]
    if len(ambient) > 1:
        raise check.fail(
            f"temperatures.{ambient[1]}.role",
            f"columns {ambient} are all role: ambient (at most one per campaign)",
            "keep role: ambient on one sensor and set the others to other",
        )
    return tuple(sensors)


def _unique(check: _Checker, key: str, pairs: list[tuple[str, str]], field: str) -> None:
    seen: dict[str, str] = {}
    for column, name in pairs:
        if name in seen:
            raise check.fail(
                f"{key}.{column}.{field}",
                f"{field} {name} is also given to column {seen[name]}",
                f"give every column its own {field} name",
            )
        seen[name] = column


def _ignore(check: _Checker, value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list):
        raise check.fail(
            "ignore_columns",
            f"expected a list of column headers, found {value!r}",
            "write e.g. ignore_columns: [ch4, ch5, t16]",
        )
    return tuple(str(c).strip() for c in value)


def _campaign(check: _Checker, value: Any) -> CampaignSpec:
    section = check.section(value, "campaign", CAMPAIGN_KEYS)
    prefix = check.text(section.get("id_prefix"), "campaign.id_prefix", "e.g. L")
    if prefix is not None and not CAMPAIGN_ID_RE.match(prefix):
        raise check.fail(
            "campaign.id_prefix",
            f"'{prefix}' has characters a campaign id cannot have",
            "use letters, digits, '-' and '_' only",
        )
    synthetic = section.get("synthetic", False)
    if not isinstance(synthetic, bool):
        raise check.fail(
            "campaign.synthetic",
            f"'{synthetic}' is not true or false",
            "write synthetic: false for measured data",
        )
    return CampaignSpec(
        machine=check.text(section.get("machine"), "campaign.machine", "the machine's name", True),
        id_prefix=prefix,
        split=check.choice(section.get("split"), "campaign.split", SPLITS, "train"),
        season=check.choice(section.get("season"), "campaign.season", SEASONS, None),
        synthetic=synthetic,
        start_state=check.choice(
            section.get("start_state"), "campaign.start_state", START_STATES, None
        ),
    )


def _cut(check: _Checker, value: Any) -> CutRule:
    section = check.section(value, "cut", CUT_KEYS)
    default = CutRule()
    return CutRule(
        rule=check.choice(section.get("rule"), "cut.rule", RULES, default.rule),
        min_stop_min=check.number(
            section.get("min_stop_min"), "cut.min_stop_min", default.min_stop_min, 0.0
        ),
        window_h=check.number(section.get("window_h"), "cut.window_h", None, 0.0, strict=True),
        stop_rpm=check.number(section.get("stop_rpm"), "cut.stop_rpm", default.stop_rpm, 0.0),
        cold_after_stop_h=check.number(
            section.get("cold_after_stop_h"), "cut.cold_after_stop_h", None, 0.0, strict=True
        ),
    )


def _check_columns_once(check: _Checker, mapping: LoggerMapping) -> None:
    """Every table column is mapped at most once and is not also ignored."""
    roles = [("time.column", mapping.time.column), ("speed.column", mapping.speed_column)]
    if mapping.time.date_column:
        roles.append(("time.date_column", mapping.time.date_column))
    roles += [(f"probes.{p.column}", p.column) for p in mapping.probes]
    roles += [(f"temperatures.{s.column}", s.column) for s in mapping.sensors]
    seen: dict[str, str] = {}
    for key, column in roles:
        if column in seen:
            raise check.fail(
                key,
                f"column '{column}' is already mapped by {seen[column]}",
                "map every table column once",
            )
        seen[column] = key
    for column in mapping.ignore_columns:
        if column in seen:
            raise check.fail(
                "ignore_columns",
                f"column '{column}' is mapped by {seen[column]} and also ignored",
                f"remove {column} from ignore_columns",
            )

"""Read and check the mapping file of ``thermal import logger`` (docs/import-logger.md).

The mapping file (YAML) says how a data logger's wide table maps onto the raw campaign contract:
how to read the table (``table:``), which column is the time (``time:``) and the spindle speed
(``speed:``), which columns are displacement probes (``probes:``) and temperatures
(``temperatures:``) under which contract names and units, which columns to leave out
(``ignore_columns:``), the campaign metadata (``campaign:``) and how to cut the record into
campaigns (``cut:``). Its keys and values are checked on the models of
:mod:`pipeline.importers.mapping_file`; what depends on several keys (a time origin for a time
in s, every column mapped once, one ambient sensor) is checked here. Every problem raises
:class:`MappingError` naming the file and the key and saying what to write.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml
from pydantic import ValidationError

from pipeline.importers.cutting import CutRule
from pipeline.importers.mapping_file import (
    PROBE_UNITS,
    CampaignSpec,
    MappingError,
    MappingFile,
    TableOptions,
    mapping_error,
    mapping_failure,
)
from pipeline.settings.base import problems
from schemas.vocabulary import AMBIENT_ROLE


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
class LoggerMapping:
    """Everything the mapping file says.

    Attributes
    ----------
    path : Path
        The mapping file (for messages).
    table : TableOptions
        :class:`pipeline.importers.mapping_file.TableOptions`.
    time : TimeSpec
    speed_column : str
        Spindle speed column, rpm.
    probes : tuple of ProbeSpec
    sensors : tuple of SensorSpec
    ignore_columns : tuple of str
        Columns of the table deliberately left out.
    campaign : CampaignSpec
        :class:`pipeline.importers.mapping_file.CampaignSpec`.
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
        return mapping_failure(self.path, key, problem, action)


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
    if content is not None and not isinstance(content, dict):
        raise check.fail(
            "the top level",
            f"expected a mapping of keys, found {content!r}",
            f"write the sections {', '.join(MappingFile.model_fields)} as top-level keys",
        )
    try:
        given = {k: v for k, v in (content or {}).items() if v is not None}
        read = MappingFile.model_validate(given)
    except ValidationError as error:
        raise mapping_error(path, problems(error, MappingFile)) from None
    mapping = LoggerMapping(
        path=path,
        table=read.table,
        time=_time(check, read),
        speed_column=read.speed.column,
        probes=_probes(check, read),
        sensors=_sensors(check, read),
        ignore_columns=read.ignore_columns,
        campaign=read.campaign,
        cut=CutRule(**read.cut.model_dump(exclude_none=True)),
    )
    _check_columns_once(check, mapping)
    return mapping


def _time(check: _Checker, read: MappingFile) -> TimeSpec:
    section = read.time
    start = section.start
    if section.unit == "timestamp":
        if start is not None:
            raise check.fail(
                "time.start",
                "a timestamp column carries its own date-time",
                "delete time.start, or use unit: s / min",
            )
    else:
        for key in ("format", "date_column"):
            if getattr(section, key) is not None:
                raise check.fail(
                    f"time.{key}",
                    f"{key} only applies to unit: timestamp",
                    f"delete time.{key}, or set unit: timestamp",
                )
        start = _start(check, start)
    return TimeSpec(
        column=section.column,
        unit=section.unit,
        format=section.format,
        start=start,
        date_column=section.date_column,
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


def _probes(check: _Checker, read: MappingFile) -> tuple[ProbeSpec, ...]:
    probes = tuple(
        ProbeSpec(column, e.axis, PROBE_UNITS[e.unit], e.probe, e.location)
        for column, e in read.probes.items()
    )
    if not probes:
        raise check.fail(
            "probes",
            "no probe column is mapped (a spindle drift campaign needs a displacement)",
            "map at least one column, e.g. ch1: {axis: Z}",
        )
    _unique(check, "probes", [(p.column, p.axis) for p in probes], "axis")
    return probes


def _sensors(check: _Checker, read: MappingFile) -> tuple[SensorSpec, ...]:
    sensors = tuple(
        SensorSpec(column, e.sensor, e.role, e.unit, e.location, e.type)
        for column, e in read.temperatures.items()
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
    return sensors


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

"""The keys and values of the mapping file of ``thermal import logger``, and how an error reads.

:class:`MappingFile` is the mapping file (docs/import-logger.md) as pydantic models, checked on
the mechanism of the typed ``params.yaml`` sections (:mod:`pipeline.settings.base`): every
level allows only its own keys, every value has its type and allowed values.
:func:`mapping_error` words the first thing wrong as the importer always has: ``mapping file
<path>, key '<key path>': <what is wrong>; <what to write>``, with the keys allowed at that level
(and the closest one) for an unknown key. What depends on several keys at once (a time origin
for a time in s, one column mapped once, one ambient sensor) is checked by
:func:`pipeline.importers.mapping.load_mapping`.
"""

from __future__ import annotations

import codecs
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, StrictBool, StrictFloat, StrictInt, field_validator
from pydantic_core import PydanticCustomError

from pipeline.importers.cutting import RULES
from pipeline.io.reader import RESERVED_COLUMNS
from pipeline.settings.base import (
    MISSING,
    UNKNOWN,
    Problem,
    Settings,
    allowed_keys,
    choices,
    closest,
    described,
    key_path,
)
from schemas.vocabulary import (
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
EXAMPLE = "see the example in docs/import-logger.md"


class MappingError(ValueError):
    """A mapping file that cannot be used; the message names the file and key and the fix."""


def mapping_failure(path: Path, key: str, problem: str, action: str) -> MappingError:
    """Return the error ``mapping file <path>, key '<key>': <problem>; <action>``."""
    return MappingError(f"mapping file {path}, key '{key}': {problem}; {action}")


def _text(value: Any) -> str | None:
    """Return a value written as text (a number as its text); blank: None."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, Mapping | list | bool):
        raise ValueError(f"expected text, found {value!r}")
    return str(value).strip()


def _required_text(value: Any) -> str:
    text = _text(value)
    if text is None:
        raise PydanticCustomError(MISSING, "missing")
    return text


def _nothing_is_empty(value: Any) -> Any:
    """``table:`` or ``cut:`` written without keys reads as an empty section."""
    return {} if value is None else value


Text = Annotated[str | None, BeforeValidator(_text)]
RequiredText = Annotated[str, BeforeValidator(_required_text)]


class TableOptions(Settings):
    """How the table is read (``table:``).

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

    delimiter: Literal[DELIMITERS] = ","
    decimal: Literal[DECIMALS] = "."
    encoding: Text = Field("utf-8", description="utf-8")
    sheet: Text = Field(None, description="the sheet name")
    header_row: StrictInt = Field(1, ge=1, description="a line count")
    skip_after_header: StrictInt = Field(0, ge=0, description="a line count")
    missing_values: tuple[str, ...] = ()

    @field_validator("encoding", mode="after")
    @classmethod
    def _known(cls, value: str | None) -> str:
        value = value or "utf-8"
        try:
            codecs.lookup(value)
        except LookupError:
            raise ValueError(
                f"'{value}' is not a known text encoding; write utf-8 (default), cp1252 or latin-1"
            ) from None
        return value

    @field_validator("missing_values", mode="before")
    @classmethod
    def _texts(cls, value: Any) -> Any:
        if value is None:
            return ()
        if not isinstance(value, list) or not all(isinstance(m, str | int | float) for m in value):
            raise ValueError(
                f'expected a list of texts, found {value!r}; write e.g. missing_values: ["---", '
                '"ERR"]'
            )
        return tuple(str(m).strip() for m in value)


class TimeSection(Settings):
    """The time column (``time:``); ``start`` is checked with ``unit`` by the loader."""

    column: RequiredText = Field(description="the time column's header")
    unit: Literal[tuple(TIME_UNITS)] = Field(
        description="s, unit: min (time since start:) or unit: timestamp"
    )
    format: Text = Field(None, description='e.g. "%d.%m.%Y %H:%M:%S"')
    start: Any = None
    date_column: Text = Field(None, description="its header")


class SpeedSection(Settings):
    """The spindle speed column (``speed:``)."""

    column: RequiredText = Field(description="the spindle speed column (rpm)")
    unit: Literal["rpm"] = "rpm"


class ProbeEntry(Settings):
    """A displacement probe column (``probes: <column>:``)."""

    axis: RequiredText = Field(description="X, Y, Z or e.g. Z2")
    unit: Literal[tuple(PROBE_UNITS)] = "um"
    probe: Text = Field(None, description="e.g. eddy_current")
    location: Text = Field(None, description="where it measures")

    @field_validator("axis")
    @classmethod
    def _axis(cls, value: str) -> str:
        if not is_displacement_name(value):
            raise ValueError(
                f"'{value}' is not a displacement axis name; write X, Y, Z, or letters and "
                "digits starting with a letter (e.g. Z2), at most 16 characters"
            )
        return value


class SensorEntry(Settings):
    """A temperature column (``temperatures: <column>:``)."""

    sensor: RequiredText = Field(description="the contract name, e.g. T1")
    role: Literal[SENSOR_ROLES] = "other"
    unit: Literal[TEMPERATURE_UNITS] = "degC"
    location: Text = Field(None, description="where it is")
    type: Text = Field(None, description="e.g. DS18B20 or PT100")

    @field_validator("sensor")
    @classmethod
    def _name(cls, value: str) -> str:
        reserved = value in RESERVED_COLUMNS or value.startswith("disp_")
        if reserved or not SENSOR_NAME_RE.match(value):
            raise ValueError(
                f"'{value}' cannot be a sensor name; write letters, digits and '_' starting "
                f"with a letter (e.g. T1), not {sorted(RESERVED_COLUMNS)} nor disp_..."
            )
        return value


class CampaignSpec(Settings):
    """Metadata written into every campaign.yaml (``campaign:``).

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

    machine: RequiredText = Field(description="the machine's name")
    id_prefix: Text = Field(None, description="e.g. L")
    split: Literal[SPLITS] = "train"
    season: Literal[SEASONS] | None = None
    synthetic: StrictBool = Field(False, description="false for measured data")
    start_state: Literal[START_STATES] | None = None

    @field_validator("id_prefix")
    @classmethod
    def _prefix(cls, value: str | None) -> str | None:
        if value is not None and not CAMPAIGN_ID_RE.match(value):
            raise ValueError(
                f"'{value}' has characters a campaign id cannot have; use letters, digits, '-' "
                "and '_' only"
            )
        return value


class CutSection(Settings):
    """How the record is cut (``cut:``); a key left out keeps the rule's default."""

    rule: Literal[RULES] | None = None
    min_stop_min: StrictFloat | None = Field(None, ge=0)
    window_h: StrictFloat | None = Field(None, gt=0)
    stop_rpm: StrictFloat | None = Field(None, ge=0)
    cold_after_stop_h: StrictFloat | None = Field(None, gt=0)


def _columns(short: str, example: str) -> BeforeValidator:
    """Column -> entry, where a bare name (``t1: T1``) stands for ``{short: T1}``."""

    def read(value: Any) -> Any:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise ValueError(
                f"expected column: entry pairs, found {value!r}; write one line per table "
                f"column, e.g. {example}"
            )
        return {
            str(k).strip(): v if isinstance(v, Mapping) else {short: v} for k, v in value.items()
        }

    return BeforeValidator(read)


def _headers(value: Any) -> Any:
    if value is None:
        return ()
    if not isinstance(value, list):
        raise ValueError(
            f"expected a list of column headers, found {value!r}; write e.g. ignore_columns: "
            "[ch4, ch5, t16]"
        )
    return tuple(str(c).strip() for c in value)


class MappingFile(Settings):
    """The whole mapping file."""

    table: Annotated[TableOptions, BeforeValidator(_nothing_is_empty)] = TableOptions()
    time: TimeSection
    speed: SpeedSection
    probes: Annotated[dict[str, ProbeEntry], _columns("axis", "ch1: {axis: Z}")]
    temperatures: Annotated[dict[str, SensorEntry], _columns("sensor", "t1: {sensor: T1}")]
    ignore_columns: Annotated[tuple[str, ...], BeforeValidator(_headers)] = ()
    campaign: CampaignSpec
    cut: Annotated[CutSection, BeforeValidator(_nothing_is_empty)] = CutSection()


def mapping_error(path: Path, found: Sequence[Problem]) -> MappingError:
    """Return the error of the first problem of a mapping file, worded with what to write."""
    first = found[0]
    key = key_path(first.path) or TOP_LEVEL
    if first.kind == UNKNOWN:
        parent = first.path[:-1]
        unknown = [str(p.path[-1]) for p in found if p.kind == UNKNOWN and p.path[:-1] == parent]
        allowed = allowed_keys(MappingFile, parent)
        where = f"at {TOP_LEVEL}" if not parent else f"under {key_path(parent)}"
        close = closest(unknown[0], allowed)
        hint = f"; did you mean '{close}'?" if close else ""
        return mapping_failure(
            path,
            key,
            f"unknown key(s) {unknown} {where}",
            f"use only {', '.join(allowed)} (check the spelling{hint})",
        )
    return mapping_failure(path, key, *_wording(first, key))


def _wording(problem: Problem, key: str) -> tuple[str, str]:
    """Return what is wrong and what to write, for a missing key or a wrong value."""
    what = described(MappingFile, problem.path)
    write = f"write {key}: {what}" if what else f"write {key}: ({EXAMPLE})"
    if problem.kind == MISSING:
        if len(problem.path) == 1:
            return "missing", f"add a {key}: section ({EXAMPLE})"
        return "missing", write
    value, context = problem.value, problem.context
    if problem.code == "literal_error":
        allowed = [
            str(c).encode("unicode_escape").decode() for c in choices(MappingFile, problem.path)
        ]
        return f"'{value}' is not one of {allowed}", f"write {key}: followed by one of " + (
            ", ".join(allowed)
        )
    if problem.code in ("greater_than_equal", "greater_than"):
        bound = f"at least {context['ge']:g}" if "ge" in context else f"more than {context['gt']:g}"
        return f"{value} is out of range", f"write a number {bound}"
    if problem.code in ("float_type", "int_type", "int_from_float"):
        whole = problem.code != "float_type"
        return (
            f"'{value}' is not a {'whole ' if whole else ''}number",
            f"write {key}: followed by a {'whole ' if whole else ''}number",
        )
    if problem.code == "bool_type":
        return f"'{value}' is not true or false", write
    if problem.code in ("model_type", "dict_type"):
        allowed = ", ".join(allowed_keys(MappingFile, problem.path))
        return f"expected a mapping of keys, found {value!r}", (
            f"write {key}: followed by indented keys ({allowed})"
        )
    wrong, _, action = problem.text.partition("; ")
    return wrong, action or write

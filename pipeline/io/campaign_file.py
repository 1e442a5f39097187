"""The keys of ``campaign.yaml`` and the type of each value, checked as ``params.yaml`` is.

:class:`CampaignFile` is the contract's ``campaign.yaml`` (:data:`schemas.contract.CAMPAIGN_KEYS`)
as a pydantic model, checked on the mechanism of the typed ``params.yaml`` sections
(:mod:`pipeline.settings.base`); :func:`file_problems` turns what it finds into problems of the
campaign, never an exception, so that the ingest stage records them and the validate stage
quarantines the campaign and goes on:

``wrong_type``
    a value of the wrong type: ``sensors:`` given as a list, ``synthetic: yes please``, a
    sensor's entry that is not a mapping, ``axis: stroke_mm:`` that is not a finite number;
``misspelt_key``
    a key the contract does not have that is a close misspelling of one the file lacks
    (``spilt:`` for ``split:``, ``sensor:`` for ``sensors:``), at the top level or in an entry
    of ``sensors:``, ``displacement:`` or ``axis:``.

Any other key is read as a comment and ignored (``notes:``, a probe's ``location:``), as the
contract says; a missing required key, an unknown kind or a start that is not ISO 8601 are
checked where the row is built (:mod:`pipeline.io.metadata`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, ValidationError

from pipeline.settings.base import closest, described, problems

MAPPING = "a mapping of names to entries (name: {key: value, ...})"
PROGRAM = "a list of entries {from_min: 0, to_min: 240, rpm: 4000}"
LOADS = "a list of entries {role: column_rear, from_min: 0, to_min: 120, power_W: 300}"

MISSPELLING_CUTOFF = 0.8
"""Least similarity of an unknown key to a contract key for it to count as its misspelling;
high, so that a comment key (``notes``, ``operator``) is never taken for one."""


class _Entry(BaseModel):
    """An entry of a mapping in campaign.yaml: known keys typed, any other key a comment."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)


class SensorEntry(_Entry):
    """One temperature sensor (``sensors: <name>:``)."""

    role: Any = None
    location: Any = None
    type: Any = None


class ProbeEntry(_Entry):
    """One displacement probe (``displacement: <axis>:``)."""

    probe: Any = None


class AxisEntry(_Entry):
    """The axis a laser measured (``axis:``)."""

    name: Any = None
    stroke_mm: StrictFloat | None = Field(None, description="a number of millimetres")


Sensor = Annotated[
    SensorEntry | None, Field(description="a mapping such as {role: bed, type: DS18B20}")
]
Probe = Annotated[ProbeEntry | None, Field(description="a mapping such as {probe: eddy_current}")]


class CampaignFile(_Entry):
    """``campaign.yaml``: the typed values of the contract's keys (every one may be absent here)."""

    campaign_id: Any = None
    kind: Any = None
    machine: Any = None
    start: Any = None
    season: Any = None
    synthetic: StrictBool | None = Field(None, description="true or false")
    split: Any = None
    start_state: Any = None
    follows: Any = None
    spindle_program: list[Any] | None = Field(None, description=PROGRAM)
    heat_loads: list[Any] | None = Field(None, description=LOADS)
    sensors: dict[Any, Sensor] | None = Field(None, description=MAPPING)
    displacement: dict[Any, Probe] | None = Field(None, description=MAPPING)
    axis: AxisEntry | None = Field(None, description=MAPPING)


Report = Callable[..., None]


def file_problems(meta: Mapping[str, Any], report: Report) -> None:
    """Report every value of a wrong type and every misspelt key of a ``campaign.yaml``.

    Parameters
    ----------
    meta : mapping
        The parsed ``campaign.yaml``.
    report : callable
        :data:`pipeline.io.files.Report`; receives ``wrong_type`` (fields ``expected`` and
        ``found``) and ``misspelt_key`` (fields ``suggestion`` and ``allowed``) problems, file
        ``campaign.yaml``, no row, column the key path (``sensors.T1``, ``axis.stroke_mm``).
    """
    try:
        CampaignFile.model_validate({str(key): value for key, value in meta.items()})
    except ValidationError as error:
        for problem in problems(error, CampaignFile):
            report(
                "campaign.yaml",
                None,
                ".".join(str(part) for part in problem.path),
                "wrong_type",
                expected=described(CampaignFile, problem.path) or problem.text,
                found=describe(problem.value),
            )
    _misspelt(meta, (), CampaignFile, report)
    for key, entry_model in (("sensors", SensorEntry), ("displacement", ProbeEntry)):
        entries = meta.get(key)
        for name, entry in (entries or {}).items() if isinstance(entries, Mapping) else ():
            if isinstance(entry, Mapping):
                _misspelt(entry, (key, str(name)), entry_model, report)
    if isinstance(meta.get("axis"), Mapping):
        _misspelt(meta["axis"], ("axis",), AxisEntry, report)


def _misspelt(
    mapping: Mapping[str, Any], path: tuple[str, ...], model: type[BaseModel], report: Report
) -> None:
    """Report each key of ``mapping`` that looks like a key of ``model`` the mapping lacks."""
    known = list(model.model_fields)
    absent = [k for k in known if k not in mapping]
    for key in mapping:
        if key in known:
            continue
        suggestion = closest(str(key), absent, MISSPELLING_CUTOFF, shortening=False)
        if suggestion is not None:
            report(
                "campaign.yaml",
                None,
                ".".join((*path, str(key))),
                "misspelt_key",
                suggestion=".".join((*path, suggestion)),
                allowed=", ".join(known),
            )


def describe(value: Any) -> str:
    """Return e.g. ``a list ([1, 2])`` for a message (long values cut)."""
    names = {list: "a list", dict: "a mapping", str: "text", bool: "true/false"}
    name = names.get(type(value), "a number" if isinstance(value, int | float) else "a value")
    text = repr(value)
    return f"{name} ({text[:60]}{'...' if len(text) > 60 else ''})"

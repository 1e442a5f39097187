"""Check the ``heat_loads:`` entries of a ``campaign.yaml`` (external heat put into the machine).

Each entry ``{role, from_min, to_min?, power_W, what?}`` is parsed by the kernel's own parser,
:func:`pipeline.thermal.loads.loads_from_contract`, so that what ingest accepts is exactly what
the physical twin reads; this module only says, per entry, why an entry was refused. Problems
(file ``campaign.yaml``, column ``heat_loads``, the entry's 1-based number in the message):

``bad_heat_load``
    not a mapping, no role, no numeric ``from_min``, no finite ``power_W`` (W), or a time that
    is not finite;
``heat_load_times``
    ``to_min`` not after ``from_min``;
``heat_load_role``
    a role that is not a structure role (:data:`schemas.vocabulary.STRUCTURE_ROLES`);
``heat_loads_overlap``
    two entries of one role on at the same time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pipeline.io.files import Report
from pipeline.thermal.loads import POWER_KEY, loads_from_contract
from schemas.vocabulary import STRUCTURE_ROLES

KEY = "heat_loads"
"""The campaign.yaml key (and the problems' column)."""


def check_heat_loads(entries: list[Any], report: Report) -> None:
    """Report every bad entry of a campaign's ``heat_loads:`` list.

    Parameters
    ----------
    entries : list
        The ``heat_loads:`` list as read from campaign.yaml (``[]`` when absent).
    report : callable
        :data:`pipeline.io.files.Report`; receives ``bad_heat_load``, ``heat_load_times``,
        ``heat_load_role`` and ``heat_loads_overlap`` problems (file ``campaign.yaml``, no row,
        column ``heat_loads``; fields ``number`` (1-based entry), ``entry`` and the details).
    """
    usable: list[tuple[int, Mapping[str, Any]]] = []
    for number, entry in enumerate(entries, start=1):
        if _entry_reported(number, entry, report):
            continue
        if entry["role"] not in STRUCTURE_ROLES:
            report(
                "campaign.yaml",
                None,
                KEY,
                "heat_load_role",
                number=number,
                value=repr(entry["role"]),
            )
            continue
        usable.append((number, entry))
    _report_overlaps(usable, report)


def _entry_reported(number: int, entry: Any, report: Report) -> bool:
    """Report one entry that the parser refuses on its own; return True if it did."""
    if not isinstance(entry, Mapping):
        _bad(
            report, number, repr(entry), "is not a mapping {role: ..., from_min: ..., power_W: ...}"
        )
        return True
    try:
        (load,) = loads_from_contract([entry])
    except (TypeError, ValueError):
        if _ends_before_start(entry):
            report(
                "campaign.yaml",
                None,
                KEY,
                "heat_load_times",
                number=number,
                entry=dict(entry),
                from_min=entry["from_min"],
                to_min=entry["to_min"],
            )
        else:
            _bad(report, number, dict(entry), _lacking(entry))
        return True
    times = [t for s in load.program.segments for t in (s.from_min, s.to_min) if t is not None]
    if not all(math.isfinite(t) for t in times):
        _bad(report, number, dict(entry), "has a from_min or to_min that is not a finite number")
        return True
    return False


def _bad(report: Report, number: int, entry: Any, detail: str) -> None:
    report("campaign.yaml", None, KEY, "bad_heat_load", number=number, entry=entry, detail=detail)


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _ends_before_start(entry: Mapping[str, Any]) -> bool:
    """Whether the entry's only fault is a ``to_min`` not after its ``from_min``.

    It is when the same entry left open-ended is one the parser accepts.
    """
    begin, end = entry.get("from_min"), entry.get("to_min")
    if not (_number(begin) and _number(end) and end <= begin):
        return False
    try:
        loads_from_contract([{**entry, "to_min": None}])
    except (TypeError, ValueError):
        return False
    return True


def _lacking(entry: Mapping[str, Any]) -> str:
    """Word what a refused entry lacks, for the ``bad_heat_load`` message."""
    missing = [k for k in ("role", "from_min", POWER_KEY) if entry.get(k) in (None, "")]
    if missing:
        return "has no " + ", no ".join(missing)
    return "has a role, from_min, to_min or power_W that is not a finite number"


def _report_overlaps(usable: list[tuple[int, Mapping[str, Any]]], report: Report) -> None:
    """Report each pair of entries of one role that are on at the same time."""
    try:
        loads_from_contract([entry for _, entry in usable])
    except ValueError:
        pass
    else:
        return
    for k, (number, entry) in enumerate(usable):
        for other, earlier in usable[:k]:
            if earlier["role"] != entry["role"]:
                continue
            try:
                loads_from_contract([earlier, entry])
            except ValueError:
                report(
                    "campaign.yaml",
                    None,
                    KEY,
                    "heat_loads_overlap",
                    number=number,
                    other=other,
                    role=entry["role"],
                )

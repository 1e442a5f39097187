"""Turn Pandera's lazy ``SchemaErrors`` into located findings (before grouping and wording).

A :class:`Finding` is one failing cell, row or column, already charged to a campaign, a raw
file and its 1-based data row; :mod:`pipeline.validation.rendering` groups and words them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pandas as pd
from pandera.errors import SchemaErrors

from schemas import DATAFRAME_CHECK_COLUMNS

Locate = Callable[[str, str | None, int | None], tuple[str, str, int | None, dict[str, Any]]]
"""``(check, column, index) -> (check id, file, row, extra fields)``."""

Details = Callable[[str, int | None], dict[str, Any]]
"""``(check id, index) -> fields``; a ``value`` field replaces the failing value."""


@dataclass(frozen=True)
class Finding:
    """One failing cell/row/column before grouping and rendering.

    ``row`` is the 1-based data row of ``file`` (None for campaign-level findings);
    ``fields`` are extra template fields (the row's values, axis, sensor, ...).
    """

    campaign: str
    file: str
    check: str
    column: str | None = None
    row: int | None = None
    value: Any = None
    fields: dict[str, Any] = field(default_factory=dict)


def failure_cases(err: SchemaErrors) -> list[tuple[str, str | None, int | None, Any]]:
    """Normalise Pandera's failure cases to ``(check, column, index, value)`` tuples.

    Handles the three shapes Pandera produces: column checks (one row per failing cell),
    row-wise dataframe checks (one row per cell of each failing row: reduced to the column the
    check is about, :data:`schemas.DATAFRAME_CHECK_COLUMNS`), and wide dataframe checks
    returning a boolean frame (failure case ``{column: value}``). Column presence checks carry
    the column name as failure case. Repeats of the same ``(check, column, index)`` are dropped.
    """
    out: list[tuple[str, str | None, int | None, Any]] = []
    seen: set[tuple] = set()
    for rec in err.failure_cases.itertuples(index=False):
        check, column, value = str(rec.check), rec.column, rec.failure_case
        index = None if rec.index is None or pd.isna(rec.index) else int(rec.index)
        column = None if column is None or pd.isna(column) else str(column)
        if check in ("column_in_dataframe", "column_in_schema"):
            items = [(check, str(value), None, value)]
        elif isinstance(value, dict):
            items = [(check, str(c), index, v) for c, v in value.items()]
        elif check in DATAFRAME_CHECK_COLUMNS:
            items = [(check, DATAFRAME_CHECK_COLUMNS[check], index, None)]
        else:
            items = [(check, column, index, value)]
        for item in items:
            key = item[:3]
            if key not in seen:
                seen.add(key)
                out.append(item)
    return out


def cell(frame: pd.DataFrame, index: int | None, column: str | None, default: Any = None) -> Any:
    """Return ``frame.at[index, column]``, or ``default`` when either is None or absent."""
    if index is None or column is None or column not in frame.columns:
        return default
    return frame.at[index, column]


def findings_from_errors(
    err: SchemaErrors,
    frame: pd.DataFrame,
    *,
    campaigns: list[str],
    locate: Locate,
    details: Details | None = None,
) -> list[Finding]:
    """Turn a lazy validation error on ``frame`` into findings.

    Parameters
    ----------
    err : SchemaErrors
    frame : DataFrame
        The validated frame, with a 0..n-1 index.
    campaigns : list of str
        Campaigns a table-wide failure (no row) is charged to.
    locate : callable
        ``(check, column, index) -> (check id, file, row, extra fields)``: renames Pandera's
        structural checks and maps the frame index to the source file row.
    details : callable, optional
        ``(check id, index) -> fields`` computed from the frame for some checks; a ``value``
        field replaces the failing value.

    Returns
    -------
    list of Finding
        One per failure case and campaign, in Pandera's order; a failure on a row is charged
        to the row's ``campaign_id`` (when the frame has one).
    """
    out = []
    for check, column, index, failure_value in failure_cases(err):
        check_id, file, row, extra = locate(check, column, index)
        value = cell(frame, index, column, failure_value)
        fields = dict(frame.loc[index].items()) if index is not None else {}
        fields.update(extra)
        detail = details(check_id, index) if details is not None else {}
        value = detail.pop("value", value)
        fields.update(detail)
        row_campaign = cell(frame, index, "campaign_id")
        for campaign in [row_campaign] if row_campaign is not None else campaigns:
            out.append(Finding(str(campaign), file, check_id, column, row, value, fields))
    return out

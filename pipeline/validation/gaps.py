"""Missing readings: each gap in one sensor's or probe's readings, bridged or dropped.

An empty cell of ``temperature.csv`` or ``displacement.csv`` is a missing reading (the raw
contract); consecutive missing readings of one column form a gap. A gap with a reading on both
sides at most ``validate.max_bridged_gap_s`` apart is bridged by linear interpolation in time
between those two readings. The samples of a longer gap, or of a gap that starts or ends the
column's record (nothing to interpolate from on one side), are dropped: every column of those
rows, so that no later stage meets a sample without a reading. Each gap is a warning
(:class:`pipeline.validation.problems.Gap`), never a problem; :func:`apply_gaps` applies them to
the samples the later stages read, never to the raw files.

Displacement is on the temperature time base: an instant is missing when ``ingest`` left it
without a value but with a source row (an empty displacement cell next to it), and a gap is
measured, and bridged, between the instants around it. An instant outside the displacement
record has no source row and keeps no value, as before (``ingest.max_alignment_gap_s``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.validation.findings import Finding
from pipeline.validation.problems import (
    BRIDGED,
    DISPLACEMENT_FILE,
    DROPPED,
    TEMPERATURE_FILE,
    Gap,
    Problem,
)
from pipeline.validation.rendering import problems_from_findings, span_text
from pipeline.validation.tables import campaign_samples
from pipeline.validation.texts import word
from schemas import ValidationLimits
from schemas.vocabulary import (
    DISPLACEMENT_COLUMN_RE,
    displacement_column,
    displacement_row_column,
    temperature_columns,
)


@dataclass(frozen=True)
class _Span:
    """One gap of one column before it is worded.

    ``file_rows`` are the empty rows of ``file``, ``samples`` the temperature.csv rows of the
    samples without a value, ``before``/``after`` the rows of the readings around the gap (None at
    the start or end of the record); ``kind`` names its text
    (:data:`pipeline.validation.texts.WARNING_TEXTS`, with the prefix ``missing_reading_``).
    """

    file: str
    column: str
    file_rows: tuple[int, ...]
    samples: tuple[int, ...]
    before: int | None
    after: int | None
    gap_s: float | None
    kind: str

    @property
    def handling(self) -> str:
        """:data:`BRIDGED` or :data:`DROPPED`."""
        return BRIDGED if self.kind == "bridged" else DROPPED


def _runs(missing: np.ndarray) -> list[tuple[int, int]]:
    """Return the ``[start, stop)`` index ranges of the runs of True in ``missing``."""
    edges = np.diff(np.concatenate([[0], missing.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _column_spans(
    frame: pd.DataFrame, file: str, column: str, values: str, rows: str, max_gap_s: float
) -> list[_Span]:
    """Return the gaps of one column of a campaign's samples (file order, index 0..n-1).

    ``values`` is the samples column, ``rows`` the column of its 1-based file rows.
    """
    value = frame[values].to_numpy(dtype=float)
    file_row = frame[rows]
    missing = np.isnan(value) & file_row.notna().to_numpy()
    elapsed = frame["elapsed_s"].to_numpy(dtype=float)
    spans = []
    for start, stop in _runs(missing):
        before = start - 1 if start > 0 and not np.isnan(value[start - 1]) else None
        after = stop if stop < len(value) and not np.isnan(value[stop]) else None
        gap_s = None if before is None or after is None else float(elapsed[after] - elapsed[before])
        if before is None:
            kind = "at_start"
        elif after is None:
            kind = "at_end"
        else:
            kind = "bridged" if gap_s <= max_gap_s else "dropped"
        spans.append(
            _Span(
                file=file,
                column=column,
                file_rows=tuple(dict.fromkeys(int(r) for r in file_row.iloc[start:stop])),
                samples=tuple(int(r) for r in frame["source_row"].iloc[start:stop]),
                before=None if before is None else int(file_row.iloc[before]),
                after=None if after is None else int(file_row.iloc[after]),
                gap_s=gap_s,
                kind=kind,
            )
        )
    return spans


def _campaign_spans(frame: pd.DataFrame, max_gap_s: float) -> list[_Span]:
    """Return the gaps of every temperature and displacement column of one campaign."""
    spans = []
    for sensor in temperature_columns(frame.columns):
        spans += _column_spans(frame, TEMPERATURE_FILE, sensor, sensor, "source_row", max_gap_s)
    for name in frame.columns:
        match = DISPLACEMENT_COLUMN_RE.match(str(name))
        if match and displacement_row_column(match.group(1)) in frame:
            axis = match.group(1)
            rows = displacement_row_column(axis)
            spans += _column_spans(frame, DISPLACEMENT_FILE, axis, str(name), rows, max_gap_s)
    return spans


def _gap(campaign_id: str, span: _Span, kept: list[int], limit_s: float) -> Gap:
    """Word one gap: what is missing, how it is handled, what the user may do."""
    first, last = span.file_rows[0], span.file_rows[-1]
    rows_text = span_text("row", first, last)
    lines_text = span_text("line", first + 1, last + 1)
    fields = {
        "campaign": campaign_id,
        "file": span.file,
        "column": span.column,
        "rows": rows_text,
        "where": f"{campaign_id}/{span.file} {rows_text} ({lines_text})",
        "before": span.before,
        "after": span.after,
        "gap_s": "?" if span.gap_s is None else f"{span.gap_s:g}",
        "max_bridged_gap_s": f"{limit_s:g}",
        "n_dropped": len(span.samples),
        "dropped_rows": span_text("row", span.samples[0], span.samples[-1]),
        "first_kept": kept[0] if kept else "none",
        "last_kept": kept[-1] if kept else "none",
    }
    message, action = word(f"missing_reading_{span.kind}", fields)
    return Gap(
        campaign=campaign_id,
        file=span.file,
        column=span.column,
        rows=span.file_rows,
        handling=span.handling,
        samples=span.samples,
        gap_s=span.gap_s,
        message=message,
        action=action,
    )


def campaign_gaps(
    samples: pd.DataFrame, campaign_id: str, limits: ValidationLimits
) -> tuple[list[Gap], int]:
    """Find and word the gaps of missing readings of one (valid) campaign.

    Parameters
    ----------
    samples : DataFrame
        Ingested samples (any campaigns; only this campaign's rows are used).
    campaign_id : str
    limits : ValidationLimits
        ``max_bridged_gap_s``, s.

    Returns
    -------
    gaps : list of Gap
        One per gap of one column, temperature sensors first, in file order.
    kept : int
        The campaign's samples left once the dropped gaps are removed.
    """
    frame = campaign_samples(samples, campaign_id)
    spans = _campaign_spans(frame, limits.max_bridged_gap_s)
    dropped = {r for s in spans if s.handling == DROPPED for r in s.samples}
    kept = [int(r) for r in frame["source_row"] if int(r) not in dropped]
    gaps = [_gap(campaign_id, s, kept, limits.max_bridged_gap_s) for s in spans]
    return gaps, len(kept)


def gaps_of_campaigns(
    samples: pd.DataFrame, campaign_ids: Iterable[str], limits: ValidationLimits
) -> tuple[list[Gap], list[Problem]]:
    """Find the gaps of missing readings of each campaign, and those left too short by them.

    Parameters
    ----------
    samples : DataFrame
        Ingested samples.
    campaign_ids : iterable of str
        The campaigns without any problem.
    limits : ValidationLimits

    Returns
    -------
    gaps : list of Gap
        Every gap (a warning), by campaign.
    problems : list of Problem
        ``too_few_readings`` for a campaign left with fewer than ``min_samples`` samples once
        its dropped gaps are removed (it is then quarantined).
    """
    gaps: list[Gap] = []
    short: list[Finding] = []
    for campaign_id in campaign_ids:
        own, kept = campaign_gaps(samples, campaign_id, limits)
        gaps += own
        if own and kept < limits.min_samples:
            short.append(Finding(campaign_id, TEMPERATURE_FILE, "too_few_readings", value=kept))
    return gaps, problems_from_findings(short, limits)


def apply_gaps(samples: pd.DataFrame, gaps: Iterable[Gap]) -> pd.DataFrame:
    """Return ``samples`` with each bridged gap interpolated and each dropped gap removed.

    Parameters
    ----------
    samples : DataFrame
        Ingested samples (``campaign_id``, ``source_row``, ``elapsed_s``, the columns).
    gaps : iterable of Gap

    Returns
    -------
    DataFrame
        A copy: a bridged gap's samples get the linear interpolation in ``elapsed_s`` between
        the column's readings before and after the gap; the samples of a dropped gap are left
        out (index 0..n-1).
    """
    out = samples.copy()
    gaps = list(gaps)
    for gap in (g for g in gaps if g.handling == BRIDGED):
        column = displacement_column(gap.column) if gap.file == DISPLACEMENT_FILE else gap.column
        own = out.loc[out["campaign_id"] == gap.campaign].sort_values("elapsed_s")
        known = own.loc[own[column].notna()]
        target = own.index[own["source_row"].isin(gap.samples)]
        out.loc[target, column] = np.interp(
            out.loc[target, "elapsed_s"], known["elapsed_s"], known[column]
        )
    dropped = {(g.campaign, r) for g in gaps if g.handling == DROPPED for r in g.samples}
    if not dropped:
        return out
    keys = zip(out["campaign_id"].astype(str), out["source_row"].astype(int), strict=True)
    keep = np.array([key not in dropped for key in keys], dtype=bool)
    return out.loc[keep].reset_index(drop=True)

"""Runs: campaigns cut from one record without a break, and what their first sample means.

A spindle thermal-drift test often runs longer than one campaign: a data logger records a day or
two of speed cycles back to back, and the record is cut into campaigns. Every campaign but the
first then starts *warm*: its first sample is not the cold state, and a thermal error counted
from it would be the change since the cut, not the thermal error. So campaigns are grouped into
*runs* and each run is referenced at its own first sample, the only one that can be cold.

Campaign B continues campaign A (a *link*) when

- B's campaign.yaml says ``follows: A`` (declared), or
- B does not say ``start_state: cold`` and, on the same machine, B's first sample comes at most
  ``max_gap_s`` after A's last one (``start`` + ``elapsed_s``, detected). The data must agree:
  a detected link whose temperatures jump across the cut by more than
  ``max_temperature_jump_degC`` (median over the sensors both campaigns have) is dropped.

A run whose first campaign says ``start_state: warm`` starts warm with an unknown history: the
error is then counted from its first sample, and the reports say so.

Displacement across a link: a probe that stayed mounted reads continuously, so B's first value
continues A's last, up to what really changes across the cut (the drift over the gap, and an
instant shift when the spindle starts or changes speed at the cut: centrifugal growth). A probe
re-zeroed at the cut reads about zero at B's first sample instead. Only that case is stitched:
across a contiguous cut (a gap of at most 2.5 sampling intervals), when B starts within
``max(zero_um, 3 x the step noise)`` of zero and the jump from A's last value (extrapolated over
the gap by A's last slope) exceeds ``max(min_stitch_um, 6 x the step noise)``, B's readings are
shifted so that they continue A's. Every other jump is kept as measured; all are reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.settings.separate import RunSettings

DECLARED, DETECTED = "declared", "detected"
CONTIGUOUS_INTERVALS = 2.5
"""A cut is contiguous when B's first sample is at most this many sampling intervals after A's
last one; only then is a displacement jump stitched."""
STITCH_NOISE_FACTOR = 6.0
ZERO_NOISE_FACTOR = 3.0
ZERO_UM = 0.5
"""A reading within max(ZERO_UM, 3 x step noise) of 0 um is taken as a re-zeroed probe."""
SLOPE_SAMPLES = 10


@dataclass(frozen=True)
class CampaignSpan:
    """When a campaign was measured, from its metadata and sample instants.

    Attributes
    ----------
    campaign_id, machine : str
    start : pandas.Timestamp
        Local time of ``elapsed_s = 0``.
    first_s, last_s : float, s
        First and last ``elapsed_s``.
    interval_s : float, s
        Median sampling interval.
    start_state : str or None
        ``cold``, ``warm`` or not given.
    follows : str or None
        Declared predecessor.
    """

    campaign_id: str
    machine: str
    start: pd.Timestamp
    first_s: float
    last_s: float
    interval_s: float
    start_state: str | None = None
    follows: str | None = None

    @property
    def begins(self) -> pd.Timestamp:
        """Local time of the first sample."""
        return self.start + pd.Timedelta(seconds=self.first_s)

    @property
    def ends(self) -> pd.Timestamp:
        """Local time of the last sample."""
        return self.start + pd.Timedelta(seconds=self.last_s)


@dataclass(frozen=True)
class Link:
    """Campaign ``campaign`` continues campaign ``previous``.

    Attributes
    ----------
    previous, campaign : str
    how : str
        ``declared`` (``follows:``) or ``detected`` (start times).
    gap_s : float, s
        From the previous campaign's last sample to this one's first.
    contiguous : bool
        The gap is at most :data:`CONTIGUOUS_INTERVALS` sampling intervals.
    """

    previous: str
    campaign: str
    how: str
    gap_s: float
    contiguous: bool


@dataclass(frozen=True)
class Run:
    """Campaigns measured without a break, in time order.

    Attributes
    ----------
    campaigns : tuple of str
        The first one is the run's id.
    offsets_s : tuple of float, s
        Run time of each campaign's ``elapsed_s = 0``.
    links : tuple of Link
        ``links[i]`` joins ``campaigns[i]`` and ``campaigns[i + 1]``.
    cold_start : bool
        False when the first campaign says ``start_state: warm``.
    notes : tuple of str
        Why a link was not made (e.g. a declared predecessor that is not among the campaigns).
    """

    campaigns: tuple[str, ...]
    offsets_s: tuple[float, ...]
    links: tuple[Link, ...] = ()
    cold_start: bool = True
    notes: tuple[str, ...] = field(default=())

    @property
    def run_id(self) -> str:
        """The first campaign's id."""
        return self.campaigns[0]


def spans_from_tables(campaigns: pd.DataFrame, samples: pd.DataFrame) -> list[CampaignSpan]:
    """One span per campaign of the validated tables that has samples.

    Parameters
    ----------
    campaigns : DataFrame
        ``campaign_id``, ``machine``, ``start``, optional ``start_state`` and ``follows``.
    samples : DataFrame
        ``campaign_id``, ``elapsed_s`` (s).
    """
    times = samples.groupby("campaign_id")["elapsed_s"]
    spans = []
    for row in campaigns.to_dict("records"):
        cid = str(row["campaign_id"])
        if cid not in times.groups:
            continue
        t = np.sort(times.get_group(cid).to_numpy(dtype=float))
        spans.append(
            CampaignSpan(
                campaign_id=cid,
                machine=str(row.get("machine") or ""),
                start=pd.Timestamp(row["start"]),
                first_s=float(t[0]),
                last_s=float(t[-1]),
                interval_s=float(np.median(np.diff(t))) if t.size > 1 else float("nan"),
                start_state=_text(row.get("start_state")),
                follows=_text(row.get("follows")),
            )
        )
    return spans


def _text(value: object) -> str | None:
    if value is None or (isinstance(value, float) and np.isnan(value)) or value is pd.NA:
        return None
    return str(value)


def _link(previous: CampaignSpan, span: CampaignSpan, how: str) -> Link:
    gap = (span.begins - previous.ends).total_seconds()
    interval = np.nanmax([previous.interval_s, span.interval_s, 1e-9])
    return Link(
        previous.campaign_id,
        span.campaign_id,
        how,
        gap,
        bool(0 <= gap <= CONTIGUOUS_INTERVALS * interval),
    )


def candidate_links(
    spans: Sequence[CampaignSpan], settings: RunSettings
) -> tuple[list[Link], list[str]]:
    """Find the declared and detected links, at most one predecessor and one successor per campaign.

    Returns
    -------
    links : list of Link
    notes : list of str
        Declared predecessors that are not among the campaigns (their successor starts warm
        with an unknown history), and links dropped because a campaign was claimed twice.
    """
    by_id = {s.campaign_id: s for s in spans}
    links, notes = [], []
    for span in spans:
        if span.follows is not None:
            if (
                span.follows in by_id
                and (span.begins - by_id[span.follows].ends).total_seconds() < 0
            ):
                notes.append(
                    f"{span.campaign_id} follows {span.follows} but starts before it ends "
                    "(start and elapsed_s overlap): not linked"
                )
            elif span.follows in by_id:
                links.append(_link(by_id[span.follows], span, DECLARED))
            else:
                notes.append(
                    f"{span.campaign_id} follows {span.follows}, which is not among the valid "
                    "spindle campaigns: it starts warm from an unknown state"
                )
            continue
        if not settings.detect or span.start_state == "cold":
            continue
        before = [
            p
            for p in spans
            if p.machine == span.machine
            and p.campaign_id != span.campaign_id
            and 0.0 <= (span.begins - p.ends).total_seconds() <= settings.max_gap_s
        ]
        if before:
            closest = min(before, key=lambda p: (span.begins - p.ends).total_seconds())
            links.append(_link(closest, span, DETECTED))
    kept, successor = [], {}
    for link in sorted(links, key=lambda k: (k.how != DECLARED, k.gap_s)):
        if link.previous in successor:
            notes.append(
                f"{link.campaign} could continue {link.previous}, which {successor[link.previous]} "
                "already continues: not linked"
            )
            continue
        successor[link.previous] = link.campaign
        kept.append(link)
    return kept, notes


def build_runs(
    spans: Sequence[CampaignSpan], links: Sequence[Link], notes: Sequence[str] = ()
) -> list[Run]:
    """Chain the campaigns along the links into runs, in order of their first sample.

    A declared cycle (A follows B, B follows A) is broken before its earliest campaign.
    """
    by_id = {s.campaign_id: s for s in spans}
    previous = {k.campaign: k for k in links}
    following = {k.previous: k for k in links}
    runs, seen = [], set()
    for span in sorted(spans, key=lambda s: s.begins):
        if span.campaign_id in seen:
            continue
        head, visited = span.campaign_id, {span.campaign_id}
        while head in previous and previous[head].previous not in visited:
            head = previous[head].previous
            visited.add(head)
        chain, chain_links = [head], []
        while chain[-1] in following and following[chain[-1]].campaign not in chain:
            chain_links.append(following[chain[-1]])
            chain.append(following[chain[-1]].campaign)
        seen.update(chain)
        origin = by_id[head].start
        runs.append(
            Run(
                campaigns=tuple(chain),
                offsets_s=tuple((by_id[c].start - origin).total_seconds() for c in chain),
                links=tuple(chain_links),
                cold_start=by_id[head].start_state != "warm",
                notes=tuple(n for n in notes if any(n.startswith(c + " ") for c in chain)),
            )
        )
    return runs


def temperature_jump(before: pd.DataFrame, after: pd.DataFrame) -> float:
    """Median over common sensors of |first reading after - last reading before|, degC.

    NaN when the campaigns share no sensor with readings on both sides.
    """
    jumps = []
    for sensor in set(before.columns) & set(after.columns):
        a = before[sensor].dropna()
        b = after[sensor].dropna()
        if len(a) and len(b):
            jumps.append(abs(float(b.iloc[0]) - float(a.iloc[-1])))
    return float(np.median(jumps)) if jumps else float("nan")


@dataclass(frozen=True)
class Stitch:
    """How a displacement axis crosses a link.

    Attributes
    ----------
    jump_um : float, um
        First reading after minus the last reading before extrapolated over the gap.
    offset_um : float, um
        Added to the later campaign's readings (0 when the readings are continuous).
    """

    jump_um: float
    offset_um: float


def stitch(
    t_before: np.ndarray,
    before: np.ndarray,
    t_after: np.ndarray,
    after: np.ndarray,
    contiguous: bool,
    min_stitch_um: float,
) -> Stitch:
    """Decide whether a displacement series continues across a link (see the module docstring).

    Parameters
    ----------
    t_before, before : ndarray, s and um
        The earlier campaign's run times and readings (already stitched).
    t_after, after : ndarray, s and um
        The later campaign's run times and raw readings.
    contiguous : bool
        Whether the cut is contiguous (see :class:`Link`).
    min_stitch_um : float, um

    Returns
    -------
    Stitch
        NaN jump and zero offset when the earlier side has fewer than two readings or the later
        one none.
    """
    ok_b, ok_a = np.isfinite(before), np.isfinite(after)
    if ok_b.sum() < 2 or ok_a.sum() < 1:
        return Stitch(float("nan"), 0.0)
    tb, yb = t_before[ok_b][-SLOPE_SAMPLES:], before[ok_b][-SLOPE_SAMPLES:]
    slope = np.polyfit(tb - tb[-1], yb, 1)[0] if tb.size >= 3 else 0.0
    expected = yb[-1] + slope * (t_after[ok_a][0] - tb[-1])
    jump = float(after[ok_a][0] - expected)
    steps = np.diff(np.concatenate([before[ok_b], after[ok_a]]))
    noise = 1.4826 * float(np.median(np.abs(steps - np.median(steps)))) if steps.size else 0.0
    tolerance = max(float(min_stitch_um), STITCH_NOISE_FACTOR * noise)
    re_zeroed = abs(float(after[ok_a][0])) <= max(ZERO_UM, ZERO_NOISE_FACTOR * noise)
    offset = -jump if contiguous and re_zeroed and abs(jump) > tolerance else 0.0
    return Stitch(jump, offset)

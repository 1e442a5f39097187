"""Cut one long logger record into campaigns by a stated rule.

The spindle is *stopped* at a sample whose speed is at most ``stop_rpm`` in magnitude and
*running* otherwise. A *stop* is a maximal stretch of stopped samples; it lasts from its first
stopped sample to the first running sample after it (to the last sample of the record when the
record ends stopped). Only stops of at least ``min_stop_min`` minutes count: a shorter one (a
tool change, a probe check) is part of the running period around it.

Rules (the index of a campaign's first sample is its *cut*):

``speed_cycles``
    A campaign is one running period plus the stop that follows it: cut at the first running
    sample after each stop. A stop at the very start of the record belongs to the first
    campaign (the machine at rest before its first cycle).
``stops``
    Cut at the first stopped sample of each stop: a campaign is a stop (cooling) followed by the
    running period after it; the first campaign is the record up to the first stop. (Cutting at
    the end of each stop instead is ``speed_cycles``.)
``fixed``
    Cut every ``window_h`` hours from the first sample, at the first sample at or after each
    multiple of the window.

A cut that would leave a campaign with fewer than :data:`MIN_SAMPLES` samples is dropped (those
samples stay with the campaign before).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

logger = logging.getLogger(__name__)

RULES = ("speed_cycles", "stops", "fixed")
"""Known cut rules."""

MIN_SAMPLES = 10
"""Fewest samples a cut may leave in a campaign: the validate stage's default
``validate.min_samples`` (a shorter spindle campaign is quarantined as too short to model)."""


@dataclass(frozen=True)
class CutRule:
    """How a record is cut (mapping file ``cut:`` or command-line flags).

    Attributes
    ----------
    rule : str
        One of :data:`RULES`.
    min_stop_min : float, min
        Shortest stop that counts (``speed_cycles``, ``stops``).
    window_h : float or None, h
        Window length of the ``fixed`` rule.
    stop_rpm : float, rpm
        The spindle is stopped at a speed of at most this magnitude.
    cold_after_stop_h : float or None, h
        A campaign whose first sample comes after the spindle has been stopped at least this
        long starts cold: it is written ``start_state: cold`` without ``follows:``, the first
        campaign of a new run. None: every campaign after the first continues the one before.
    """

    rule: str = "speed_cycles"
    min_stop_min: float = 10.0
    window_h: float | None = None
    stop_rpm: float = 0.0
    cold_after_stop_h: float | None = None

    def describe(self) -> str:
        """Return the rule and its parameters in words (for logs and campaign.yaml notes)."""
        if self.rule == "fixed":
            text = f"fixed windows of {self.window_h:g} h"
        else:
            at = "end" if self.rule == "speed_cycles" else "start"
            text = (
                f"{self.rule} (cut at the {at} of every stop of at least {self.min_stop_min:g} "
                f"min; stopped at <= {self.stop_rpm:g} rpm)"
            )
        if self.cold_after_stop_h is not None:
            text += f"; cold after a stop of at least {self.cold_after_stop_h:g} h"
        return text


@dataclass(frozen=True)
class Segment:
    """One campaign's samples in the record.

    Attributes
    ----------
    first, stop : int
        The campaign is samples ``first`` to ``stop - 1`` of the record.
    stopped_before_s : float, s
        How long the spindle had been stopped at the campaign's first sample (0 when it ran
        just before; 0 for the first campaign, whose history the record does not hold).
    """

    first: int
    stop: int
    stopped_before_s: float


def stop_periods(rpm: np.ndarray, stop_rpm: float) -> list[tuple[int, int]]:
    """Stretches of stopped samples.

    Parameters
    ----------
    rpm : ndarray of shape (n,), rpm
        Spindle speed of every sample.
    stop_rpm : float, rpm

    Returns
    -------
    list of (int, int)
        ``(begin, end)``: samples ``begin`` to ``end - 1`` are stopped and ``end`` is the first
        running sample after them (``n`` when the record ends stopped).
    """
    stopped = np.abs(np.asarray(rpm, dtype=float)) <= stop_rpm
    edges = np.diff(np.concatenate([[False], stopped, [False]]).astype(np.int8))
    return list(
        zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True)
    )


def _stop_duration_s(elapsed_s: np.ndarray, begin: int, end: int) -> float:
    return float(elapsed_s[min(end, len(elapsed_s) - 1)] - elapsed_s[begin])


def cut_indices(elapsed_s: np.ndarray, rpm: np.ndarray, rule: CutRule) -> list[int]:
    """First sample of every campaign under ``rule``.

    Parameters
    ----------
    elapsed_s : ndarray of shape (n,), s
        Time of every sample, strictly increasing.
    rpm : ndarray of shape (n,), rpm
        Spindle speed of every sample.
    rule : CutRule

    Returns
    -------
    list of int
        Increasing sample indices, starting with 0.
    """
    n = len(elapsed_s)
    if rule.rule == "fixed":
        window_s = float(rule.window_h) * 3600.0
        marks = elapsed_s[0] + window_s * np.arange(
            1, int((elapsed_s[-1] - elapsed_s[0]) // window_s) + 1
        )
        candidates = np.searchsorted(elapsed_s, marks, side="left").tolist()
    else:
        long_stops = [
            (begin, end)
            for begin, end in stop_periods(rpm, rule.stop_rpm)
            if _stop_duration_s(elapsed_s, begin, end) >= rule.min_stop_min * 60.0
        ]
        if rule.rule == "speed_cycles":
            candidates = [end for begin, end in long_stops if begin > 0]
        else:
            candidates = [begin for begin, _ in long_stops]
    cuts = [0]
    for index in sorted(set(candidates)):
        if index - cuts[-1] >= MIN_SAMPLES and n - index >= MIN_SAMPLES:
            cuts.append(int(index))
    dropped = len({c for c in candidates if 0 < c < n}) - (len(cuts) - 1)
    if dropped:
        logger.warning(
            "%d cut(s) of the %s rule left fewer than %d samples in a campaign: not cut there",
            dropped,
            rule.rule,
            MIN_SAMPLES,
        )
    return cuts


def segments(elapsed_s: np.ndarray, rpm: np.ndarray, rule: CutRule) -> list[Segment]:
    """Cut the record into campaigns.

    Parameters
    ----------
    elapsed_s, rpm, rule
        Sample times (s), spindle speeds (rpm) and the rule, as for :func:`cut_indices`.

    Returns
    -------
    list of Segment
        In time order; together they hold every sample once.
    """
    cuts = cut_indices(elapsed_s, rpm, rule)
    stop_begin = np.full(len(elapsed_s), -1)
    for begin, end in stop_periods(rpm, rule.stop_rpm):
        stop_begin[begin:end] = begin
    result = []
    for first, stop in zip(cuts, [*cuts[1:], len(elapsed_s)], strict=True):
        begin = stop_begin[first - 1] if first > 0 else -1
        stopped = float(elapsed_s[first] - elapsed_s[begin]) if begin >= 0 else 0.0
        result.append(Segment(first, stop, stopped))
    return result

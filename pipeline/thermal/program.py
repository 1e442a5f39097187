"""Piecewise-constant operating programs: spindle speed (rpm) or axis feed (mm/s).

The raw contract writes a spindle program as ``[{from_min, to_min?, rpm}, ...]`` (minutes from
the campaign start, the last entry may be open-ended); :class:`Program` reads and writes that
form and evaluates the value at any instant (right-continuous: at a breakpoint the new value).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Segment:
    """One constant piece of a program.

    Attributes
    ----------
    from_min : float
        Start, minutes since the campaign start.
    to_min : float or None
        End, minutes (exclusive); None = open-ended.
    value : float
        Spindle speed (rpm) or axis feed (mm/s) during the segment.
    """

    from_min: float
    to_min: float | None
    value: float


@dataclass(frozen=True)
class Program:
    """A piecewise-constant program.

    The value is 0 before the first segment and after a closed last segment.

    Attributes
    ----------
    segments : tuple of Segment
        Sorted, non-overlapping pieces.
    key : str
        Name of the value in the contract form: ``"rpm"`` or ``"feed_mm_s"``.
    """

    segments: tuple[Segment, ...]
    key: str = "rpm"

    def __post_init__(self) -> None:
        """Check the segments are ordered and do not overlap."""
        for a, b in zip(self.segments, self.segments[1:], strict=False):
            if a.to_min is None or a.to_min > b.from_min:
                raise ValueError(
                    f"program: segment starting at {a.from_min} min overlaps the one starting "
                    f"at {b.from_min} min; give each segment a to_min <= the next from_min"
                )
        for s in self.segments:
            if s.to_min is not None and s.to_min <= s.from_min:
                raise ValueError(f"program: segment at {s.from_min} min has to_min <= from_min")

    @classmethod
    def constant(cls, value: float, key: str = "rpm") -> Program:
        """Return a program holding ``value`` from 0 min on."""
        return cls((Segment(0.0, None, float(value)),), key=key)

    @classmethod
    def from_contract(cls, entries: Iterable[Mapping[str, Any]], key: str = "rpm") -> Program:
        """Build from the contract list ``[{from_min, to_min?, <key>}, ...]``.

        Parameters
        ----------
        entries : iterable of mapping
            E.g. the ``spindle_program`` of a campaign.yaml.
        key : str
            Name of the value field (``"rpm"`` for spindle programs).

        Raises
        ------
        ValueError
            If an entry lacks ``from_min`` or the value key; the message names the entry.
        """
        segments = []
        for i, e in enumerate(entries):
            if "from_min" not in e or key not in e:
                raise ValueError(
                    f"program entry {i} ({dict(e)}) needs 'from_min' and '{key}'; "
                    f"write it as {{from_min: 0, to_min: 240, {key}: ...}}"
                )
            to_min = e.get("to_min")
            segments.append(
                Segment(
                    float(e["from_min"]), None if to_min is None else float(to_min), float(e[key])
                )
            )
        return cls(tuple(sorted(segments, key=lambda s: s.from_min)), key=key)

    @classmethod
    def from_log(cls, elapsed_s: np.ndarray, values: np.ndarray, key: str = "rpm") -> Program:
        """Zero-order hold of a measured log (e.g. spindle.csv), one segment per sample."""
        t = np.asarray(elapsed_s, dtype=float) / 60.0
        v = np.asarray(values, dtype=float)
        segments = [
            Segment(float(t[i]), float(t[i + 1]) if i + 1 < t.size else None, float(v[i]))
            for i in range(t.size)
        ]
        return cls(tuple(segments), key=key)

    def to_contract(self) -> list[dict[str, float]]:
        """Return the contract list form (``to_min`` omitted for an open-ended segment)."""
        out = []
        for s in self.segments:
            entry: dict[str, float] = {"from_min": s.from_min}
            if s.to_min is not None:
                entry["to_min"] = s.to_min
            entry[self.key] = s.value
            out.append(entry)
        return out

    def breakpoints_s(self) -> np.ndarray:
        """Instants where the value may jump, s, sorted unique, shape (k,)."""
        pts = [s.from_min for s in self.segments]
        pts += [s.to_min for s in self.segments if s.to_min is not None]
        return np.unique(np.asarray(pts, dtype=float) * 60.0)

    def value_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Value at each instant (right-continuous), same shape as ``t_s``."""
        t_min = np.asarray(t_s, dtype=float) / 60.0
        out = np.zeros_like(t_min)
        for s in self.segments:
            end = np.inf if s.to_min is None else s.to_min
            out = np.where((t_min >= s.from_min) & (t_min < end), s.value, out)
        return out

"""What validation reports: problems, gaps of missing readings, and the stage outcome.

One :class:`Problem` per finding group (it quarantines the campaign), one :class:`Gap` per run of
missing readings of one column (a warning), and :class:`ValidationResult`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

CAMPAIGN_FILE = "campaign.yaml"
TEMPERATURE_FILE = "temperature.csv"
DISPLACEMENT_FILE = "displacement.csv"
LASER_FILE = "laser.csv"


class NoValidCampaignError(RuntimeError):
    """Raised when every campaign is quarantined (or there is none)."""


@dataclass(frozen=True)
class Problem:
    """One entry of ``reports/validation.json``.

    ``row`` is the 1-based data row of ``file`` (the first of a group of consecutive rows; the
    message names them all), None for campaign-level problems; ``line`` is ``row + 1`` (a CSV's
    header is line 1). In ``campaign.yaml`` the row is the line.
    """

    campaign: str
    file: str
    row: int | None
    column: str | None
    check: str
    value: Any
    message: str
    action: str

    @property
    def line(self) -> int | None:
        """File line of ``row`` (a CSV's header is line 1; a YAML row is its line)."""
        if self.row is None:
            return None
        return self.row if self.file.endswith(".yaml") else self.row + 1

    def to_dict(self) -> dict[str, Any]:
        """Return the report entry (JSON-ready)."""
        return {
            "campaign": self.campaign,
            "file": self.file,
            "row": self.row,
            "line": self.line,
            "column": self.column,
            "check": self.check,
            "value": self.value,
            "message": self.message,
            "action": self.action,
        }


BRIDGED, DROPPED = "bridged", "dropped"
"""How a gap of missing readings is handled in the validated data."""


@dataclass(frozen=True)
class Gap:
    """One warning of ``reports/validation.json``: consecutive missing readings of one column.

    Not a problem: the campaign stays valid, and the validated samples are bridged by linear
    interpolation in time (``handling`` :data:`BRIDGED`) or lose the samples of the gap
    (:data:`DROPPED`).

    Attributes
    ----------
    campaign, file, column : str
        The campaign, ``temperature.csv`` or ``displacement.csv``, and the sensor or axis.
    rows : tuple of int
        1-based data rows of ``file`` whose cell of ``column`` is empty.
    handling : str
        :data:`BRIDGED` or :data:`DROPPED`.
    samples : tuple of int
        The samples concerned, as their 1-based ``temperature.csv`` rows: interpolated when
        bridged, removed when dropped.
    gap_s : float or None, s
        Time from the reading before the gap to the reading after it; None when the gap starts
        or ends the record.
    message, action : str
        What is missing and how it was handled; what the user may do.
    """

    campaign: str
    file: str
    column: str
    rows: tuple[int, ...]
    handling: str
    samples: tuple[int, ...]
    gap_s: float | None
    message: str
    action: str

    def to_dict(self) -> dict[str, Any]:
        """Return the report entry (JSON-ready); ``row``/``line`` are the first empty row's."""
        return {
            "campaign": self.campaign,
            "file": self.file,
            "row": self.rows[0],
            "line": self.rows[0] + 1,
            "column": self.column,
            "check": "missing_reading",
            "rows": list(self.rows),
            "handling": self.handling,
            "gap_s": self.gap_s,
            "samples": list(self.samples),
            "message": self.message,
            "action": self.action,
        }


@dataclass(frozen=True)
class ValidationResult:
    """Outcome of :func:`pipeline.validation.checks.validate_tables`.

    Attributes
    ----------
    campaigns : tuple of str
        Every campaign id seen in any ingested table, sorted.
    problems : tuple of Problem
        Every problem, grouped by campaign.
    gaps : tuple of Gap
        The missing readings of the valid campaigns and how each gap is handled (warnings).
    """

    campaigns: tuple[str, ...]
    problems: tuple[Problem, ...]
    gaps: tuple[Gap, ...] = ()

    @property
    def quarantined(self) -> list[str]:
        """Campaigns with at least one problem, sorted."""
        return sorted({p.campaign for p in self.problems})

    @property
    def valid(self) -> list[str]:
        """Campaigns without any problem, sorted."""
        bad = set(self.quarantined)
        return [c for c in self.campaigns if c not in bad]


def row_number(value: Any) -> int | None:
    """Return a 1-based file row as ``int``, None when it is missing (None, NaN, ``pd.NA``)."""
    return None if value is None or pd.isna(value) else int(value)

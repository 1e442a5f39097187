"""Report a validation result: ``reports/validation.json``, the log lines, the failure."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pipeline.validation.problems import BRIDGED, DROPPED, NoValidCampaignError, ValidationResult


def build_report(
    result: ValidationResult, machines: Mapping[str, str] | None = None
) -> dict[str, Any]:
    """Return the content of ``reports/validation.json``.

    ``problems`` quarantine their campaigns; ``warnings`` are the gaps of missing readings of
    the other campaigns, each with how it is handled in the validated data. ``machines``: each
    campaign's machine (``""`` when unknown), written as ``summary.machines``.
    """
    return {
        "summary": {
            "campaigns": len(result.campaigns),
            "valid": result.valid,
            "quarantined": result.quarantined,
            "machines": {c: (machines or {}).get(c, "") for c in result.campaigns},
        },
        "problems": [p.to_dict() for p in result.problems],
        "warnings": [g.to_dict() for g in result.gaps],
    }


def require_valid(result: ValidationResult, report_path: Path | str) -> None:
    """Raise :class:`NoValidCampaignError` (naming the report) when no campaign is valid."""
    if not result.campaigns:
        raise NoValidCampaignError(
            "validate: no campaign found in data/ingested; add campaign folders under "
            f"data/raw/ (see docs/data-contract.md) and rerun dvc repro (report: {report_path})"
        )
    if not result.valid:
        raise NoValidCampaignError(
            f"validate: no valid campaign: all {len(result.campaigns)} campaigns are quarantined "
            f"({', '.join(result.quarantined)}); see {report_path} for every problem and what to "
            "do, fix the raw files and rerun dvc repro"
        )


def quarantine_summary(result: ValidationResult, campaign_id: str) -> str:
    """Return a one-line summary of a quarantined campaign's problems, for the log."""
    own = [p for p in result.problems if p.campaign == campaign_id]
    counts: dict[str, int] = {}
    for p in own:
        label = f"{p.check} ({p.file}{' ' + p.column if p.column else ''})"
        counts[label] = counts.get(label, 0) + 1
    parts = [f"{label} x{n}" if n > 1 else label for label, n in counts.items()]
    return f"{len(own)} problem(s): " + "; ".join(parts)


def gap_summaries(result: ValidationResult) -> dict[str, str]:
    """Return a one-line summary of each campaign's gaps of missing readings, for the log.

    Returns
    -------
    dict of str to str
        Campaign id -> e.g. ``3 gap(s) of missing readings: 2 bridged, 1 dropped (4 samples)``.
    """
    summaries = {}
    for campaign_id in dict.fromkeys(g.campaign for g in result.gaps):
        own = [g for g in result.gaps if g.campaign == campaign_id]
        bridged = sum(g.handling == BRIDGED for g in own)
        dropped = {s for g in own if g.handling == DROPPED for s in g.samples}
        summaries[campaign_id] = (
            f"{len(own)} gap(s) of missing readings: {bridged} bridged, "
            f"{len(own) - bridged} dropped ({len(dropped)} samples)"
        )
    return summaries

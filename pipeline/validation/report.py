"""Report a validation result: ``reports/validation.json``, the log line, the failure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pipeline.validation.problems import NoValidCampaignError, ValidationResult


def build_report(result: ValidationResult) -> dict[str, Any]:
    """Return the content of ``reports/validation.json``."""
    return {
        "summary": {
            "campaigns": len(result.campaigns),
            "valid": result.valid,
            "quarantined": result.quarantined,
        },
        "problems": [p.to_dict() for p in result.problems],
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

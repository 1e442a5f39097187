"""The repository's ``params.yaml`` sections, typed and checked as the stages read them."""

from __future__ import annotations

from pathlib import Path

from pipeline.settings.base import load_settings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.validate import ValidateSettings
from schemas import ValidationLimits

REPO_PARAMS = Path(__file__).resolve().parents[2] / "params.yaml"


def alignment_gap_s() -> float:
    """``ingest.max_alignment_gap_s`` of the repository, s."""
    return load_settings(IngestSettings, "ingest", REPO_PARAMS).max_alignment_gap_s


def validation_limits() -> ValidationLimits:
    """The check limits of the repository's ``validate`` section."""
    return load_settings(ValidateSettings, "validate", REPO_PARAMS).limits()

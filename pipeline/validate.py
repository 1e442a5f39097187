"""The ``validate`` stage: Pandera checks per campaign; quarantine every campaign with a problem.

``thermal validate`` reads ``data/ingested/*.parquet``, validates each campaign lazily against
the models of :mod:`schemas` (its sensor map and displacement axes added per campaign), turns
every failure case and every ingest problem into a problem naming campaign, file, row (1-based
data row), line, column and check, and writes

- ``data/validated/spindle/{campaigns,samples}.parquet`` and
  ``data/validated/axis/{campaigns,samples,laser}.parquet``: the ingested tables restricted to
  the valid campaigns (samples columns without data for them dropped);
- ``reports/validation.json``: ``{"summary": {"campaigns", "valid", "quarantined"},
  "problems": [{"campaign", "file", "row", "line", "column", "check", "value", "message",
  "action"}]}``.

A campaign with any problem is left out and logged as a warning; the stage fails only when no
campaign is valid. Raw files are never touched. The checks, texts and report live in
:mod:`pipeline.validation`; this module combines them (:func:`validate_tables`) and does the I/O.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.config import load_section
from pipeline.errors import MissingInputError
from pipeline.validation.campaign_checks import validate_campaign_table
from pipeline.validation.findings import Finding
from pipeline.validation.ingest_problems import problems_from_ingest
from pipeline.validation.laser_checks import validate_laser
from pipeline.validation.limits import limits_from_params
from pipeline.validation.plausibility import validate_plausibility
from pipeline.validation.problems import (
    CAMPAIGN_FILE,
    LASER_FILE,
    TEMPERATURE_FILE,
    NoValidCampaignError,
    ValidationResult,
)
from pipeline.validation.rendering import problems_from_findings
from pipeline.validation.report import build_report, quarantine_summary, require_valid
from pipeline.validation.sample_checks import validate_samples
from pipeline.validation.tables import select_valid
from schemas import ValidationLimits
from schemas.vocabulary import AXIS_KIND

logger = logging.getLogger(__name__)

FOLLOW_ON_CHECKS = frozenset(
    {"no_samples", "no_laser", "sensor_column_missing", "displacement_column_missing"}
)
"""Problems that only repeat a file-level ingest problem (missing/unreadable file)."""

OUTPUT_FILES = {
    "campaigns": paths.CAMPAIGNS_FILE,
    "samples": paths.SAMPLES_FILE,
    "laser": paths.LASER_FILE,
}


def validate_tables(
    campaigns: pd.DataFrame,
    samples: pd.DataFrame,
    laser: pd.DataFrame,
    problems: pd.DataFrame,
    limits: ValidationLimits,
) -> ValidationResult:
    """Validate every campaign of the ingested tables.

    Parameters
    ----------
    campaigns, samples, laser, problems : DataFrame
        The four tables written by ``ingest`` (``data/ingested/*.parquet``).
    limits : ValidationLimits

    Returns
    -------
    ValidationResult
        All problems: ingest's, campaign.yaml's, samples' (every campaign) and laser's
        (axis_positioning campaigns) and the campaign-level plausibility checks (sample count,
        units). :data:`FOLLOW_ON_CHECKS` are left out when ingest already reported a file-level
        problem (no row) with that file, e.g. a missing file, and a campaign.yaml problem on a
        key ingest already reported (e.g. ``missing_key`` kind, then not ``kind_known``).
        A campaign with data but no campaigns row and no ingest problem gets
        ``campaign_metadata_missing``.
    """
    found = problems_from_ingest(problems)
    unreadable = {(p.campaign, p.file) for p in found if p.row is None}
    yaml_keys = {(p.campaign, p.column) for p in found if p.file == CAMPAIGN_FILE and p.column}
    found += [
        p
        for p in validate_campaign_table(campaigns, limits)
        if (p.campaign, p.column) not in yaml_keys
    ]
    for campaign in campaigns.to_dict("records"):
        campaign_id = str(campaign["campaign_id"])
        own = validate_samples(campaign, samples, limits)
        own += validate_plausibility(campaign, samples, limits)
        if campaign.get("kind") == AXIS_KIND:
            own += validate_laser(campaign_id, laser, limits)
        found += [
            p
            for p in own
            if not (p.check in FOLLOW_ON_CHECKS and (p.campaign, p.file) in unreadable)
        ]
    known = {str(c) for c in campaigns["campaign_id"]} | {p.campaign for p in found}
    orphans = [
        Finding(str(c), file, "campaign_metadata_missing")
        for table, file in ((samples, TEMPERATURE_FILE), (laser, LASER_FILE))
        for c in pd.unique(table["campaign_id"])
        if str(c) not in known
    ]
    found += problems_from_findings(orphans, limits)
    all_ids = known | {f.campaign for f in orphans}
    ordered = sorted(found, key=lambda p: p.campaign)  # stable: keeps the order within one
    return ValidationResult(campaigns=tuple(sorted(all_ids)), problems=tuple(ordered))


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise MissingInputError(f"{path} not found; run the ingest stage first (dvc repro)")
    return pd.read_parquet(path)


def main(argv: list[str] | None = None) -> int:
    """Run the validate stage; return 0, or 1 when no campaign is valid.

    Reads ``params.yaml`` ``validate:`` and ``data/ingested/*.parquet``; writes
    ``data/validated/{spindle,axis}/*.parquet`` and ``reports/validation.json``.
    """
    parser = argparse.ArgumentParser(
        prog="thermal validate",
        description="Validate the ingested campaigns (Pandera); quarantine every campaign with "
        f"a problem; write data/validated/ and {paths.VALIDATION_REPORT}.",
    )
    parser.parse_args(argv)
    limits = limits_from_params(load_section("validate"))
    campaigns = _read(paths.INGESTED_CAMPAIGNS)
    samples = _read(paths.INGESTED_SAMPLES)
    laser = _read(paths.INGESTED_LASER)
    problems = _read(paths.INGESTED_PROBLEMS)

    result = validate_tables(campaigns, samples, laser, problems, limits)
    for campaign_id in result.quarantined:
        logger.warning(
            "campaign %s quarantined: %s; see %s",
            campaign_id,
            quarantine_summary(result, campaign_id),
            paths.VALIDATION_REPORT,
        )
    paths.VALIDATION_REPORT.parent.mkdir(parents=True, exist_ok=True)
    paths.VALIDATION_REPORT.write_text(
        json.dumps(build_report(result), indent=2, ensure_ascii=False) + "\n", encoding="utf-8"
    )
    try:
        require_valid(result, paths.VALIDATION_REPORT)
    except NoValidCampaignError as err:
        logger.error("%s", err)
        return 1

    outputs = select_valid(campaigns, samples, laser, result.valid)
    for name, directory in (("spindle", paths.VALIDATED_SPINDLE), ("axis", paths.VALIDATED_AXIS)):
        directory.mkdir(parents=True, exist_ok=True)
        for table, frame in outputs[name].items():
            frame.to_parquet(directory / OUTPUT_FILES[table], index=False)
    logger.info(
        "validate: %d of %d campaigns valid (%s); %d quarantined; report %s",
        len(result.valid),
        len(result.campaigns),
        ", ".join(result.valid),
        len(result.quarantined),
        paths.VALIDATION_REPORT,
    )
    return 0

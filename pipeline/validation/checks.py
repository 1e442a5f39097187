"""Every check of every campaign of the ingested tables, combined into one validation result.

First the folder: which machine each campaign is of; a campaign whose machine is unknown is
quarantined (:mod:`pipeline.validation.machines`). Per campaign: the Pandera models of
:mod:`schemas` (its sensor map and displacement axes added), the sample, laser and
plausibility checks of this package, and the ingest problems; a campaign with any problem is
quarantined (:class:`pipeline.validation.problems.ValidationResult`). The gaps of missing
readings of the other campaigns are warnings (:mod:`pipeline.validation.gaps`).
"""

from __future__ import annotations

import pandas as pd

from pipeline.validation.campaign_checks import validate_campaign_table
from pipeline.validation.findings import Finding
from pipeline.validation.gaps import gaps_of_campaigns
from pipeline.validation.ingest_problems import problems_from_ingest
from pipeline.validation.laser_checks import validate_laser
from pipeline.validation.machines import machine_findings
from pipeline.validation.plausibility import validate_plausibility
from pipeline.validation.problems import (
    CAMPAIGN_FILE,
    LASER_FILE,
    TEMPERATURE_FILE,
    ValidationResult,
)
from pipeline.validation.rendering import problems_from_findings
from pipeline.validation.sample_checks import validate_samples
from schemas import ValidationLimits
from schemas.vocabulary import AXIS_KIND

FOLLOW_ON_CHECKS = frozenset(
    {"no_samples", "no_laser", "sensor_column_missing", "displacement_column_missing"}
)
"""Problems that only repeat a file-level ingest problem (missing/unreadable file)."""


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
        The gaps of missing readings of the campaigns without problems (warnings; a campaign
        they leave with fewer than ``min_samples`` samples gets ``too_few_readings``), and
        all problems: ingest's, campaign.yaml's, samples' (every campaign) and laser's
        (axis_positioning campaigns) and the campaign-level plausibility checks (sample count,
        units). :data:`FOLLOW_ON_CHECKS` are left out when ingest already reported a file-level
        problem (no row) with that file, e.g. a missing file, and a campaign.yaml problem on a
        key ingest already reported (e.g. ``missing_key`` kind, then not ``kind_known``).
        A campaign with data but no campaigns row and no ingest problem gets
        ``campaign_metadata_missing``; a campaign whose machine is unknown, or that follows a
        campaign of another machine, gets the problems of :mod:`pipeline.validation.machines`.
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
    found += problems_from_findings(orphans + machine_findings(campaigns), limits)
    all_ids = known | {f.campaign for f in orphans}
    bad = {p.campaign for p in found}
    gaps, short = gaps_of_campaigns(samples, sorted(all_ids - bad), limits)
    found += short
    ordered = sorted(found, key=lambda p: p.campaign)  # stable: keeps the order within one
    return ValidationResult(
        campaigns=tuple(sorted(all_ids)), problems=tuple(ordered), gaps=tuple(gaps)
    )

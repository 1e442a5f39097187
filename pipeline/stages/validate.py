"""The ``validate`` stage: Pandera checks per campaign; quarantine every campaign with a problem.

``thermal validate`` reads ``data/ingested/*.parquet``, validates each campaign lazily against
the models of :mod:`schemas` (its sensor map and displacement axes added per campaign), turns
every failure case and every ingest problem into a problem naming campaign, file, row (1-based
data row), line, column and check, finds the gaps of missing readings (empty cells) of the other
campaigns, and writes

- ``data/validated/spindle/{campaigns,samples}.parquet`` and
  ``data/validated/axis/{campaigns,samples,laser}.parquet``: the ingested tables restricted to
  the valid campaigns (samples columns without data for them dropped; ``machine`` the machine
  each campaign is of, :func:`pipeline.machines.resolved_names`), each gap of missing
  readings bridged by linear interpolation in time or its samples dropped
  (``validate.max_bridged_gap_s``);
- ``reports/validation.json``: ``{"summary": {"campaigns", "valid", "quarantined"},
  "problems": [{"campaign", "file", "row", "line", "column", "check", "value", "message",
  "action"}], "warnings": [{"campaign", "file", "row", "line", "column", "check", "rows",
  "handling", "gap_s", "samples", "message", "action"}]}``.

A campaign with any problem is left out and logged as a warning; a gap of missing readings is
a warning only. The stage fails when no campaign is valid. A folder may hold the campaigns of
several machines: every later stage models each machine on its own. Raw files are never
touched. The checks, texts and report live in :mod:`pipeline.validation`; this module combines
them (:func:`validate_tables`) and does the I/O.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.machines import resolved_names
from pipeline.settings.base import load_settings
from pipeline.settings.validate import ValidateSettings
from pipeline.validation.checks import validate_tables
from pipeline.validation.gaps import apply_gaps
from pipeline.validation.problems import (
    NoValidCampaignError,
)
from pipeline.validation.report import (
    build_report,
    gap_summaries,
    quarantine_summary,
    require_valid,
)
from pipeline.validation.tables import select_valid
from pipeline.warnings_capture import summarise_warnings

logger = logging.getLogger(__name__)


OUTPUT_FILES = {
    "campaigns": paths.CAMPAIGNS_FILE,
    "samples": paths.SAMPLES_FILE,
    "laser": paths.LASER_FILE,
}


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise MissingInputError(f"{path} not found; run the ingest stage first (dvc repro)")
    return pd.read_parquet(path)


@summarise_warnings()
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
    limits = load_settings(ValidateSettings, "validate").limits()
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
    for campaign_id, summary in gap_summaries(result).items():
        logger.warning("campaign %s: %s; see %s", campaign_id, summary, paths.VALIDATION_REPORT)
    machines = dict(
        zip(campaigns["campaign_id"].astype(str), resolved_names(campaigns), strict=True)
    )
    paths.VALIDATION_REPORT.parent.mkdir(parents=True, exist_ok=True)
    paths.VALIDATION_REPORT.write_text(
        json.dumps(build_report(result, machines), indent=2, ensure_ascii=False) + "\n",
        encoding="utf-8",
    )
    try:
        require_valid(result, paths.VALIDATION_REPORT)
    except NoValidCampaignError as err:
        logger.error("%s", err)
        return 1

    campaigns = campaigns.assign(machine=resolved_names(campaigns))
    outputs = select_valid(campaigns, apply_gaps(samples, result.gaps), laser, result.valid)
    for name, directory in (("spindle", paths.VALIDATED_SPINDLE), ("axis", paths.VALIDATED_AXIS)):
        directory.mkdir(parents=True, exist_ok=True)
        for table, frame in outputs[name].items():
            frame.to_parquet(directory / OUTPUT_FILES[table], index=False)
    valid = campaigns.loc[campaigns["campaign_id"].isin(result.valid)]
    machines = valid.groupby("machine")["campaign_id"].agg(lambda ids: ", ".join(sorted(ids)))
    logger.info(
        "validate: %d of %d campaigns valid (%s); %d quarantined; report %s",
        len(result.valid),
        len(result.campaigns),
        "; ".join(f"machine {m}: {ids}" for m, ids in machines.items()),
        len(result.quarantined),
        paths.VALIDATION_REPORT,
    )
    return 0

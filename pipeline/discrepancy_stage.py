"""DVC stage ``discrepancy``: where the twin and the measurements disagree, and what is missing.

``thermal discrepancy [--raw data/raw] [--out reports/discrepancy]`` reads any folder of
campaigns in the raw contract (in the repository or elsewhere) with the project's own ingest
and validation (campaigns with a problem are quarantined and left out, as in the validate
stage), keeps the spindle-drift campaigns, then

1. calibrates the baseline twin (:mod:`pipeline.discrepancy.model`) and localises its residuals
   by phase, speed level and ambient trend (:mod:`pipeline.discrepancy.localise`);
2. names the missing effects by forward selection with cross-validation across campaigns
   (:mod:`pipeline.discrepancy.search`);
3. writes ``<out>/discrepancy.json``, ``<out>/discrepancy.md``, ``<out>/localisation.csv`` and
   the figures, and logs an MLflow run with the same files (:mod:`pipeline.discrepancy.report`).

When the campaigns cannot be compared with the twin -- fewer than two valid spindle-drift
campaigns with a Z displacement, or no sensor with a structure role (the twin's nodes are
built from the roles; campaigns whose sensors are all ``other`` give it nothing to attach
to) -- the stage still succeeds: it writes ``discrepancy.json`` with ``status: untestable``,
the reason and the roles it would need, and ``discrepancy.md`` saying so, so that the rest of
``dvc repro`` goes on (the ``twin`` candidate of ``evaluate`` is then skipped with that reason).

Parameters: ``params.yaml`` section ``discrepancy`` (thresholds, folds, n_jobs, MLflow store);
the ingest and validation limits come from the ``ingest`` and ``validate`` sections so that a
campaign is read and quarantined exactly as by those stages.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.config import DEFAULT_PARAMS, load_section
from pipeline.discrepancy.data import MeasuredCampaign, campaigns_from_tables
from pipeline.discrepancy.localise import LocaliseSettings, localise
from pipeline.discrepancy.model import ROLE_NODES
from pipeline.discrepancy.report import (
    build_document,
    log_mlflow,
    untestable_document,
    write_outputs,
    write_untestable,
)
from pipeline.discrepancy.search import SearchResult, SearchSettings, campaign_roles, search_twin
from pipeline.ingest import ingest
from pipeline.validate import validate_tables
from pipeline.validation.limits import limits_from_params
from pipeline.validation.report import quarantine_summary
from pipeline.validation.tables import select_valid

logger = logging.getLogger(__name__)

DEFAULT_OUT = paths.REPORTS / "discrepancy"


def read_raw(
    raw_dir: Path, max_alignment_gap_s: float, validate_params: dict
) -> tuple[list[MeasuredCampaign], list[str], bool]:
    """Ingest and validate a raw folder; return its valid spindle campaigns.

    Parameters
    ----------
    raw_dir : Path
        One sub-folder per campaign (docs/data-contract.md).
    max_alignment_gap_s : float
        As ``params.yaml`` ``ingest.max_alignment_gap_s``.
    validate_params : dict
        The ``validate`` section.

    Returns
    -------
    campaigns : list of MeasuredCampaign
        Valid spindle-drift campaigns with a Z displacement.
    quarantined : list of str
        Campaigns left out, each logged with its problems.
    synthetic : bool
        True if any kept campaign is flagged ``synthetic`` in its campaign.yaml.
    """
    tables = ingest(Path(raw_dir), max_alignment_gap_s)
    limits = limits_from_params(validate_params)
    result = validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )
    for campaign_id in result.quarantined:
        logger.warning(
            "campaign %s quarantined: %s; run `thermal ingest --raw %s` and `thermal validate` "
            "for the full report",
            campaign_id,
            quarantine_summary(result, campaign_id),
            raw_dir,
        )
    spindle = select_valid(tables["campaigns"], tables["samples"], tables["laser"], result.valid)[
        "spindle"
    ]
    campaigns = campaigns_from_tables(spindle["campaigns"], spindle["samples"])
    meta = spindle["campaigns"]
    synthetic = bool("synthetic" in meta and pd.Series(meta["synthetic"]).fillna(False).any())
    return campaigns, list(result.quarantined), synthetic


STRUCTURE_ROLES = tuple(ROLE_NODES)
"""Sensor roles that are nodes of the twin's thermal network (at least one is needed)."""
MIN_CAMPAIGNS = 2


def untestable_reason(campaigns: list[MeasuredCampaign]) -> str | None:
    """Why the twin cannot be compared with these campaigns, or None when it can.

    Parameters
    ----------
    campaigns : list of MeasuredCampaign
        The valid spindle-drift campaigns with a Z displacement.

    Returns
    -------
    str or None
        In words, with what to add: too few campaigns (the search holds campaigns out), or no
        sensor whose role is a node of the twin's network.
    """
    if len(campaigns) < MIN_CAMPAIGNS:
        return (
            f"{len(campaigns)} valid spindle-drift campaign(s) with a Z displacement; the "
            f"comparison needs at least {MIN_CAMPAIGNS} (campaigns are held out to test each "
            "effect): add campaigns with a Z probe or fix the quarantined ones"
        )
    roles = campaign_roles(campaigns)
    if not roles & set(STRUCTURE_ROLES):
        return (
            f"no sensor has a structure role (roles present: {', '.join(sorted(roles))}): the "
            "twin's thermal network is built from the places of the sensors; give the sensors "
            "on the machine their role in campaign.yaml (at least one of "
            f"{', '.join(STRUCTURE_ROLES)})"
        )
    return None


def run(
    campaigns: list[MeasuredCampaign],
    section: dict,
    out_dir: Path,
    *,
    quarantined: list[str] | None = None,
    synthetic: bool = False,
    mlflow: bool = True,
) -> tuple[SearchResult, dict]:
    """Search, localise and write the outputs for already-read campaigns.

    Returns
    -------
    result : SearchResult
    doc : dict
        The ``discrepancy.json`` content.
    """
    settings = SearchSettings.from_params(section)
    loc_settings = LocaliseSettings(**dict(section.get("localise") or {}))
    result = search_twin(campaigns, settings)
    before = localise(
        campaigns,
        result.baseline.full.z_residual_um,
        result.baseline.full.t_residual_k,
        loc_settings,
        label="the baseline twin",
    )
    after = localise(
        campaigns,
        result.final.full.z_residual_um,
        result.final.full.t_residual_k,
        loc_settings,
        label="the augmented twin",
    )
    doc = build_document(
        result,
        before,
        after,
        settings,
        synthetic=synthetic,
        campaign_ids=[c.campaign_id for c in campaigns],
        quarantined=quarantined or [],
    )
    files = write_outputs(out_dir, doc, campaigns, result, before)
    logger.info(
        "discrepancy: named %s; held-out Z RMS %.2f -> %.2f um (%.0f s)",
        ", ".join(result.named_effects) or "nothing",
        result.rmse_um_before,
        result.rmse_um_after,
        result.seconds,
    )
    if mlflow and section.get("mlflow", True):
        try:
            doc["mlflow_run_id"] = log_mlflow(files, doc, section)
        except Exception as err:  # the report stands without the tracking record
            logger.warning("MLflow logging failed (%s); the report files are written", err)
    return result, doc


def run_untestable(
    campaigns: list[MeasuredCampaign],
    reason: str,
    section: dict,
    out_dir: Path,
    *,
    quarantined: list[str] | None = None,
    synthetic: bool = False,
    mlflow: bool = True,
) -> dict:
    """Write the report of campaigns the twin cannot be compared with (status untestable).

    Returns
    -------
    dict
        The ``discrepancy.json`` content.
    """
    doc = untestable_document(
        reason,
        needed_roles=list(STRUCTURE_ROLES),
        roles_present=sorted(campaign_roles(campaigns)),
        campaign_ids=[c.campaign_id for c in campaigns],
        quarantined=quarantined or [],
        synthetic=synthetic,
    )
    files = write_untestable(out_dir, doc)
    logger.warning("discrepancy: untestable: %s", reason)
    if mlflow and section.get("mlflow", True):
        try:
            doc["mlflow_run_id"] = log_mlflow(files, doc, section)
        except Exception as err:  # the report stands without the tracking record
            logger.warning("MLflow logging failed (%s); the report files are written", err)
    return doc


def main(argv: list[str] | None = None) -> int:
    """Run the stage; return 0 (also when untestable), 1 when the raw folder cannot be read."""
    parser = argparse.ArgumentParser(
        prog="thermal discrepancy", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--raw", type=Path, default=paths.RAW, help="raw campaign folder")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument(
        "--params", type=Path, default=DEFAULT_PARAMS, help="params file (default params.yaml)"
    )
    parser.add_argument("--no-mlflow", action="store_true", help="do not log an MLflow run")
    parser.add_argument(
        "--run-record",
        type=Path,
        default=None,
        help=f"where to write the MLflow run id (default {paths.DISCREPANCY_RECORD} when --out "
        "is the default, else none)",
    )
    args = parser.parse_args(argv)
    section = load_section("discrepancy", args.params)
    gap = float(load_section("ingest", args.params)["max_alignment_gap_s"])
    try:
        campaigns, quarantined, synthetic = read_raw(
            args.raw, gap, load_section("validate", args.params)
        )
    except (ValueError, FileNotFoundError) as err:
        logger.error("%s", err)
        return 1
    reason = untestable_reason(campaigns)
    common = {"quarantined": quarantined, "synthetic": synthetic, "mlflow": not args.no_mlflow}
    if reason is not None:
        doc = run_untestable(campaigns, reason, section, args.out, **common)
    else:
        doc = run(campaigns, section, args.out, **common)[1]
    record = args.run_record or (paths.DISCREPANCY_RECORD if args.out == DEFAULT_OUT else None)
    if record is not None:
        write_run_record(record, doc.get("mlflow_run_id"))
    return 0


def write_run_record(path: Path, run_id: str | None) -> None:
    """Write where this execution's MLflow run is (``{"run_id": ...}``; null if none logged).

    The run id changes with every execution, so it is kept out of the report folder (a DVC
    output that later stages depend on); the track stage reads it to link the discrepancy run
    and the pipeline run of the same ``dvc repro`` both ways.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"run_id": run_id}, indent=2) + "\n", encoding="utf-8")

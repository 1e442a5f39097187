"""DVC stage ``discrepancy``: where the twin and the measurements disagree, and what is missing.

``thermal discrepancy`` reads the valid spindle campaigns of the ``validate`` stage
(``data/validated/spindle/``, the quarantined ones named in ``reports/validation.json``); with
``--raw PATH`` it reads any folder of campaigns in the raw contract instead, with the same ingest
and validation code in memory (campaigns with a problem are quarantined and left out, as in the
validate stage). It keeps the spindle-drift campaigns with a Z displacement, then (see
:mod:`pipeline.discrepancy.workflow`)

1. calibrates the baseline twin (:mod:`pipeline.discrepancy.model`) and localises its residuals
   by phase, speed level and ambient trend (:mod:`pipeline.discrepancy.localise`);
2. names the missing effects by forward selection with cross-validation across campaigns
   (:mod:`pipeline.discrepancy.search`);
3. writes ``<out>/discrepancy.json``, ``<out>/discrepancy.md``, ``<out>/localisation.csv`` and
   the figures (:mod:`pipeline.discrepancy.report`);
4. logs an MLflow run with the same files (:mod:`pipeline.tracking.discrepancy_run`).

When the campaigns cannot be compared with the twin -- fewer than two valid spindle-drift
campaigns with a Z displacement, or no sensor with a structure role (the twin's nodes are
built from the roles; campaigns whose sensors are all ``other`` give it nothing to attach
to) -- the stage still succeeds: it writes ``discrepancy.json`` with ``status: untestable``,
the reason and the roles it would need, and ``discrepancy.md`` saying so, so that the rest of
``dvc repro`` goes on (the ``twin`` candidate of ``evaluate`` is then skipped with that reason).

Parameters: ``params.yaml`` section ``discrepancy`` (thresholds, folds, n_jobs, experiment) and
``tracking`` (the MLflow store);
with ``--raw`` the ingest and validation limits come from the ``ingest`` and ``validate``
sections so that a campaign is read and quarantined exactly as by those stages.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.followup import FollowUp, history_entry
from pipeline.discrepancy.report import STATUS_TESTED
from pipeline.discrepancy.workflow import (
    read_raw,
    run,
    run_untestable,
    spindle_campaigns,
    untestable_reason,
)
from pipeline.errors import MissingInputError
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.tracking import TrackingSettings
from pipeline.settings.validate import ValidateSettings
from pipeline.tracking.discrepancy_run import log_discrepancy_run
from pipeline.warnings_capture import summarise_warnings

logger = logging.getLogger(__name__)

DEFAULT_OUT = paths.REPORTS / "discrepancy"


def read_validated() -> tuple[list[MeasuredCampaign], list[str], bool]:
    """Read the ``validate`` stage's spindle campaigns and the campaigns it quarantined.

    Returns
    -------
    campaigns : list of MeasuredCampaign
        Valid spindle-drift campaigns with a Z displacement.
    quarantined : list of str
        Campaigns the validate stage left out (``reports/validation.json``).
    synthetic : bool
        True if any campaign is flagged ``synthetic`` in its campaign.yaml.
    """
    folder = paths.VALIDATED_SPINDLE
    needed = [folder / paths.CAMPAIGNS_FILE, folder / paths.SAMPLES_FILE, paths.VALIDATION_REPORT]
    missing = [str(path) for path in needed if not path.is_file()]
    if missing:
        raise MissingInputError(
            f"{', '.join(missing)} not found: run the validate stage first (dvc repro validate), "
            "or give a raw folder with --raw"
        )
    report = json.loads(paths.VALIDATION_REPORT.read_text(encoding="utf-8"))
    campaigns, synthetic = spindle_campaigns(pd.read_parquet(needed[0]), pd.read_parquet(needed[1]))
    return campaigns, list(report["summary"]["quarantined"]), synthetic


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage; return 0 (also when untestable), 1 when the raw folder cannot be read."""
    parser = argparse.ArgumentParser(
        prog="thermal discrepancy", description=__doc__.splitlines()[0]
    )
    parser.add_argument(
        "--raw",
        type=Path,
        default=None,
        help="read and validate this raw campaign folder in memory (default: the validate "
        f"stage's {paths.VALIDATED_SPINDLE} and {paths.VALIDATION_REPORT})",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument(
        "--params", type=Path, default=DEFAULT_PARAMS, help="params file (default params.yaml)"
    )
    parser.add_argument("--no-mlflow", action="store_true", help="do not log an MLflow run")
    parser.add_argument(
        "--history",
        type=Path,
        default=None,
        help="the earlier run's outcome, read and then replaced (default "
        f"{paths.DISCREPANCY_HISTORY} when --out is the default, else none)",
    )
    parser.add_argument(
        "--run-record",
        type=Path,
        default=None,
        help=f"where to write the MLflow run id (default {paths.DISCREPANCY_RECORD} when --out "
        "is the default, else none)",
    )
    args = parser.parse_args(argv)
    section = load_settings(DiscrepancySettings, "discrepancy", args.params)
    logged = not args.no_mlflow and section.mlflow
    tracking = load_settings(TrackingSettings, "tracking", args.params) if logged else None
    if args.raw is None:
        campaigns, quarantined, synthetic = read_validated()
    else:
        gap = load_settings(IngestSettings, "ingest", args.params).max_alignment_gap_s
        limits = load_settings(ValidateSettings, "validate", args.params).limits()
        try:
            campaigns, quarantined, synthetic = read_raw(args.raw, gap, limits)
        except (ValueError, FileNotFoundError) as err:
            logger.error("%s", err)
            return 1
    reason = untestable_reason(campaigns)
    common = {"quarantined": quarantined, "synthetic": synthetic}
    history = args.history or (paths.DISCREPANCY_HISTORY if args.out == DEFAULT_OUT else None)
    if reason is not None:
        doc, files = run_untestable(campaigns, reason, args.out, **common)
    else:
        doc, files = run(campaigns, section, args.out, follow=read_follow_up(history), **common)[1:]
    write_history(history, doc)
    if tracking is not None:
        try:
            doc["mlflow_run_id"] = log_discrepancy_run(files, doc, tracking, section.experiment)
        except Exception as err:  # the report stands without the tracking record
            logger.warning("MLflow logging failed (%s); the report files are written", err)
    record = args.run_record or (paths.DISCREPANCY_RECORD if args.out == DEFAULT_OUT else None)
    if record is not None:
        write_run_record(record, doc.get("mlflow_run_id"))
    return 0


def read_follow_up(path: Path | None) -> FollowUp | None:
    """Return the earlier run's outcome kept in ``path``, None without one."""
    if path is None or not path.is_file():
        return None
    return FollowUp.from_document(json.loads(path.read_text(encoding="utf-8")))


def write_history(path: Path | None, doc: dict) -> None:
    """Keep what the next run needs of this one (:func:`history_entry`) in ``path``.

    An untestable run keeps only its status (the file is a DVC output, so it is written): the
    next run that can search starts afresh.
    """
    if path is None:
        return
    tested = doc.get("status") == STATUS_TESTED
    entry = history_entry(doc) if tested else {"status": doc.get("status")}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(entry, indent=2) + "\n", encoding="utf-8")


def write_run_record(path: Path, run_id: str | None) -> None:
    """Write where this execution's MLflow run is (``{"run_id": ...}``; null if none logged).

    The run id changes with every execution, so it is kept out of the report folder (a DVC
    output that later stages depend on); the track stage reads it to link the discrepancy run
    and the pipeline run of the same ``dvc repro`` both ways.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"run_id": run_id}, indent=2) + "\n", encoding="utf-8")

"""DVC stage ``discrepancy``: where the twin and the measurements disagree, and what is missing.

``thermal discrepancy`` reads the valid spindle campaigns of the ``validate`` stage
(``data/validated/spindle/``, the quarantined ones named in ``reports/validation.json``); with
``--raw PATH`` it reads any folder of campaigns in the raw contract instead, with the same ingest
and validation code in memory (campaigns with a problem are quarantined and left out, as in the
validate stage). Each machine is compared with its own twin (:mod:`pipeline.machines`), its
outputs in ``<out>/<machine>/``: for each, it keeps the spindle-drift campaigns with a Z
displacement, then (see :mod:`pipeline.discrepancy.workflow`)

1. calibrates the baseline twin (:mod:`pipeline.discrepancy.model`) and localises its residuals
   by phase, speed level and ambient trend (:mod:`pipeline.discrepancy.localise`);
2. names the missing effects by forward selection with cross-validation across campaigns
   (:mod:`pipeline.discrepancy.search`);
3. writes ``<out>/discrepancy.json``, ``<out>/discrepancy.md``, ``<out>/localisation.csv`` and
   the figures (:mod:`pipeline.discrepancy.report`);
4. logs an MLflow run with the same files (:mod:`pipeline.tracking.discrepancy_run`), one per
   machine.

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
from functools import partial
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.followup import FollowUp, history_entry
from pipeline.discrepancy.report import STATUS_TESTED
from pipeline.discrepancy.workflow import (
    read_raw_tables,
    run,
    run_untestable,
    spindle_campaigns,
    untestable_reason,
)
from pipeline.errors import MissingInputError
from pipeline.fit_cache import StageCache
from pipeline.machines import MACHINE_COLUMN, UNNAMED, machine_key
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.tracking import TrackingSettings
from pipeline.settings.validate import ValidateSettings
from pipeline.tracking.discrepancy_run import log_discrepancy_run
from pipeline.validation.tables import drop_empty_columns
from pipeline.warnings_capture import summarise_warnings

logger = logging.getLogger(__name__)

DEFAULT_OUT = paths.REPORTS / "discrepancy"


def read_validated() -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Read the ``validate`` stage's spindle tables and the campaigns it quarantined.

    Returns
    -------
    campaigns, samples : DataFrame
        ``data/validated/spindle/{campaigns,samples}.parquet``.
    quarantined : dict of str to str
        Campaigns the validate stage left out (``reports/validation.json``) -> their machine
        (``""``: unknown).
    """
    folder = paths.VALIDATED_SPINDLE
    needed = [folder / paths.CAMPAIGNS_FILE, folder / paths.SAMPLES_FILE, paths.VALIDATION_REPORT]
    missing = [str(path) for path in needed if not path.is_file()]
    if missing:
        raise MissingInputError(
            f"{', '.join(missing)} not found: run the validate stage first (dvc repro validate), "
            "or give a raw folder with --raw"
        )
    summary = json.loads(paths.VALIDATION_REPORT.read_text(encoding="utf-8"))["summary"]
    machines = summary.get("machines") or {}
    quarantined = {c: machines.get(c, "") for c in summary["quarantined"]}
    return pd.read_parquet(needed[0]), pd.read_parquet(needed[1]), quarantined


def machine_tables(
    campaigns: pd.DataFrame, samples: pd.DataFrame, machine: str
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Return one machine's rows of the validated spindle tables (its own sensor columns)."""
    own = campaigns.loc[campaigns[MACHINE_COLUMN].astype(str) == machine].reset_index(drop=True)
    ids = set(own["campaign_id"].astype(str))
    rows = samples.loc[samples["campaign_id"].astype(str).isin(ids)].reset_index(drop=True)
    return own, drop_empty_columns(rows)


def build_parser() -> argparse.ArgumentParser:
    """Return the command's options."""
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
    parser.add_argument(
        "--out", type=Path, default=DEFAULT_OUT, help="output folder (one folder per machine)"
    )
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
        help=f"where to write the MLflow run ids (default {paths.DISCREPANCY_RECORD} when --out "
        "is the default, else none)",
    )
    return parser


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage; return 0 (also when untestable), 1 when the raw folder cannot be read."""
    args = build_parser().parse_args(argv)
    section = load_settings(DiscrepancySettings, "discrepancy", args.params)
    logged = not args.no_mlflow and section.mlflow
    tracking = load_settings(TrackingSettings, "tracking", args.params) if logged else None
    if args.raw is None:
        campaigns, samples, quarantined = read_validated()
    else:
        gap = load_settings(IngestSettings, "ingest", args.params).max_alignment_gap_s
        limits = load_settings(ValidateSettings, "validate", args.params).limits()
        try:
            campaigns, samples, quarantined = read_raw_tables(args.raw, gap, limits)
        except (ValueError, FileNotFoundError) as err:
            logger.error("%s", err)
            return 1
    history = args.history or (paths.DISCREPANCY_HISTORY if args.out == DEFAULT_OUT else None)
    earlier = history_entries(history)
    # the stage's own run keeps each machine's result; a run on other folders computes afresh
    cache = StageCache("discrepancy") if args.raw is None and args.out == DEFAULT_OUT else None
    entries, run_ids = {}, {}
    for machine in sorted(set(campaigns[MACHINE_COLUMN].astype(str))) or [UNNAMED]:
        own, rows = machine_tables(campaigns, samples, machine)
        left_out = sorted(c for c, owner in quarantined.items() if owner == machine)
        out = args.out / machine_key(machine)
        follow = FollowUp.from_document(earlier.get(machine))
        compute = partial(
            compare_machine,
            own,
            rows,
            section,
            out,
            follow,
            {"quarantined": left_out, "machine": machine},
        )
        if cache is None:
            doc = compute()
        else:
            parts = [
                ("campaigns", own),
                ("samples", rows),
                ("quarantined", left_out),
                ("discrepancy", section),
                ("history", earlier.get(machine) if follow is not None else None),
            ]
            doc = cache.result_with_files(machine, parts, compute, [out])
        files = sorted(path for path in out.rglob("*") if path.is_file())
        entries[machine] = history_of(doc)
        if tracking is not None:
            try:
                doc["mlflow_run_id"] = log_discrepancy_run(files, doc, tracking, section.experiment)
            except Exception as err:  # the report stands without the tracking record
                logger.warning("MLflow logging failed (%s); the report files are written", err)
        run_ids[machine] = doc.get("mlflow_run_id")
    write_history(history, entries)
    if cache is not None:
        cache.prune()
    record = args.run_record or (paths.DISCREPANCY_RECORD if args.out == DEFAULT_OUT else None)
    if record is not None:
        write_run_record(record, run_ids)
    return 0


def compare_machine(
    campaigns: pd.DataFrame,
    samples: pd.DataFrame,
    section: DiscrepancySettings,
    out: Path,
    follow: FollowUp | None,
    common: dict,
) -> dict:
    """Compare one machine's campaigns with its twin, write its report; return the document.

    ``campaigns`` and ``samples``: the machine's validated spindle tables; ``common``: the
    quarantined campaigns and the machine.
    """
    measured, synthetic = spindle_campaigns(campaigns, samples)
    reason = untestable_reason(measured)
    if reason is not None:
        return run_untestable(measured, reason, out, synthetic=synthetic, **common)[0]
    return run(measured, section, out, follow=follow, synthetic=synthetic, **common)[1]


def history_entries(path: Path | None) -> dict[str, dict]:
    """Return each machine's entry of the earlier run's history in ``path`` (empty without one).

    An entry becomes the machine's :class:`FollowUp` (:meth:`FollowUp.from_document`; None for
    an untestable run).
    """
    if path is None or not path.is_file():
        return {}
    return json.loads(path.read_text(encoding="utf-8")).get("machines") or {}


def history_of(doc: dict) -> dict:
    """Return what the next run needs of this machine's run (:func:`history_entry`).

    An untestable run keeps only its status: the next run that can search starts afresh.
    """
    tested = doc.get("status") == STATUS_TESTED
    return history_entry(doc) if tested else {"status": doc.get("status")}


def write_history(path: Path | None, entries: dict[str, dict]) -> None:
    """Keep each machine's :func:`history_of` in ``path`` (``{"machines": {machine: entry}}``)."""
    if path is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"machines": entries}, indent=2) + "\n", encoding="utf-8")


def write_run_record(path: Path, run_ids: dict[str, str | None]) -> None:
    """Write where this execution's MLflow runs are (``{"machines": {machine: run id}}``).

    The run ids change with every execution, so they are kept out of the report folder (a DVC
    output that later stages depend on); the track stage reads them to link the discrepancy run
    and the pipeline run of the same ``dvc repro`` both ways.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"machines": run_ids}, indent=2) + "\n", encoding="utf-8")

"""The ``track`` stage: log the cross-season scores of one pipeline execution to MLflow.

``thermal track`` (run from the repository root) reads the select and evaluate outputs
(``reports/selection/selected.json``, ``reports/fitted_models.json``,
``reports/cross_season_scores.csv``, ``metrics/cross_season.json``,
``data/models/champion/<machine>/<axis>/``) and logs, for each machine on its own (tag
``machine`` on every run)

- one parent run per pipeline execution and machine: overall scores
  ``<axis>.<model>.<selection>.<mode>.<scheme>.<key>`` (um) and each axis' champion
  (``<axis>.champion.*``), the whole ``params.yaml`` and every selection's inputs
  (``selected.<axis>.<method>.<unit>``) as parameters, tags ``run_identity``, ``git_commit``,
  ``synthetic``, ``dvc.*`` (md5 hashes from ``dvc.lock``), ``skipped.<axis>.<candidate>`` (why
  a candidate was not scored), the report files (comparison report, matrices, selection
  evidence) as artifacts;
- one child run per candidate (axis, model, selection, mode) with its summary scores, every
  cross-campaign score and what each fit decided (see :mod:`pipeline.tracking.records`); the
  child of each axis' champion (tag ``champion: true``) also holds the champion model, with
  its signature and an input example, registered as
  ``<track.registered_model>-<machine>-<axis>``;
- the promotion gate (:mod:`pipeline.tracking.promotion`): each registered version takes the
  alias ``champion`` only when it proves better than the current champion on the campaigns
  that one was not trained on (or when there is none yet); the decision goes to
  ``reports/promotion/promotion.json`` and ``promotion.md``.

The store is ``$MLFLOW_TRACKING_URI`` when set, else ``tracking.default_tracking_uri``
(``sqlite:///mlflow.db`` in the working directory, artifacts in ``mlartifacts/`` beside it).
When the store already holds a finished parent with the same run identity (see
:mod:`pipeline.tracking.identity`: the machine's own raw campaigns, scores and champions, code
and params) nothing is logged for that machine. ``reports/mlflow_run.json`` records where each
machine's run is (``{"tracking_uri", "experiment", "machines": {machine: ...}}``).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

from pipeline.config import DEFAULT_PARAMS
from pipeline.paths import (
    AXIS_MODEL_METRICS,
    CROSS_SEASON_METRICS,
    PROMOTION,
    PROMOTION_DECISION,
    PROMOTION_REPORT,
    TRACKING_RECORD,
)
from pipeline.protocol.promotion import GateDecision, render_report
from pipeline.settings.base import load_settings
from pipeline.settings.track import TrackSettings
from pipeline.settings.tracking import DEFAULT_TRACKING_URI, TrackingSettings
from pipeline.tracking import records, store
from pipeline.tracking.location import (
    ENV_TRACKING_URI,
    resolve_tracking_uri,
    unreachable_message,
)
from pipeline.tracking.pipeline_run import (
    gate_inputs,
    log_pipeline_run,
    prepare,
)
from pipeline.tracking.stage_outputs import read_json
from pipeline.warnings_capture import summarise_warnings

logger = logging.getLogger(__name__)


def _parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="thermal track",
        description=(
            "Log the evaluate outputs to MLflow: one parent run per pipeline execution, one "
            "child per candidate model/selection/mode, and register the champion. Store: "
            f"${ENV_TRACKING_URI} or {DEFAULT_TRACKING_URI}; writes {TRACKING_RECORD}."
        ),
    )
    parser.add_argument("--params", default=str(DEFAULT_PARAMS), help="params file (params.yaml)")
    return parser.parse_args(argv)


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the track stage; return the exit code (0 on success)."""
    args = _parse_args(list(argv or []))
    started = time.perf_counter()
    settings = load_settings(TrackSettings, "track", args.params)
    store_settings = load_settings(TrackingSettings, "tracking", args.params)
    prepared = [prepare(Path(args.params), machine) for machine in machines()]
    n_metrics = {p.machine: records.count_metrics([p.parent, *p.children]) for p in prepared}
    ready = time.perf_counter()
    uri = resolve_tracking_uri(store_settings)
    margin = settings.promotion.min_improvement
    entries = {}
    try:
        for machine_run in prepared:
            machine = machine_run.machine
            entries[machine] = log_pipeline_run(
                machine_run,
                store_settings,
                settings,
                uri,
                n_metrics[machine],
                gate_inputs(machine, list(machine_run.champions), margin),
            )
            entries[machine]["metrics"] = n_metrics[machine]
    except store.UNREACHABLE as error:
        raise SystemExit(unreachable_message(uri, error)) from error
    finished = time.perf_counter()
    logger.info(
        "track took %.2f s (reading and hashing %.2f s, MLflow %.2f s)",
        finished - started,
        ready - started,
        finished - ready,
    )
    record = {
        "tracking_uri": store.public_uri(uri),
        "experiment": settings.experiment,
        "machines": entries,
    }
    TRACKING_RECORD.parent.mkdir(parents=True, exist_ok=True)
    TRACKING_RECORD.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    write_promotion(record)
    return 0


def machines() -> list[str]:
    """Return the machines ``evaluate`` or ``model_axis`` modelled, sorted."""
    found = set(read_json(CROSS_SEASON_METRICS).get("machines") or {})
    if AXIS_MODEL_METRICS.is_file():
        found |= set(read_json(AXIS_MODEL_METRICS).get("machines") or {})
    return sorted(found)


def write_promotion(record: dict) -> None:
    """Write the gate's decisions: ``promotion.json`` and the Markdown ``promotion.md``.

    ``promotion.json``: ``tracking_uri``, ``machines`` (each machine's parent run and
    champions) and ``axes``, every machine's decisions (each with its ``machine``).
    """
    PROMOTION.mkdir(parents=True, exist_ok=True)
    decisions = [
        {**decision, "machine": machine}
        for machine, entry in record["machines"].items()
        for decision in entry.get("promotion") or []
    ]
    document = {
        "tracking_uri": record.get("tracking_uri"),
        "machines": {
            machine: {
                "parent_run_id": entry.get("parent_run_id"),
                "champions": entry.get("champions"),
            }
            for machine, entry in record["machines"].items()
        },
        "axes": decisions,
    }
    PROMOTION_DECISION.write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    PROMOTION_REPORT.write_text(
        render_report([GateDecision.from_dict(d) for d in decisions]), encoding="utf-8"
    )

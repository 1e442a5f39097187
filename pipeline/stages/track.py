"""The ``track`` stage: log the cross-season scores of one pipeline execution to MLflow.

``thermal track`` (run from the repository root) reads the select and evaluate outputs
(``reports/selection/selected.json``, ``reports/fitted_models.json``,
``reports/cross_season_scores.csv``, ``metrics/cross_season.json``,
``data/models/champion/<axis>/``) and logs

- one parent run per pipeline execution: overall scores
  ``<axis>.<model>.<selection>.<mode>.<scheme>.<key>`` (um) and each axis' champion
  (``<axis>.champion.*``), the whole ``params.yaml`` and every selection's inputs
  (``selected.<axis>.<method>.<unit>``) as parameters, tags ``run_identity``, ``git_commit``,
  ``synthetic``, ``dvc.*`` (md5 hashes from ``dvc.lock``), ``skipped.<axis>.<candidate>`` (why
  a candidate was not scored), the report files (comparison report, matrices, selection
  evidence) as artifacts;
- one child run per candidate (axis, model, selection, mode) with its summary scores, every
  cross-campaign score and what each fit decided (see :mod:`pipeline.tracking.records`); the
  child of each axis' champion (tag ``champion: true``) also holds the champion model, with
  its signature and an input example, registered as ``<track.registered_model>-<axis>``;
- the promotion gate (:mod:`pipeline.tracking.promotion`): each registered version takes the
  alias ``champion`` only when it proves better than the current champion on the campaigns
  that one was not trained on (or when there is none yet); the decision goes to
  ``reports/promotion/promotion.json`` and ``promotion.md``.

The store is ``$MLFLOW_TRACKING_URI`` when set, else ``tracking.default_tracking_uri``
(``sqlite:///mlflow.db`` in the working directory, artifacts in ``mlartifacts/`` beside it).
When the store already holds a finished parent with the same run identity (see
:mod:`pipeline.tracking.identity`) nothing is logged. ``reports/mlflow_run.json`` records
where the run is.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

from pipeline.config import DEFAULT_PARAMS
from pipeline.paths import (
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
    prepared = prepare(Path(args.params))
    n_metrics = records.count_metrics([prepared.parent, *prepared.children])
    ready = time.perf_counter()
    uri = resolve_tracking_uri(store_settings)
    try:
        record = log_pipeline_run(
            prepared,
            store_settings,
            settings,
            uri,
            n_metrics,
            gate_inputs(list(prepared.champions), settings.promotion.min_improvement),
        )
    except store.UNREACHABLE as error:
        raise SystemExit(unreachable_message(uri, error)) from error
    finished = time.perf_counter()
    logger.info(
        "track took %.2f s (reading and hashing %.2f s, MLflow %.2f s)",
        finished - started,
        ready - started,
        finished - ready,
    )
    record["metrics"] = n_metrics
    TRACKING_RECORD.parent.mkdir(parents=True, exist_ok=True)
    TRACKING_RECORD.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    write_promotion(record)
    return 0


def write_promotion(record: dict) -> None:
    """Write the gate's decisions: ``promotion.json`` and the Markdown ``promotion.md``."""
    PROMOTION.mkdir(parents=True, exist_ok=True)
    decisions = record.get("promotion") or []
    document = {
        "parent_run_id": record.get("parent_run_id"),
        "tracking_uri": record.get("tracking_uri"),
        "champions": record.get("champions"),
        "axes": decisions,
    }
    PROMOTION_DECISION.write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    PROMOTION_REPORT.write_text(
        render_report([GateDecision.from_dict(d) for d in decisions]), encoding="utf-8"
    )

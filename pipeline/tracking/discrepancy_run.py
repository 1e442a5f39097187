"""The discrepancy workflow's MLflow run: its metrics, named effects, thresholds and report files.

One run per execution in the experiment ``discrepancy.experiment`` (``thermal-discrepancy``) of the
store of ``params.yaml`` ``tracking`` (``$MLFLOW_TRACKING_URI`` wins); the ``discrepancy`` stage
logs it after writing the report, and the ``track`` stage links it with the pipeline's run.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.discrepancy.report import STATUS_TESTED, STATUS_UNTESTABLE
from pipeline.machines import machine_key
from pipeline.settings.tracking import TrackingSettings
from pipeline.tracking.location import (
    absolute_store_uri,
    local_artifact_location,
    resolve_tracking_uri,
)
from pipeline.tracking.store import ensure_experiment, log_values, make_client

logger = logging.getLogger(__name__)


def _run_tags(doc: Mapping[str, Any]) -> dict[str, str]:
    """Return the MLflow run's tags: stage, status, machine, synthetic, effects' fates, why not."""
    tags = {
        "stage": "discrepancy",
        "status": str(doc.get("status", STATUS_TESTED)),
        "synthetic": str(bool(doc["synthetic"])).lower(),
        "named_effects": ",".join(doc["named_effects"]) or "none",
        "suspects": ",".join(s["effect"] for s in doc.get("suspects") or []) or "none",
        "no_longer_named": ",".join(d["effect"] for d in doc.get("no_longer_named") or [])
        or "none",
    }
    if doc.get("machine"):
        tags["machine"] = str(doc["machine"])
    if doc.get("status") == STATUS_UNTESTABLE:
        tags["mlflow.note.content"] = f"Untestable: {doc['reason']}"
    return tags


Metrics = list[tuple[str, float, int]]
"""Metrics of the run: ``(key, value, step)``."""


def _rmse_metrics(rmse: Mapping[str, Any], prefix: str = "") -> Metrics:
    """Return the held-out Z (um) and temperature (K) RMS before and after that ``rmse`` holds."""
    keys = ("rmse_um_before", "rmse_um_after", "rmse_T_K_before", "rmse_T_K_after")
    return [(f"{prefix}{k}", float(rmse[k]), 0) for k in keys if rmse.get(k) is not None]


def _search_values(doc: Mapping[str, Any]) -> tuple[Metrics, dict[str, str], dict[str, str]]:
    """Return the held-out Z RMS along the search (um) and each named effect's parameters.

    Step 0 of the ``heldout_rmse_um`` metric is the baseline, step k the twin after the k-th
    named effect. Each parameter an effect brings is the param ``<effect>.<name>`` (its value)
    with the tag ``unit.<effect>.<name>`` (its unit, e.g. ``um/krpm^2``): MLflow allows only
    letters, digits, ``_ - . / :`` and spaces in keys, so units, which may hold ``^`` or ``*``,
    stay out of them.
    """
    metrics: Metrics = []
    params, tags = {}, {}
    if doc.get("rmse_um_before") is not None:
        metrics.append(("heldout_rmse_um", float(doc["rmse_um_before"]), 0))
    for k, step in enumerate(doc.get("steps", []), start=1):
        metrics.append(("heldout_rmse_um", float(step["rmse_um_after"]), k))
        for name, value in step["effect_parameters"].items():
            if value["value"] is not None:
                params[f"{step['effect']}.{name}"] = str(value["value"])
                tags[f"unit.{step['effect']}.{name}"] = str(value["unit"])
    return metrics, params, tags


def _per_campaign_metrics(per_campaign: Mapping[str, Any]) -> Metrics:
    """Return each campaign's held-out Z (um) and temperature (K) RMS before and after."""
    metrics: Metrics = []
    for cid, pair in per_campaign.items():
        for when in ("before", "after"):
            for key, name in (("z_um", "rmse_um"), ("t_k", "rmse_T_K")):
                value = pair[when].get(key)
                if value is not None and np.isfinite(value):
                    metrics.append((f"{name}_{when}.{cid}", float(value), 0))
    return metrics


def _identifiability_values(
    entries: Mapping[str, Any],
) -> tuple[Metrics, dict[str, str], dict[str, str]]:
    """Return every candidate's identifiability class, signal and proposed test.

    Each effect gets the tag ``identifiability.<effect>`` (its class), the metric
    ``signal_sigma.<effect>`` (its visible signal, noise sigmas) and, when it is not
    identifiable, the param ``proposed_test.<effect>`` (the proposed plan's name, without one
    ``calibration step: <its name>`` or ``none visible``) with the metric
    ``proposed_signal_sigma.<effect>`` (the signal the plan would leave, or the grid's best).
    """
    metrics: Metrics = []
    params, tags = {}, {}
    for effect, entry in entries.items():
        tags[f"identifiability.{effect}"] = str(entry["class"])
        signal = entry.get("signal_sigma")
        if signal is not None and np.isfinite(signal):
            metrics.append((f"signal_sigma.{effect}", float(signal), 0))
        proposed = entry.get("proposed_test")
        if not proposed:
            continue
        plan = proposed if proposed.get("visible") else proposed.get("best_in_grid") or {}
        step = proposed.get("calibration_step")
        name = (
            str(plan.get("name", ""))
            if proposed.get("visible")
            else f"calibration step: {step['name']}"
            if step
            else "none visible"
        )
        params[f"proposed_test.{effect}"] = name[:500]
        if plan.get("expected_signal_sigma") is not None:
            metrics.append(
                (f"proposed_signal_sigma.{effect}", float(plan["expected_signal_sigma"]), 0)
            )
    return metrics, params, tags


def run_values(doc: Mapping[str, Any]) -> tuple[Metrics, dict[str, str], dict[str, str]]:
    """Return the run's metrics ``(key, value, step)``, params and tags after creation.

    Parameters
    ----------
    doc : mapping
        The ``discrepancy.json`` content.

    Returns
    -------
    metrics : list of (str, float, int)
    params : dict of str to str
    tags : dict of str to str
    """
    search_metrics, params, tags = _search_values(doc)
    ident_metrics, ident_params, ident_tags = _identifiability_values(
        doc.get("identifiability") or {}
    )
    metrics = [
        *_rmse_metrics(doc),
        *search_metrics,
        *_per_campaign_metrics(doc.get("per_campaign", {})),
        # the validation campaigns the search never saw
        *_rmse_metrics(doc.get("validation") or {}, prefix="validation_"),
        *ident_metrics,
    ]
    params["named_effects"] = ",".join(doc["named_effects"]) or "none"
    params.update({name: str(value) for name, value in doc.get("thresholds", {}).items()})
    params["campaigns"] = ",".join(doc["campaigns"])[:500]
    return metrics, {**params, **ident_params}, {**tags, **ident_tags}


def log_discrepancy_run(
    files: Sequence[Path], doc: Mapping[str, Any], settings: TrackingSettings, experiment: str
) -> str:
    """Log one MLflow run with the metrics, the named effects and the report files.

    Parameters
    ----------
    files : sequence of Path
        Report files, logged as artifacts under ``discrepancy/``.
    doc : mapping
        The ``discrepancy.json`` content.
    settings : TrackingSettings
        The store and the local artifact folder (``params.yaml`` ``tracking``;
        ``$MLFLOW_TRACKING_URI`` wins over the default store).
    experiment : str
        The experiment (``params.yaml`` ``discrepancy.experiment``).

    Returns
    -------
    str
        The run id.
    """
    uri = absolute_store_uri(resolve_tracking_uri(settings))
    client = make_client(uri)
    location = local_artifact_location(uri, settings.local_artifact_dir, experiment)
    experiment_id = ensure_experiment(client, experiment, location)
    name = f"discrepancy-{machine_key(doc['machine'])}" if doc.get("machine") else "discrepancy"
    run = client.create_run(experiment_id, tags=_run_tags(doc), run_name=name)
    run_id = run.info.run_id
    try:
        log_values(client, run_id, *run_values(doc))
        for path in files:
            client.log_artifact(run_id, str(path), artifact_path="discrepancy")
    except BaseException:
        client.set_terminated(run_id, "FAILED")
        raise
    client.set_terminated(run_id)
    logger.info("logged MLflow run %s in experiment '%s'", run_id, experiment)
    return run_id

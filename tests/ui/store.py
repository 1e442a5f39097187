"""Build a small real MLflow store in the pipeline's tracking layout, for the UI check's tests.

No pipeline run: :class:`mlflow.MlflowClient` on a SQLite store writes one experiment with a
description, one parent run (tag ``ranked_by.Z``), five child runs of axis Z (tags ``axis``,
``model``, ``selection``, ``mode``, ``eligible``, ``ineligible_reason``, ``rank``, ``champion``;
the ranking metric; artifacts ``cross_season_rms.png`` and ``scores.json``), the
champion's model logged from its child run and registered (description, alias ``champion``),
and the ``reports/mlflow_run.json`` the ``track`` stage writes.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import mlflow
import mlflow.pyfunc
import numpy as np
from matplotlib.figure import Figure
from mlflow import MlflowClient

from pipeline.tracking import views

RANKING_METRIC = "loso_Mn_rms_um"
DESCRIPTION = (
    "Thermal-error models of the spindle, one child run per candidate "
    "axis/model/selection/mode, ranked by the mean held-out RMS in um."
)
# (model, selection, mode, held-out RMS um, eligible, rank); the one-step model has the lowest
# RMS but is not eligible, so a run list that does not filter on eligibility puts it first.
CANDIDATES = (
    ("pls_dl", "gra_top_k", "static", 2.19, True, "1"),
    ("ridge_dl", "gra_top_k", "static", 2.20, True, "2"),
    ("mlr", "best_subset", "static", 2.84, True, "3"),
    ("none", "none", "static", 25.31, True, "4"),
    ("tv_ar", "none", "one_step", 0.35, False, ""),
)


@dataclass(frozen=True)
class UiStore:
    """Where a built store is and what it holds."""

    tracking_uri: str
    experiment: str
    experiment_id: str
    parent_run_id: str
    champion_run_name: str
    registered_model: str
    record: dict


def _heat_map(path: Path, seed: int) -> None:
    values = np.random.default_rng(seed).uniform(0.5, 4.0, size=(4, 4))
    figure = Figure(figsize=(3, 3), dpi=60)
    axes = figure.subplots()
    axes.imshow(values, cmap="viridis")
    axes.set_title("RMS (um)")
    figure.savefig(path)


class _Zero(mlflow.pyfunc.PythonModel):
    """Predicts no thermal error (the registered champion's stand-in)."""

    def predict(self, context, model_input, params=None):
        return [0.0] * len(model_input)


def _register_zero_model(client: MlflowClient, uri: str, run_id: str, name: str) -> str:
    """Log a model from the champion's own child run and register it, as the track stage does.

    The fluent API logs the model, and the registry resolves its ``models:/`` source, through
    the global tracking URI: set for the duration, then restored (``set_tracking_uri`` also
    sets ``$MLFLOW_TRACKING_URI``; ``None`` unsets both). Returns the version.
    """
    previous = os.environ.get("MLFLOW_TRACKING_URI")
    mlflow.set_tracking_uri(uri)
    try:
        with mlflow.start_run(run_id=run_id):
            model = mlflow.pyfunc.log_model(
                name="model", python_model=_Zero(), pip_requirements=["mlflow"]
            )
        client.create_registered_model(name)
        version = client.create_model_version(
            name,
            source=model.model_uri,
            run_id=run_id,
            description="Axis Z: pls_dl/gra_top_k/static, held-out RMS 2.19 um against 25.31 um.",
            model_id=model.model_id,
        )
    finally:
        mlflow.set_tracking_uri(previous)
    client.set_registered_model_alias(name, "champion", version.version)
    return str(version.version)


def _log_candidate(
    client,
    experiment_id: str,
    parent_id: str,
    seed: int,
    candidate: tuple,
    figures: Path,
    *,
    drop_champion_metric: bool,
    drop_heat_map_rank: str | None,
) -> tuple[str, str]:
    """Log one child run as the track stage does (tags, metrics, heat-map, table); id, name."""
    model, selection, mode, rms, eligible, rank = candidate
    name = f"Z/{model}/{selection}/{mode}"
    champion = rank == "1"
    tags = {
        "mlflow.parentRunId": parent_id,
        "axis": "Z",
        "model": model,
        "selection": selection,
        "mode": mode,
        "eligible": str(eligible).lower(),
        "rank": rank,
        "champion": str(champion).lower(),
    }
    if not eligible:
        tags["ineligible_reason"] = "one-step prediction needs the measured error"
    run_id = client.create_run(experiment_id, run_name=name, tags=tags).info.run_id
    if not (champion and drop_champion_metric):
        client.log_metric(run_id, RANKING_METRIC, rms)
    client.log_metric(run_id, "pooled_Mn_val_rms_um", rms * 0.98)
    if rank != drop_heat_map_rank:
        figure = figures / str(seed) / "cross_season_rms.png"
        figure.parent.mkdir(exist_ok=True)
        _heat_map(figure, seed)
        client.log_artifact(run_id, str(figure))
    client.log_table(
        run_id, {"test_campaign": ["K01", "K02"], "rmse_um": [rms, rms * 1.1]}, "scores.json"
    )
    client.set_terminated(run_id)
    return run_id, name


MACHINE = "vmc-450"
"""The machine of the store's pipeline run."""


def _share_ranked_view(client, experiment_id: str, parent_id: str) -> None:
    """Store the ranked view of axis Z as pipeline.tracking.views writes it for the pipeline."""
    key = views.view_key("ranked", MACHINE, "Z")
    state = {
        "searchFilter": f"tags.`mlflow.parentRunId` = '{parent_id}' and tags.eligible = 'true'",
        "orderByKey": views.column("metrics", RANKING_METRIC),
        "orderByAsc": True,
        "selectedColumns": [views.column("tags", "rank"), views.column("metrics", RANKING_METRIC)],
    }
    client.set_experiment_tag(experiment_id, f"{views.SHARED_VIEW_TAG}{key}", json.dumps(state))


def build_ui_store(
    root: Path,
    experiment: str,
    registered_model: str,
    *,
    drop_champion_metric: bool = False,
    drop_heat_map_rank: str | None = None,
) -> UiStore:
    """Write one pipeline execution to the SQLite store ``root/mlflow.db``.

    Parameters
    ----------
    root : Path
        Folder of ``mlflow.db`` and ``mlartifacts/`` (several experiments may share it).
    experiment : str
        Experiment name (unique in the store).
    registered_model : str
        Registered model name of the axis Z champion (unique in the store).
    drop_champion_metric : bool
        Leave the ranking metric out of the champion's child run.
    drop_heat_map_rank : str or None
        Leave ``cross_season_rms.png`` out of the child run of this rank (e.g. ``"2"``).

    Returns
    -------
    UiStore
        The store's URI, the ids, and the ``reports/mlflow_run.json`` record.
    """
    root.mkdir(parents=True, exist_ok=True)
    uri = f"sqlite:///{(root / 'mlflow.db').as_posix()}"
    client = MlflowClient(tracking_uri=uri, registry_uri=uri)
    artifacts = (root / "mlartifacts" / experiment).as_uri()
    experiment_id = client.create_experiment(
        experiment, artifact_location=artifacts, tags={"mlflow.note.content": DESCRIPTION}
    )
    parent = client.create_run(
        experiment_id,
        run_name="pipeline-0123abcd",
        tags={"ranked_by.Z": RANKING_METRIC, "synthetic": "true"},
    )
    parent_id = parent.info.run_id
    figures = root / "figures"
    figures.mkdir(exist_ok=True)
    champion_id, champion_name = "", ""
    for seed, candidate in enumerate(CANDIDATES):
        run_id, name = _log_candidate(
            client,
            experiment_id,
            parent_id,
            seed,
            candidate,
            figures,
            drop_champion_metric=drop_champion_metric,
            drop_heat_map_rank=drop_heat_map_rank,
        )
        if candidate[-1] == "1":
            champion_id, champion_name = run_id, name
    client.set_terminated(parent_id)
    _share_ranked_view(client, experiment_id, parent_id)
    version = _register_zero_model(client, uri, champion_id, registered_model)
    record = {
        "tracking_uri": uri,
        "experiment": experiment,
        "machine": MACHINE,
        "experiment_id": experiment_id,
        "parent_run_id": parent_id,
        "champions": {
            "Z": {
                "registered_model": registered_model,
                "version": version,
                "uri": f"models:/{registered_model}@champion",
                "model": "pls_dl/gra_top_k/static",
                "compensate": True,
            }
        },
    }
    return UiStore(
        uri, experiment, experiment_id, parent_id, champion_name, registered_model, record
    )


def write_record(folder: Path, record: dict) -> Path:
    """Write one machine's ``record`` as the track stage does (``folder/reports/mlflow_run.json``).

    Returns the file's path.
    """
    path = folder / "reports" / "mlflow_run.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    shared = ("tracking_uri", "experiment")
    document = {
        **{key: record[key] for key in shared},
        "machines": {record["machine"]: {k: v for k, v in record.items() if k not in shared}},
    }
    path.write_text(json.dumps(document, indent=2))
    return path

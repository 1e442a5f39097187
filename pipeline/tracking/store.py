"""Write run records to an MLflow tracking store in batches.

The only module of the package that imports :mod:`mlflow`. Every run gets its tags at
creation, then its parameters and metrics in one ``MlflowClient.log_batch`` call (which splits
them into requests within MLflow's limits itself), then its end status: a few store round trips
per run whatever the number of metrics.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from urllib.parse import unquote, urlsplit, urlunsplit

import pandas as pd
import requests
from mlflow.entities import Metric, Param, Run, RunStatus, RunTag
from mlflow.exceptions import MlflowException
from mlflow.tracking import MlflowClient
from mlflow.utils.mlflow_tags import MLFLOW_LOGGED_ARTIFACTS

from pipeline.errors import InputDataError
from pipeline.tracking.records import IDENTITY_TAG, NOTE_TAG, PARENT_RUN_TAG, RunRecord
from pipeline.tracking.views import SHARED_VIEW_TAG

logger = logging.getLogger(__name__)

MAX_TAGS_AT_CREATION = 100
"""Tags sent with ``create_run``; the rest follow in a ``log_batch`` call."""


# MLflow's own defaults retry an unreachable server for minutes; fail within about a minute
# instead. A user's own settings of these variables win.
__all__ = ["MlflowException"]  # re-exported: callers catch it without importing mlflow

UNREACHABLE = (MlflowException, requests.exceptions.RequestException)
"""What a store that cannot be reached (or refuses a request) raises."""

HTTP_DEFAULTS = {"MLFLOW_HTTP_REQUEST_MAX_RETRIES": "2", "MLFLOW_HTTP_REQUEST_TIMEOUT": "20"}


def sqlite_path(uri: str) -> str | None:
    """Return the database path of a ``sqlite:///`` URI (None: not SQLite, or in memory)."""
    prefix = "sqlite:///"
    if not uri.startswith(prefix):
        return None
    path = unquote(uri[len(prefix) :].split("?", 1)[0])
    return None if not path or path == ":memory:" else path


def public_uri(uri: str) -> str:
    """Return ``uri`` without user name and password, safe to write to a report."""
    parts = urlsplit(uri)
    if "@" not in parts.netloc:
        return uri
    return urlunsplit(parts._replace(netloc=parts.netloc.rsplit("@", 1)[1]))


def make_client(tracking_uri: str) -> MlflowClient:
    """Return a client of the store at ``tracking_uri`` (e.g. ``sqlite:///mlflow.db``)."""
    for name, value in HTTP_DEFAULTS.items():
        os.environ.setdefault(name, value)
    return MlflowClient(tracking_uri=tracking_uri)


def ensure_experiment(client: MlflowClient, name: str, artifact_location: str | None) -> str:
    """Return the id of experiment ``name``, creating it if needed.

    Parameters
    ----------
    client : MlflowClient
        Client of the store.
    name : str
        Experiment name (``params.yaml`` ``track.experiment``).
    artifact_location : str or None
        Artifact root of a new experiment (a ``file://`` URI for the local store); ``None``
        lets the store choose (a tracking server's ``--default-artifact-root``).

    Raises
    ------
    InputDataError
        If the experiment exists but is deleted: MLflow keeps the name reserved.
    """
    experiment = client.get_experiment_by_name(name)
    if experiment is None:
        experiment_id = client.create_experiment(name, artifact_location=artifact_location)
        logger.info("created MLflow experiment '%s' (id %s)", name, experiment_id)
        return experiment_id
    if experiment.lifecycle_stage != "active":
        raise InputDataError(
            f"MLflow experiment '{name}' (id {experiment.experiment_id}) is deleted; restore it "
            f"(mlflow experiments restore --experiment-id {experiment.experiment_id}), delete it "
            "for good (mlflow gc), or set another params.yaml track.experiment"
        )
    return experiment.experiment_id


def find_parent(client: MlflowClient, experiment_id: str, identity: str) -> Run | None:
    """Return the finished, active parent run tagged with ``identity``, if any."""
    runs = client.search_runs(
        [experiment_id],
        filter_string=f"tags.{IDENTITY_TAG} = '{identity}' and attributes.status = 'FINISHED'",
        max_results=1,
        order_by=["attributes.start_time DESC"],
    )
    return runs[0] if runs else None


def discard_incomplete(
    client: MlflowClient, experiment_id: str, identity: str, stale_after_s: float = 1800.0
) -> list[str]:
    """Delete the unfinished attempts at logging the execution tagged with ``identity``.

    An attempt cut off by an unreachable server leaves a parent run that is ``FAILED`` (or still
    ``RUNNING`` when the connection went before its end status could be set), some of its
    children and perhaps a registered champion version. They are deleted (runs are
    soft-deleted: ``mlflow gc`` purges them), so the store holds the execution once. A
    ``RUNNING`` parent is deleted only once it started more than ``stale_after_s`` ago: a
    younger one may be another ``thermal track`` of the same execution logging right now (a
    scheduled retrain and a developer on one team server).

    Parameters
    ----------
    client : MlflowClient
        Client of the store.
    experiment_id : str
        The experiment the attempts were logged to.
    identity : str
        The execution's run identity (tag ``run_identity`` of its parent).
    stale_after_s : float, s
        Age from which a ``RUNNING`` parent counts as abandoned.

    Returns
    -------
    list of str
        Ids of the parent runs deleted.
    """
    parents = client.search_runs(
        [experiment_id],
        filter_string=f"tags.{IDENTITY_TAG} = '{identity}' and attributes.status != 'FINISHED'",
        max_results=1000,
    )
    deleted = []
    now_ms = time.time() * 1000.0
    for parent in parents:
        running = parent.info.status == RunStatus.to_string(RunStatus.RUNNING)
        if running and now_ms - parent.info.start_time < stale_after_s * 1000.0:
            continue
        parent_id = parent.info.run_id
        children = client.search_runs(
            [experiment_id],
            filter_string=f"tags.{PARENT_RUN_TAG} = '{parent_id}'",
            max_results=5000,
        )
        child_ids = [run.info.run_id for run in children]
        for child_id in child_ids:
            for version in client.search_model_versions(f"run_id = '{child_id}'"):
                client.delete_model_version(version.name, version.version)
        for run_id in [*child_ids, parent_id]:
            client.delete_run(run_id)
        deleted.append(parent_id)
    return deleted


def log_values(
    client: MlflowClient,
    run_id: str,
    metrics: Sequence[tuple[str, float, int]] = (),
    params: Mapping[str, str] | None = None,
    tags: Mapping[str, str] | None = None,
) -> None:
    """Log metrics ``(key, value, step)``, params and tags in one ``log_batch`` call."""
    params, tags = params or {}, tags or {}
    if not metrics and not params and not tags:
        return
    timestamp = int(time.time() * 1000)
    client.log_batch(
        run_id,
        metrics=[Metric(key, float(value), timestamp, step) for key, value, step in metrics],
        params=[Param(key, str(value)) for key, value in params.items()],
        tags=[RunTag(key, str(value)) for key, value in tags.items()],
    )


def log_record(client: MlflowClient, run_id: str, record: RunRecord) -> None:
    """Log a record's params and metrics (tags are set at run creation) in one ``log_batch``."""
    metrics = [(key, value, 0) for key, value in record.metrics.items()]
    log_values(client, run_id, metrics, record.params)


def _create_run(client: MlflowClient, experiment_id: str, record: RunRecord, extra: dict) -> str:
    tags = list({**record.tags, **extra}.items())
    first = dict(tags[:MAX_TAGS_AT_CREATION])
    run = client.create_run(experiment_id, tags=first, run_name=record.name)
    if rest := tags[MAX_TAGS_AT_CREATION:]:
        client.log_batch(run.info.run_id, tags=[RunTag(key, value) for key, value in rest])
    return run.info.run_id


def table_tag(record: RunRecord) -> dict[str, str]:
    """Return the ``mlflow.loggedArtifacts`` tag listing a record's tables (none: no tag).

    With it, MLflow's UI shows the table artifacts as tables and ``MlflowClient.load_table``
    finds them, as after ``MlflowClient.log_table``.
    """
    if not record.tables:
        return {}
    listed = [{"path": artifact_file, "type": "table"} for artifact_file in record.tables]
    return {MLFLOW_LOGGED_ARTIFACTS: json.dumps(listed)}


def log_evidence(client: MlflowClient, run_id: str, record: RunRecord) -> None:
    """Log a record's tables and files under their artifact paths, in one upload.

    A table is written as ``MlflowClient.log_table`` writes it (JSON, pandas' ``split``
    orientation without the index), listed by :func:`table_tag` when the run is created;
    ``log_table`` itself would list and read the run's artifacts and the run once per table.
    """
    if not record.tables and not record.files:
        return
    with tempfile.TemporaryDirectory() as folder:
        targets = {path: Path(folder) / path for path in [*record.tables, *record.files]}
        for target in targets.values():
            target.parent.mkdir(parents=True, exist_ok=True)
        for artifact_file, rows in record.tables.items():
            frame = pd.DataFrame(rows)
            frame.to_json(targets[artifact_file], orient="split", index=False, date_format="iso")
        for artifact_path, local in record.files.items():
            shutil.copyfile(local, targets[artifact_path])
        client.log_artifacts(run_id, folder)


def _log_one(
    client: MlflowClient,
    experiment_id: str,
    record: RunRecord,
    extra: dict,
    hook: Callable[[RunRecord, str], None] | None = None,
) -> str:
    run_id = _create_run(client, experiment_id, record, {**extra, **table_tag(record)})
    try:
        if hook is not None:
            hook(record, run_id)
        log_record(client, run_id, record)
        log_evidence(client, run_id, record)
    except BaseException:
        client.set_terminated(run_id, RunStatus.to_string(RunStatus.FAILED))
        raise
    return run_id


def log_pipeline(
    client: MlflowClient,
    experiment_id: str,
    parent: RunRecord,
    children: Sequence[RunRecord],
    artifacts: Sequence[tuple[Path, str]],
    with_child: Callable[[RunRecord, str], None] | None = None,
) -> str:
    """Log the parent run, its child runs and the parent's artifacts.

    The parent is marked ``FINISHED`` only after everything is logged, and ``FAILED`` if
    anything raises, so :func:`find_parent` never reuses an incomplete record.

    Parameters
    ----------
    client : MlflowClient
        Client of the store.
    experiment_id : str
        Target experiment.
    parent : RunRecord
        The pipeline execution (its tags carry the run identity).
    children : sequence of RunRecord
        One per candidate (axis, model, selection, mode); linked with ``mlflow.parentRunId``.
    artifacts : sequence of (Path, str)
        Local file and the artifact folder it goes to on the parent (e.g. ``"reports"``).
    with_child : callable, optional
        Called with each child's record and run id right after the child is created, before
        its metrics are logged (an axis' champion model is logged and registered there, from
        its own child run: MLflow links a logged model to every metric its run already has,
        one request per metric).

    Returns
    -------
    str
        The parent run id.
    """
    parent_id = _create_run(client, experiment_id, parent, {})
    try:
        log_record(client, parent_id, parent)
        for child in children:
            child_id = _log_one(
                client, experiment_id, child, {PARENT_RUN_TAG: parent_id}, with_child
            )
            client.set_terminated(child_id)
        for path, folder in artifacts:
            client.log_artifact(parent_id, str(path), artifact_path=folder or None)
    except BaseException:
        client.set_terminated(parent_id, RunStatus.to_string(RunStatus.FAILED))
        raise
    client.set_terminated(parent_id)
    return parent_id


def describe_experiment(client: MlflowClient, experiment_id: str, text: str) -> None:
    """Set the experiment's description (the tag ``mlflow.note.content``) to ``text``."""
    client.set_experiment_tag(experiment_id, NOTE_TAG, text)


def share_views(client: MlflowClient, experiment_id: str, views: Mapping[str, str]) -> None:
    """Store shared views of the run list (experiment tags ``mlflow.sharedViewState.<key>``)."""
    for key, state in views.items():
        client.set_experiment_tag(experiment_id, f"{SHARED_VIEW_TAG}{key}", state)


def link_runs(client: MlflowClient, parent_id: str, other_id: str, name: str) -> bool:
    """Tag a pipeline run and another run of the same ``dvc repro`` with each other's id.

    The parent gets ``<name>_run_id`` (and ``<name>_experiment_id``), the other run
    ``pipeline_run_id`` and ``pipeline_experiment_id``. Returns False, with a warning, when the
    other run is not in this store (e.g. logged to another tracking URI).
    """
    try:
        other = client.get_run(other_id)
        parent = client.get_run(parent_id)
    except MlflowException as error:
        logger.warning("cannot link run %s to the pipeline run %s: %s", other_id, parent_id, error)
        return False
    client.set_tag(parent_id, f"{name}_run_id", other_id)
    client.set_tag(parent_id, f"{name}_experiment_id", other.info.experiment_id)
    client.set_tag(other_id, "pipeline_run_id", parent_id)
    client.set_tag(other_id, "pipeline_experiment_id", parent.info.experiment_id)
    client.set_tag(other_id, "pipeline_run_name", parent.info.run_name)
    return True


def parent_versions(
    client: MlflowClient, experiment_id: str, parent_id: str, names: Sequence[str]
) -> dict[str, str]:
    """Return the latest version of each model registered from a child run of ``parent_id``.

    Models with no version from this parent are left out.
    """
    children = client.search_runs(
        [experiment_id], filter_string=f"tags.{PARENT_RUN_TAG} = '{parent_id}'", max_results=5000
    )
    ids = {run.info.run_id for run in children}
    found = {}
    for name in names:
        mine = [v for v in client.search_model_versions(f"name = '{name}'") if v.run_id in ids]
        if mine:
            found[name] = str(max(mine, key=lambda v: int(v.version)).version)
    return found


def champion_version(client: MlflowClient, registered_name: str, alias: str) -> str | None:
    """Version of ``registered_name`` carrying ``alias``, or ``None`` if there is none."""
    try:
        return str(client.get_model_version_by_alias(registered_name, alias).version)
    except MlflowException:
        return None

"""Where the runs are logged: the tracking URI, its absolute form, the local artifact folder.

``$MLFLOW_TRACKING_URI`` when set, else ``params.yaml``'s ``default_tracking_uri``
(``sqlite:///mlflow.db`` in the working directory, artifacts in ``mlartifacts/`` beside it); and
the message of a store that cannot be reached, saying that nothing is lost and how to log later.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipeline.settings.tracking import TrackingSettings
from pipeline.tracking import records, store

ENV_TRACKING_URI = "MLFLOW_TRACKING_URI"


def resolve_tracking_uri(settings: TrackingSettings) -> str:
    """Return ``$MLFLOW_TRACKING_URI`` if set and not empty, else the configured default."""
    return os.environ.get(ENV_TRACKING_URI) or settings.default_tracking_uri


def absolute_store_uri(uri: str) -> str:
    """Return ``uri`` with a relative SQLite path made absolute (from the working directory).

    MLflow caches one store per URI string in a process, so a relative ``sqlite:///mlflow.db``
    would keep pointing at the first working directory's file.
    """
    path = store.sqlite_path(uri)
    if path is None or Path(path).is_absolute():
        return uri
    query = uri.split("?", 1)[1] if "?" in uri else ""
    return f"sqlite:///{Path(path).resolve().as_posix()}" + (f"?{query}" if query else "")


def local_artifact_location(uri: str, artifact_dir: str, experiment: str) -> str | None:
    """Artifact root of a new experiment in a local SQLite store, else ``None``.

    Parameters
    ----------
    uri : str
        Tracking URI. For ``sqlite:///<path>`` (relative to the working directory) or
        ``sqlite:////<absolute path>`` the artifacts go to ``<db folder>/<artifact_dir>/
        <experiment>/<run id>/artifacts``; other stores (a tracking server) choose themselves.
    artifact_dir : str
        Folder name beside the database, e.g. ``mlartifacts``.
    experiment : str
        Experiment name, used as sub-folder (unsafe characters replaced by ``_``).

    Returns
    -------
    str or None
        A ``file://`` URI, or ``None`` for non-SQLite or in-memory stores.
    """
    db_path = store.sqlite_path(uri)
    if db_path is None:
        return None
    folder = records.safe_key(experiment).replace("/", "_").replace(" ", "_")
    return (Path(db_path).resolve().parent / artifact_dir / folder).as_uri()


def unreachable_message(uri: str, error: BaseException) -> str:
    """Return the message of a track stage that could not log: nothing lost, how to log later."""
    return (
        f"thermal track: the MLflow tracking store {store.public_uri(uri)} cannot be used "
        f"({str(error).strip()[:300]}). Nothing is lost: the scores, reports and champion models "
        "of this pipeline execution are DVC outputs (reports/, metrics/, data/models/champion/) "
        "and stay as they are. When the store can be reached (start the server, or fix "
        "MLFLOW_TRACKING_URI; unset it to log to the local store sqlite:///mlflow.db), run "
        "'bin/thermal track' from the repository root, or 'dvc repro' (.venv/bin/dvc), which "
        "reruns only this stage: the execution is logged once, and a partly logged attempt of "
        "it is deleted, not duplicated."
    )

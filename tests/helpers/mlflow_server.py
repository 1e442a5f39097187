"""Start a real ``mlflow server`` for tests, and always stop it.

Usage (in a test marked ``@pytest.mark.slow``)::

    from tests.helpers.mlflow_server import running_mlflow_server

    with running_mlflow_server(tmp_path) as uri:   # "http://127.0.0.1:<port>"
        env = {**os.environ, "MLFLOW_TRACKING_URI": uri}
        ...

The server listens on 127.0.0.1 at a free port, with its backend in
``<tmp_path>/mlflow-server/mlflow.db`` (a copy of an empty database that already has MLflow's
tables, made once per MLflow version: a server migrating a new database takes seconds) and
proxied artifacts in
``<tmp_path>/mlflow-server/artifacts``; its output goes to ``<tmp_path>/mlflow-server/mlflow.log``
(quoted in the error when it does not become healthy). It runs in its own process group, which
is terminated (then killed) on exit, workers included
(:func:`tests.helpers.processes.running_mlflow`, the code the UI check starts ``mlflow ui``
with).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import mlflow
from mlflow.tracking import MlflowClient

from tests.helpers.processes import running_mlflow


def empty_database(destination: Path) -> None:
    """Write an empty MLflow database (tables made, no run) to ``destination``.

    The tables are made once per MLflow version, in the system's temporary folder, and copied:
    MLflow's schema migrations take seconds on every new database. The template is written under
    another name and renamed, so that a test session running beside this one never reads half a
    file.
    """
    template = Path(tempfile.gettempdir()) / f"thermal-tests-mlflow-{mlflow.__version__}.db"
    if not template.is_file():
        scratch = template.with_name(f"{template.name}.{os.getpid()}.tmp")
        MlflowClient(tracking_uri=f"sqlite:///{scratch}").search_experiments()
        os.replace(scratch, template)
    shutil.copyfile(template, destination)


@contextmanager
def running_mlflow_server(tmp_path: Path, timeout_s: float = 120.0) -> Iterator[str]:
    """Run ``mlflow server`` until the ``with`` block ends; yield its tracking URI.

    Parameters
    ----------
    tmp_path : Path
        Folder for the server's database, artifacts and log (sub-folder ``mlflow-server``).
    timeout_s : float
        How long to wait for ``/health`` to answer 200, in seconds.

    Yields
    ------
    str
        ``http://127.0.0.1:<port>``, for ``MLFLOW_TRACKING_URI``.

    Raises
    ------
    tests.helpers.processes.ServerError
        If the server exits or is not healthy in time, with the end of its log.
    """
    folder = Path(tmp_path) / "mlflow-server"
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "mlflow.db").is_file():
        empty_database(folder / "mlflow.db")
    arguments = [
        "server",
        "--backend-store-uri",
        f"sqlite:///{folder / 'mlflow.db'}",
        "--artifacts-destination",
        str(folder / "artifacts"),
    ]
    with running_mlflow(arguments, folder, timeout_s) as uri:
        yield uri

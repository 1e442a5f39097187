"""A team's tracking server for tests: ``mlflow server`` on PostgreSQL with artifacts in S3.

Usage (in a test marked ``@pytest.mark.slow``; skip it where
``tests.helpers.postgres_server.unavailable_reason`` says why)::

    from tests.helpers.team_server import running_team_server

    with running_team_server(tmp_path) as team:
        env = {**os.environ, "MLFLOW_TRACKING_URI": team.uri}
        ...

The setup ``docs/team-server.md`` describes, every part a real server on 127.0.0.1: PostgreSQL
as the backend store (:mod:`.postgres_server`), moto's S3 server as the artifact store
(:mod:`.s3_server`), and ``mlflow server`` between them, which proxies the artifacts: the
pipeline's side needs only the tracking URI, no S3 credentials.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from tests.helpers.postgres_server import running_postgres
from tests.helpers.processes import running_mlflow
from tests.helpers.s3_server import S3_CREDENTIALS, running_s3_server

BUCKET = "mlflow-artifacts"


@dataclass(frozen=True)
class TeamServer:
    """The running servers: MLflow's tracking URI, the database's URL, the S3 endpoint."""

    uri: str
    database: str
    s3_endpoint: str


@contextmanager
def running_team_server(tmp_path: Path, timeout_s: float = 180.0) -> Iterator[TeamServer]:
    """Run PostgreSQL, an S3 server and ``mlflow server`` until the ``with`` block ends.

    Parameters
    ----------
    tmp_path : Path
        Folder for the S3 server's and MLflow's logs.
    timeout_s : float
        How long to wait for MLflow's ``/health``, s (it creates its tables in the new
        database first).
    """
    folder = Path(tmp_path) / "team-server"
    folder.mkdir(parents=True, exist_ok=True)
    with (
        running_postgres(database="mlflow") as database,
        running_s3_server(folder, bucket=BUCKET) as endpoint,
    ):
        arguments = [
            "server",
            "--backend-store-uri",
            database,
            "--artifacts-destination",
            f"s3://{BUCKET}/mlartifacts",
        ]
        store = {**S3_CREDENTIALS, "MLFLOW_S3_ENDPOINT_URL": endpoint}
        with running_mlflow(arguments, folder, timeout_s, env=store) as uri:
            yield TeamServer(uri, database, endpoint)

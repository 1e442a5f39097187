"""Start a real ``mlflow server`` for tests, and always stop it.

Usage (in a test marked ``@pytest.mark.slow``)::

    from tests.mlflow_server import running_mlflow_server

    with running_mlflow_server(tmp_path) as uri:   # "http://127.0.0.1:<port>"
        env = {**os.environ, "MLFLOW_TRACKING_URI": uri}
        ...

The server listens on 127.0.0.1 at a free port, with its backend in
``<tmp_path>/mlflow-server/mlflow.db`` and proxied artifacts in
``<tmp_path>/mlflow-server/artifacts``; its output goes to ``<tmp_path>/mlflow-server/server.log``
(quoted in the error when it does not become healthy). It runs in its own process group, which
is terminated (then killed) on exit, workers included.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def free_port() -> int:
    """Return a TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _healthy(uri: str) -> bool:
    try:
        with urllib.request.urlopen(f"{uri}/health", timeout=2) as response:  # noqa: S310
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def _log_tail(log: Path, lines: int = 40) -> str:
    try:
        return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no server log)"


def _stop(process: subprocess.Popen, grace_s: float = 10.0) -> None:
    if process.poll() is not None:
        return
    try:
        os.killpg(process.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    try:
        process.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait(timeout=grace_s)


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
    RuntimeError
        If the server exits or is not healthy in time, with the end of its log.
    """
    folder = Path(tmp_path) / "mlflow-server"
    folder.mkdir(parents=True, exist_ok=True)
    port = free_port()
    uri = f"http://127.0.0.1:{port}"
    log = folder / "server.log"
    command = [
        sys.executable,
        "-m",
        "mlflow",
        "server",
        "--backend-store-uri",
        f"sqlite:///{folder / 'mlflow.db'}",
        "--artifacts-destination",
        str(folder / "artifacts"),
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        "--workers",
        "1",
    ]
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    with log.open("wb") as output:
        process = subprocess.Popen(  # noqa: S603
            command,
            cwd=folder,
            env=env,
            stdout=output,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
    try:
        deadline = time.monotonic() + timeout_s
        while not _healthy(uri):
            if process.poll() is not None:
                raise RuntimeError(
                    f"mlflow server exited with code {process.returncode} before answering "
                    f"{uri}/health; end of {log}:\n{_log_tail(log)}"
                )
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"mlflow server did not answer {uri}/health within {timeout_s:.0f} s; "
                    f"end of {log}:\n{_log_tail(log)}"
                )
            time.sleep(0.25)
        yield uri
    finally:
        _stop(process)

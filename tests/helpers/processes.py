"""Server processes for tests: a free 127.0.0.1 port, ``mlflow ui``/``mlflow server``, stopping.

:func:`running_mlflow` starts the ``mlflow`` executable of the running Python environment on a
free port, waits for ``/health`` and always stops it with its workers (:func:`stop_group`, its
whole process group). The MLflow server of the end-to-end tests (:mod:`.mlflow_server`), the UI
check (``tests/ui/``), the S3 server and the OPC UA controller start their processes this way.
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
from contextlib import contextmanager, suppress
from pathlib import Path

HEALTH_TIMEOUT_S = 60.0
LOG_TAIL_LINES = 30
JOB_EXECUTION_SWITCH = "MLFLOW_SERVER_ENABLE_JOB_EXECUTION"
"""Set to ``false`` for the servers started here: MLflow 3's job runner (Huey consumer processes
for its GenAI scorer jobs, which the pipeline never submits) would otherwise start with every
server and keep a core busy for tens of seconds."""


class ServerError(RuntimeError):
    """A server process did not start; the message ends with its output."""


def free_port() -> int:
    """Return a TCP port on 127.0.0.1 that was free a moment ago (the OS chooses it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def healthy(base_url: str, timeout_s: float = 2.0) -> bool:
    """Return whether ``<base_url>/health`` answers 200."""
    try:
        with urllib.request.urlopen(f"{base_url}/health", timeout=timeout_s) as response:  # noqa: S310
            return response.status == 200
    except (urllib.error.URLError, OSError):
        return False


def log_tail(path: Path, lines: int = LOG_TAIL_LINES) -> str:
    """Return the last ``lines`` lines of a process's log file, decoded."""
    try:
        output = path.read_bytes()
    except OSError:
        return "(no output)"
    return "\n".join(output.decode(errors="replace").splitlines()[-lines:])


def stop_group(process: subprocess.Popen, grace_s: float = 5.0) -> None:
    """Stop the process group of ``process`` (started in its own session) and reap it.

    SIGTERM first, SIGKILL to whatever of the group is left after ``grace_s`` seconds or after
    the leader exited (a server's workers).
    """
    if process.poll() is None:
        with suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        with suppress(subprocess.TimeoutExpired):
            process.wait(timeout=grace_s)
    with suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)
    process.wait(timeout=grace_s)


def mlflow_command() -> list[str]:
    """Return the ``mlflow`` executable beside the running Python, else ``python -m mlflow``."""
    executable = Path(sys.executable).parent / "mlflow"
    return [str(executable)] if executable.is_file() else [sys.executable, "-m", "mlflow"]


def _wait_healthy(
    process: subprocess.Popen, base_url: str, name: str, log: Path, timeout_s: float
) -> None:
    """Wait until ``<base_url>/health`` answers 200.

    Raises
    ------
    ServerError
        If ``process`` (``name``, its output in ``log``) exits first, or ``timeout_s`` seconds
        pass.
    """
    deadline = time.monotonic() + timeout_s
    while not healthy(base_url):
        if process.poll() is not None:
            raise ServerError(
                f"{name} exited with code {process.returncode} before "
                f"answering {base_url}/health; its output ends with:\n{log_tail(log)}"
            )
        if time.monotonic() > deadline:
            raise ServerError(
                f"{name} did not answer {base_url}/health within "
                f"{timeout_s:.0f} s; its output ends with:\n{log_tail(log)}"
            )
        time.sleep(0.25)


@contextmanager
def running_mlflow(
    arguments: list[str],
    folder: Path,
    timeout_s: float = HEALTH_TIMEOUT_S,
    env: dict[str, str] | None = None,
) -> Iterator[str]:
    """Run ``mlflow <arguments>`` on a free 127.0.0.1 port until the ``with`` block ends.

    The process runs in ``folder`` (its output in ``folder/mlflow.log``), without the caller's
    ``MLFLOW_*`` variables, in its own process group, stopped with its workers on exit.

    Parameters
    ----------
    arguments : list of str
        E.g. ``["ui", "--backend-store-uri", uri]`` or ``["server", ...]``; ``--host``,
        ``--port`` and ``--workers 1`` are added.
    folder : Path
        Working folder of the process (and of its log).
    timeout_s : float
        How long to wait for ``/health`` to answer 200, in seconds.
    env : dict of str to str, optional
        Variables the server gets beside the caller's others (e.g. its artifact store's
        ``MLFLOW_S3_ENDPOINT_URL`` and credentials).

    Yields
    ------
    str
        ``http://127.0.0.1:<port>``.

    Raises
    ------
    ServerError
        If the process exits or is not healthy in time, with the end of its output.
    """
    port = free_port()
    base_url = f"http://127.0.0.1:{port}"
    host = ["--host", "127.0.0.1", "--port", str(port), "--workers", "1"]
    extra = env or {}
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env.update({**extra, JOB_EXECUTION_SWITCH: "false"})
    log = Path(folder) / "mlflow.log"
    with log.open("wb") as output:
        process = subprocess.Popen(  # noqa: S603
            [*mlflow_command(), *arguments, *host],
            cwd=folder,
            env=env,
            stdout=output,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
    try:
        _wait_healthy(process, base_url, f"mlflow {arguments[0]}", log, timeout_s)
        yield base_url
    finally:
        stop_group(process)

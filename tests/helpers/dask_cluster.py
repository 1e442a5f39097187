"""Start a real Dask cluster on 127.0.0.1 for tests: a scheduler and worker processes.

Usage (in a test marked ``@pytest.mark.slow``)::

    from tests.helpers.dask_cluster import running_dask_cluster

    with running_dask_cluster(tmp_path, n_workers=2) as address:  # "tcp://127.0.0.1:<port>"
        env = {**os.environ, "THERMAL_DASK_SCHEDULER": address}
        ...

The scheduler is ``dask scheduler`` and each worker ``dask worker <address>`` (one thread, one
process), separate processes of the running Python environment, each in its own process group,
stopped as the MLflow server is (:func:`~tests.helpers.processes.stop_group`); their output goes
to ``<tmp_path>/dask/<name>.log``.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

from distributed import Client

from tests.helpers.processes import ServerError, free_port, log_tail, stop_group

START_TIMEOUT_S = 90.0


@contextmanager
def running_dask_cluster(
    tmp_path: Path, n_workers: int = 2, timeout_s: float = START_TIMEOUT_S
) -> Iterator[str]:
    """Run a Dask scheduler and ``n_workers`` workers until the ``with`` block ends.

    Yields
    ------
    str
        The scheduler's address, ``tcp://127.0.0.1:<port>``, once every worker has joined.

    Raises
    ------
    ServerError
        If a process exits or the workers have not joined in time, with the end of its log.
    """
    folder = Path(tmp_path) / "dask"
    folder.mkdir(parents=True, exist_ok=True)
    address = f"tcp://127.0.0.1:{free_port()}"
    dask = str(Path(sys.executable).parent / "dask")
    local = ["--no-dashboard", "--host", "127.0.0.1"]
    commands = {"scheduler": [dask, "scheduler", "--port", address.rsplit(":", 1)[1], *local]}
    for i in range(n_workers):
        commands[f"worker-{i}"] = [dask, "worker", address, "--nthreads", "1", *local]
    with ExitStack() as stack:
        processes = {}
        for name, command in commands.items():
            processes[name] = _start(command, folder / f"{name}.log")
            stack.callback(stop_group, processes[name])
        _wait_for_workers(address, n_workers, processes, folder, timeout_s)
        yield address


def _start(command: list[str], log: Path) -> subprocess.Popen:
    with log.open("wb") as output:
        return subprocess.Popen(  # noqa: S603
            command,
            cwd=log.parent,
            stdout=output,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )


def _wait_for_workers(
    address: str, n_workers: int, processes: dict, folder: Path, timeout_s: float
) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        for name, process in processes.items():
            if process.poll() is not None:
                raise ServerError(
                    f"dask {name} exited with code {process.returncode}; its output ends "
                    f"with:\n{log_tail(folder / f'{name}.log')}"
                )
        try:
            with Client(address, timeout=5) as client:
                client.wait_for_workers(n_workers, timeout=max(1.0, deadline - time.monotonic()))
                return
        except (OSError, TimeoutError) as error:
            if time.monotonic() > deadline:
                raise ServerError(
                    f"the Dask cluster at {address} did not have {n_workers} workers within "
                    f"{timeout_s:.0f} s ({error}); the scheduler's output ends with:\n"
                    f"{log_tail(folder / 'scheduler.log')}"
                ) from error
            time.sleep(0.5)

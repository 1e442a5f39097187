"""Processes of ``thermal ui-check``: a local ``mlflow ui`` server and headless Chromium.

:func:`running_mlflow_ui` starts the ``mlflow`` executable of the running Python environment on
a free 127.0.0.1 port, waits for ``/health`` and always stops it (its whole process group);
:func:`render_page` runs Chromium once on a URL, writes a PNG screenshot and returns the DOM
after the page's JavaScript ran (``--dump-dom``). No browser automation library: Playwright
would download its own browser, which an offline machine cannot do.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator, Mapping
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import BinaryIO

ENV_CHROMIUM = "CHROMIUM"
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
HEALTH_TIMEOUT_S = 60.0
LOG_TAIL_LINES = 30
HEADLESS_FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--no-first-run",
    "--no-default-browser-check",
)
"""Flags of every headless Chromium this check starts (no GPU, no first-run dialogs)."""


class ServerError(RuntimeError):
    """The ``mlflow ui`` server did not start; the message ends with its output."""


class BrowserError(RuntimeError):
    """Chromium did not render a page; the message ends with its output."""


def find_chromium(env: Mapping[str, str] | None = None) -> str | None:
    """Return the Chromium executable to use, or ``None``.

    Parameters
    ----------
    env : mapping, optional
        Environment (``os.environ`` by default): ``$CHROMIUM`` if set, else the first of
        ``chromium``, ``chromium-browser``, ``google-chrome`` on its ``PATH``.

    Returns
    -------
    str or None
        An executable path.
    """
    env = os.environ if env is None else env
    path = env.get("PATH", os.defpath)
    if env.get(ENV_CHROMIUM):
        return shutil.which(env[ENV_CHROMIUM], path=path)
    for name in CHROMIUM_NAMES:
        found = shutil.which(name, path=path)
        if found:
            return found
    return None


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


def fetch(url: str, timeout_s: float = 30.0) -> tuple[int, bytes]:
    """GET ``url``; return the HTTP status and body (status 0 when nothing answered)."""
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as response:  # noqa: S310
            return response.status, response.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()
    except (urllib.error.URLError, OSError):
        return 0, b""


def _last_lines(output: bytes, lines: int = LOG_TAIL_LINES) -> str:
    """Return the last ``lines`` lines of a process's ``output``, decoded."""
    return "\n".join(output.decode(errors="replace").splitlines()[-lines:])


def file_tail(file: BinaryIO) -> str:
    """Return the last lines of an open (temporary) output file, read from its start."""
    file.seek(0)
    return _last_lines(file.read())


def _tail(path: Path) -> str:
    try:
        return _last_lines(path.read_bytes())
    except OSError:
        return "(no output)"


def stop_group(process: subprocess.Popen, grace_s: float = 5.0) -> None:
    """Stop the process group of ``process`` (started in its own session) and reap it.

    SIGTERM first, SIGKILL to whatever of the group is left after ``grace_s`` seconds or after
    the leader exited (Chromium's helper processes).
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
                f"answering {base_url}/health; its output ends with:\n{_tail(log)}"
            )
        if time.monotonic() > deadline:
            raise ServerError(
                f"{name} did not answer {base_url}/health within "
                f"{timeout_s:.0f} s; its output ends with:\n{_tail(log)}"
            )
        time.sleep(0.25)


@contextmanager
def running_mlflow(
    arguments: list[str], folder: Path, timeout_s: float = HEALTH_TIMEOUT_S
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
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
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


@contextmanager
def running_mlflow_ui(store_uri: str, timeout_s: float = HEALTH_TIMEOUT_S) -> Iterator[str]:
    """Run ``mlflow ui`` on ``store_uri`` until the ``with`` block ends; yield its base URL.

    The runs' artifacts are served from their own (``file://``) artifact locations. See
    :func:`running_mlflow`.
    """
    with tempfile.TemporaryDirectory(prefix="thermal-ui-check-") as folder:
        arguments = ["ui", "--backend-store-uri", store_uri]
        with running_mlflow(arguments, Path(folder), timeout_s) as base_url:
            yield base_url


def chromium_command(
    chromium: str, profile: Path, window: tuple[int, int], arguments: list[str]
) -> list[str]:
    """Return the command line of a headless Chromium.

    Parameters
    ----------
    chromium : str
        The Chromium executable.
    profile : Path
        ``--user-data-dir``, a fresh temporary folder.
    window : tuple of int
        Window width and height, in CSS pixels.
    arguments : list of str
        What follows :data:`HEADLESS_FLAGS`, the profile and the window size (the page last).

    Returns
    -------
    list of str
    """
    return [
        chromium,
        *HEADLESS_FLAGS,
        f"--user-data-dir={profile}",
        f"--window-size={window[0]},{window[1]}",
        *arguments,
    ]


def _run_to_end(command: list[str], timeout_s: float) -> tuple[int | None, str, str]:
    """Run ``command`` in its own process group, stopped with its children after it ends.

    Returns
    -------
    code : int or None
        Exit code; None if it ran longer than ``timeout_s`` seconds.
    stdout : str
        Its whole output.
    tail : str
        The last lines of its error output.
    """
    with tempfile.TemporaryFile() as output, tempfile.TemporaryFile() as errors:
        process = subprocess.Popen(  # noqa: S603
            command, stdout=output, stderr=errors, stdin=subprocess.DEVNULL, start_new_session=True
        )
        try:
            code = process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            code = None
        finally:
            stop_group(process)
        output.seek(0)
        return code, output.read().decode("utf-8", errors="replace"), file_tail(errors)


def render_page(
    chromium: str,
    url: str,
    screenshot: Path,
    profile: Path,
    window: tuple[int, int] = (1600, 1200),
    budget_ms: int = 15000,
) -> str:
    """Load ``url`` in headless Chromium; write a PNG screenshot and return the rendered DOM.

    Parameters
    ----------
    chromium : str
        The Chromium executable.
    url : str
        The page, e.g. ``http://127.0.0.1:5000/#/experiments/1?workflowType=machine_learning``.
    screenshot : Path
        PNG file to write (its folder is created).
    profile : Path
        ``--user-data-dir``: a fresh temporary folder of this check, shared by its pages.
    window : tuple of int
        Window width and height, in CSS pixels; tables render only the rows that fit.
    budget_ms : int
        ``--virtual-time-budget``, in ms of virtual time: how long the page's scripts may run
        (network waits do not count) before the DOM and the screenshot are taken.

    Returns
    -------
    str
        The serialised DOM.

    Raises
    ------
    BrowserError
        If Chromium fails, takes far longer than the budget, or writes no screenshot.
    """
    screenshot.parent.mkdir(parents=True, exist_ok=True)
    screenshot.unlink(missing_ok=True)
    page = [f"--virtual-time-budget={budget_ms}", f"--screenshot={screenshot}", "--dump-dom", url]
    timeout_s = budget_ms / 1000 + 90
    code, dom, tail = _run_to_end(chromium_command(chromium, profile, window, page), timeout_s)
    if code is None:
        raise BrowserError(f"Chromium did not finish {url} within {timeout_s:.0f} s:\n{tail}")
    if code != 0 or not screenshot.is_file():
        raise BrowserError(
            f"Chromium exited with code {code} on {url} "
            f"({'no' if not screenshot.is_file() else 'a'} screenshot):\n{tail}"
        )
    return dom

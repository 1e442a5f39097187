"""Drive headless Chromium through the DevTools protocol (CDP), for pages that need a click.

:class:`Session` starts Chromium with ``--remote-debugging-port=0`` and a fresh profile, reads
the port it chose from ``DevToolsActivePort``, connects to its page over a WebSocket
(:mod:`pipeline.tracking.rfc6455`) and sends commands (``Page.navigate``, ``Runtime.evaluate``,
``Page.captureScreenshot``), matching each answer by its id and ignoring events. Leaving the
``with`` block closes the connection and kills Chromium's process group.
"""

from __future__ import annotations

import base64
import json
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from pipeline.tracking import rfc6455, ui_browser

COMMAND_TIMEOUT_S = 60.0


class CdpError(RuntimeError):
    """Chromium did not start, or answered a command with an error."""


class Session:
    """One headless Chromium and a DevTools connection to its page.

    Parameters
    ----------
    chromium : str
        The Chromium executable.
    window : tuple of int
        Viewport width and height, CSS px (``Emulation.setDeviceMetricsOverride``).
    timeout_s : float
        Longest wait for Chromium to start and for each command's answer, in seconds.
    """

    def __init__(
        self,
        chromium: str,
        window: tuple[int, int] = (1600, 1200),
        timeout_s: float = COMMAND_TIMEOUT_S,
    ) -> None:
        self.chromium, self.window, self.timeout_s = chromium, window, timeout_s
        self._profile = tempfile.TemporaryDirectory(prefix="thermal-cdp-")
        self._errors = tempfile.TemporaryFile()
        self._process: subprocess.Popen | None = None
        self._socket: rfc6455.WebSocket | None = None
        self._last_id = 0

    def __enter__(self) -> Session:
        try:
            self._start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start(self) -> None:
        profile = Path(self._profile.name)
        arguments = ["--remote-debugging-port=0", "about:blank"]
        self._process = subprocess.Popen(  # noqa: S603
            ui_browser.chromium_command(self.chromium, profile, self.window, arguments),
            stdout=subprocess.DEVNULL,
            stderr=self._errors,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
        active, deadline = profile / "DevToolsActivePort", time.monotonic() + self.timeout_s
        while len(lines := _lines(active)) < 2:
            if self._process.poll() is not None or time.monotonic() > deadline:
                raise CdpError(
                    f"Chromium opened no DevTools port:\n{ui_browser.file_tail(self._errors)}"
                )
            time.sleep(0.05)
        port = int(lines[0])
        status, body = ui_browser.fetch(f"http://127.0.0.1:{port}/json/list", self.timeout_s)
        pages = [t for t in json.loads(body or b"[]") if t.get("type") == "page"] if status else []
        if not pages:
            raise CdpError(f"Chromium on port {port} lists no page target ({status})")
        path = urlsplit(pages[0]["webSocketDebuggerUrl"]).path
        self._socket = rfc6455.connect("127.0.0.1", port, path, self.timeout_s)
        width, height = self.window
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=width,
            height=height,
            deviceScaleFactor=1,
            mobile=False,
        )

    def call(self, method: str, timeout_s: float | None = None, **params: Any) -> dict[str, Any]:
        """Send one command; return its ``result`` (events met meanwhile are dropped).

        Raises
        ------
        CdpError
            If Chromium answers with an error.
        TimeoutError
            If no answer comes within ``timeout_s`` seconds (default: the session's).
        """
        if self._socket is None:
            raise CdpError(f"{method}: the session is not connected")
        self._last_id += 1
        ident = self._last_id
        self._socket.send(json.dumps({"id": ident, "method": method, "params": params}))
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"{method}: no answer within {timeout_s or self.timeout_s} s")
            self._socket.sock.settimeout(remaining)
            message = json.loads(self._socket.receive())
            if message.get("id") != ident:
                continue
            if "error" in message:
                raise CdpError(f"{method}: {message['error'].get('message', message['error'])}")
            return message.get("result", {})

    def evaluate(self, expression: str) -> Any:
        """Evaluate JavaScript in the page (promises awaited); return its JSON value."""
        result = self.call(
            "Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True
        )
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            text = details.get("exception", {}).get("description") or details.get("text")
            raise CdpError(f"JavaScript error: {text}")
        return result.get("result", {}).get("value")

    def wait_for(self, condition: str, timeout_s: float, interval_s: float = 0.25) -> bool:
        """Poll the JavaScript ``condition`` until truthy; False after ``timeout_s`` seconds."""
        deadline = time.monotonic() + timeout_s
        while not self.evaluate(f"!!({condition})"):
            if time.monotonic() > deadline:
                return False
            time.sleep(interval_s)
        return True

    def navigate(self, url: str, timeout_s: float = 30.0) -> bool:
        """Open ``url``; return whether the document finished loading within ``timeout_s`` s."""
        answer = self.call("Page.navigate", url=url)
        if answer.get("errorText"):
            raise CdpError(f"{url}: {answer['errorText']}")
        return self.wait_for("document.readyState === 'complete'", timeout_s)

    def screenshot(self, path: Path, full_page: bool = False) -> None:
        """Write a PNG of the viewport (or of the whole page) to ``path``."""
        answer = self.call("Page.captureScreenshot", format="png", captureBeyondViewport=full_page)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(answer["data"]))

    def html(self) -> str:
        """Return the serialised DOM (``document.documentElement.outerHTML``)."""
        return str(self.evaluate("document.documentElement.outerHTML"))

    def close(self) -> None:
        """Close the connection, kill Chromium's process group, remove its profile."""
        if self._socket is not None:
            self._socket.close()
            self._socket = None
        if self._process is not None:
            ui_browser.stop_group(self._process)
            self._process = None
        self._errors.close()
        self._profile.cleanup()


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text().split()
    except OSError:
        return []

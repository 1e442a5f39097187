"""Capture the Compare page with one artifact selected in its Artifacts file tree (CDP).

The Compare page lists the files common to the runs in a file tree and shows "Select a file to
preview" in each run's column until a file is clicked; which file is selected is React state,
not in the URL, so ``chromium --screenshot`` cannot show it. :func:`capture_selected` drives
Chromium through :class:`pipeline.tracking.cdp.Session`: it opens the page, waits for the tree,
closes the MLflow Assistant side panel (it takes a third of the width), clicks the tree entry
(``data-testid="artifact-tree-node"``, ``artifact-name=<path>``), waits until every run's
column shows the image loaded (``img`` with ``alt=<path>``, complete, natural width > 0),
scrolls it into view if needed, and takes the screenshot and the DOM.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from pipeline.tracking import cdp, rfc6455
from pipeline.tracking.ui_browser import BrowserError

TREE_NODES = "[...document.querySelectorAll('[data-testid=\"artifact-tree-node\"]')]"
NO_COMMON = "document.body.innerText.includes('No common artifacts to display')"
CLOSE_ASSISTANT = (
    "document.querySelector('[data-component-id=\"mlflow.assistant.chat_panel.close\"]')?.click()"
)
SETTLED = "!document.querySelector('[class*=\"skeleton\"]')"  # no loading placeholder left
SNAPSHOT = (
    "({html: document.documentElement.outerHTML, loaded: [...document.images]"
    ".filter(i => i.complete && i.naturalWidth > 0).map(i => i.src)})"
)


@dataclass
class Capture:
    """What the capture saw.

    Attributes
    ----------
    html : str
        The serialised DOM after the click.
    loaded : frozenset of str
        ``src`` of every image loaded (complete, natural width > 0) when the DOM was taken.
    notes : list of str
        What went wrong on the way (no tree entry, images not loaded in time), one line each.
    """

    html: str
    loaded: frozenset[str]
    notes: list[str] = field(default_factory=list)


def _node(path: str) -> str:
    name = json.dumps(path)
    return (
        f"{TREE_NODES}.find(n => n.getAttribute('artifact-name') === {name} "
        f"|| n.textContent.trim() === {name})"
    )


def _loaded(path: str) -> str:
    return (
        f"[...document.images].filter(i => i.alt === {json.dumps(path)} && i.complete "
        "&& i.naturalWidth > 0)"
    )


def _scroll_into_view(path: str) -> str:
    return (
        f"(() => {{ const last = {_loaded(path)}.pop(); "
        "if (last && last.getBoundingClientRect().bottom > innerHeight) "
        "last.scrollIntoView({block: 'end'}); })()"
    )


def _select(session: cdp.Session, path: str, count: int, timeout_s: float) -> list[str]:
    """Click ``path`` in the file tree and wait for ``count`` loaded images; return notes."""
    # The tree appears once every run's file list is in; "No common artifacts" shows until then.
    if not session.wait_for(f"{TREE_NODES}.length > 0", timeout_s):
        shows = "No common artifacts to display" if session.evaluate(NO_COMMON) else "nothing"
        return [f"the Artifacts file tree lists no file within {timeout_s:g} s (it shows: {shows})"]
    session.evaluate(CLOSE_ASSISTANT)
    if not session.evaluate(f"!!{_node(path)}"):
        listed = session.evaluate(f"{TREE_NODES}.map(n => n.textContent.trim()).join(', ')")
        return [f"the Artifacts file tree lists no {path} (it lists: {listed or 'nothing'})"]
    session.evaluate(f"{_node(path)}.click()")
    notes = []
    if not session.wait_for(f"{_loaded(path)}.length >= {count}", timeout_s):
        shown = session.evaluate(f"{_loaded(path)}.length")
        notes.append(
            f"after clicking {path} in the Artifacts file tree, {shown} of {count} run "
            f"columns showed the image loaded within {timeout_s:g} s"
        )
    session.wait_for(SETTLED, timeout_s)
    session.evaluate(_scroll_into_view(path))
    return notes


def capture_selected(
    chromium: str,
    url: str,
    path: str,
    count: int,
    screenshot: Path,
    window: tuple[int, int],
    timeout_s: float = 15.0,
) -> Capture:
    """Open the Compare page ``url``, select ``path`` in its file tree, capture the result.

    Parameters
    ----------
    chromium : str
        The Chromium executable.
    url : str
        The Compare page (``#/compare-runs?runs=[...]&experiments=[...]``).
    path : str
        The artifact to click in the Artifacts file tree, e.g. ``cross_season_rms.png``.
    count : int
        How many run columns must show it (the number of compared runs).
    screenshot : Path
        PNG file to write (its folder is created).
    window : tuple of int
        Viewport width and height, CSS px.
    timeout_s : float
        Longest wait for the page, for the tree and for the images, each, in seconds.

    Returns
    -------
    Capture
        The DOM, the loaded images and what went wrong on the way.

    Raises
    ------
    BrowserError
        If Chromium does not start, the DevTools connection fails or a command times out.
    """
    screenshot.unlink(missing_ok=True)
    try:
        with cdp.Session(chromium, window, timeout_s=max(timeout_s, 30.0)) as session:
            notes = [] if session.navigate(url, timeout_s) else [f"not loaded in {timeout_s:g} s"]
            notes += _select(session, path, count, timeout_s)
            session.screenshot(screenshot)
            snapshot = session.evaluate(SNAPSHOT)
    except (cdp.CdpError, rfc6455.WebSocketError, TimeoutError, OSError) as error:
        raise BrowserError(f"DevTools session on {url} failed: {error}") from None
    return Capture(str(snapshot["html"]), frozenset(snapshot["loaded"]), notes)

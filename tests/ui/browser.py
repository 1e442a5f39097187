"""Headless Chromium through Playwright: open a page of the MLflow UI, capture what it shows.

Playwright drives the Chromium installed on the machine (``executable_path``: ``$CHROMIUM``,
else ``chromium`` or ``chromium-browser`` on the ``PATH``) and never downloads a browser of its
own. :func:`launched` starts it once for the check, with one browser context (the pages share
its cache); :func:`render` opens one page in a new tab, waits until the page shows the texts it
must show (or the time allowed runs out), on Compare clicks the artifact in the Artifacts file
tree, writes the screenshot and returns the DOM with the images the browser had loaded.

Compare lists the files common to the runs in a file tree and shows "Select a file to preview"
in each run's column until a file is clicked: which file is selected is React state, not in the
URL. :func:`render` waits for the tree, closes the MLflow Assistant side panel (it takes a third
of the width), clicks the tree entry (``data-testid="artifact-tree-node"``,
``artifact-name=<path>``) and waits until every run's column shows the image loaded. Until a
file is selected the columns' "Select a file to preview" placeholders lie over the tree, so a
pointer click would land on them: the click is dispatched to the entry itself, as a person's
click on the visible entry would be.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from playwright.sync_api import BrowserContext, Locator, sync_playwright
from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import Page as BrowserPage
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from tests.ui.dom import PageDom, parse_dom
from tests.ui.pages import WINDOW_WIDTH, Page

ENV_CHROMIUM = "CHROMIUM"
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
LAUNCH_ARGS = ("--disable-gpu", "--disable-dev-shm-usage", "--hide-scrollbars")
"""Flags of the headless Chromium (no GPU on the machine, small ``/dev/shm`` in containers)."""

TREE_NODE = '[data-testid="artifact-tree-node"]'
CLOSE_ASSISTANT = '[data-component-id="mlflow.assistant.chat_panel.close"]'
SHOWS = """([texts, image]) => {
  const words = (s) => ' ' + (s.match(/[0-9A-Za-z]+/g) || []).join(' ') + ' ';
  const body = document.body ? document.body.innerText.replace(/\\s+/g, ' ') : '';
  const shown = ([text, exact]) => exact ? body.includes(text) : words(body).includes(words(text));
  const loaded = [...document.images].some((i) => i.alt === image && i.complete
    && i.naturalWidth > 0);
  return !document.querySelector('[class*="skeleton"]') && texts.every(shown)
    && (!image || loaded);
}"""
"""True when the page shows every ``[text, exact]`` (exact: as it is, else compared on letters and
digits, as :func:`tests.ui.pages.check_page` does) and the image loaded, with no loading
placeholder left."""
LOADED = """(alt) => [...document.images].filter((i) => i.alt === alt && i.complete
  && i.naturalWidth > 0).length"""
"""How many images ``alt=<path>`` the browser has loaded (complete, natural width > 0)."""
SNAPSHOT = """() => ({html: document.documentElement.outerHTML, loaded: [...document.images]
  .filter((i) => i.complete && i.naturalWidth > 0).map((i) => i.src)})"""


class BrowserError(RuntimeError):
    """Chromium did not start or did not render a page."""


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


@contextmanager
def launched(chromium: str) -> Iterator[BrowserContext]:
    """Run headless ``chromium`` under Playwright until the ``with`` block ends.

    Yields
    ------
    playwright.sync_api.BrowserContext
        One context (cookies, storage, cache) for every page of the check.

    Raises
    ------
    BrowserError
        If Chromium does not start.
    """
    with sync_playwright() as playwright:
        try:
            browser = playwright.chromium.launch(executable_path=chromium, args=list(LAUNCH_ARGS))
        except PlaywrightError as error:
            raise BrowserError(f"{chromium} did not start: {_first_line(error)}") from None
        try:
            yield browser.new_context()
        finally:
            browser.close()


def _first_line(error: PlaywrightError) -> str:
    """The message of a Playwright error without its call log."""
    return error.message.strip().splitlines()[0]


def _wait(tab: BrowserPage, script: str, arg: object, timeout_ms: float) -> bool:
    """Wait until ``script(arg)`` is true in the page; return False if ``timeout_ms`` passed."""
    try:
        tab.wait_for_function(script, arg=arg, timeout=max(timeout_ms, 1), polling=250)
    except PlaywrightError:
        return False
    return True


def _tree_entry(tab: BrowserPage, path: str) -> Locator:
    """The Artifacts file tree's entry of ``path`` (by its ``artifact-name``, else its text)."""
    nodes = tab.locator(TREE_NODE)
    named = tab.locator(f"{TREE_NODE}[artifact-name={json.dumps(path)}]")
    return named.or_(nodes.filter(has_text=re.compile(rf"^\s*{re.escape(path)}\s*$"))).first


def select_artifact(tab: BrowserPage, path: str, count: int, timeout_ms: float) -> list[str]:
    """Click ``path`` in Compare's file tree; wait for ``count`` loaded images; return notes.

    The tree appears once every run's file list is in ("No common artifacts to display" shows
    until then, and for good when the runs share no file).
    """
    seconds = f"{timeout_ms / 1000:g} s"
    try:
        tab.locator(TREE_NODE).first.wait_for(timeout=timeout_ms)
    except PlaywrightError:
        shown = tab.get_by_text("No common artifacts to display").count()
        shows = "No common artifacts to display" if shown else "nothing"
        return [f"the Artifacts file tree lists no file within {seconds} (it shows: {shows})"]
    close = tab.locator(CLOSE_ASSISTANT)
    if close.count():
        close.first.click()
    entry = _tree_entry(tab, path)
    if not entry.count():
        listed = ", ".join(text.strip() for text in tab.locator(TREE_NODE).all_inner_texts())
        return [f"the Artifacts file tree lists no {path} (it lists: {listed or 'nothing'})"]
    entry.dispatch_event("click")
    notes = []
    if not _wait(tab, f"([alt, count]) => ({LOADED})(alt) >= count", [path, count], timeout_ms):
        shown = tab.evaluate(LOADED, path)
        notes.append(
            f"after clicking {path} in the Artifacts file tree, {shown} of {count} run "
            f"columns showed the image loaded within {seconds}"
        )
    images = tab.locator(f"img[alt={json.dumps(path)}]")
    if images.count():
        images.last.scroll_into_view_if_needed()
    return notes


def _open(tab: BrowserPage, page: Page, timeout_ms: float) -> list[str]:
    """Load ``page.url``; wait until it shows its required texts and image; return notes."""
    try:
        tab.goto(page.url, wait_until="load", timeout=timeout_ms)
    except PlaywrightTimeout:
        return [f"not loaded in {timeout_ms / 1000:g} s"]
    texts = [[check.text, check.exact] for check in page.checks if check.required]
    _wait(tab, SHOWS, [texts, None if page.select else page.image], timeout_ms)
    return []


def render(
    context: BrowserContext, page: Page, screenshot: Path, timeout_ms: float
) -> tuple[PageDom, list[str]]:
    """Open ``page`` in a new tab, write its screenshot, return what it shows.

    Parameters
    ----------
    context : playwright.sync_api.BrowserContext
        The running Chromium's context (:func:`launched`).
    page : Page
        The page, its window height, the texts it must show and the artifact to click, if any.
    screenshot : Path
        PNG file to write (its folder is created).
    timeout_ms : float
        Longest wait for the page to load, for its texts and, on Compare, for the file tree
        and for the images, each, in ms.

    Returns
    -------
    PageDom
        The rendered DOM and the images loaded when it was taken.
    list of str
        What went wrong on the way (not loaded in time, no tree entry, images not loaded).

    Raises
    ------
    BrowserError
        If the page could not be opened or captured.
    """
    screenshot.parent.mkdir(parents=True, exist_ok=True)
    screenshot.unlink(missing_ok=True)
    try:
        tab = context.new_page()
    except PlaywrightError as error:
        raise BrowserError(_first_line(error)) from None
    try:
        tab.set_default_timeout(timeout_ms)
        tab.set_viewport_size({"width": WINDOW_WIDTH, "height": page.height})
        notes = _open(tab, page, timeout_ms)
        if page.select is not None and not notes:
            notes += select_artifact(tab, page.select, page.image_count, timeout_ms)
            _wait(tab, SHOWS, [[], None], timeout_ms)  # no loading placeholder left
        tab.screenshot(path=str(screenshot))
        snapshot = tab.evaluate(SNAPSHOT)
    except PlaywrightError as error:
        raise BrowserError(_first_line(error)) from None
    finally:
        tab.close()
    dom = parse_dom(str(snapshot["html"]))
    dom.loaded = frozenset(snapshot["loaded"])
    return dom, notes

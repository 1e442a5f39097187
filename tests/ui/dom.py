"""Read a page of the MLflow UI from the DOM Chromium rendered (pure: strings in, data out).

The browser (:mod:`tests.ui.browser`) serialises the document after the React app ran.
:func:`parse_dom` keeps what the UI check looks at: the text nodes of the body (scripts,
styles, ``noscript`` and SVG left out), the error banners the UI draws (Ant/Du Bois alerts,
messages, notifications and result pages of type error/404/500), the images (``alt``, ``src``)
and, in a run table, which run each row shows in which position (``row-index``).
:func:`error_phrases` finds the exact phrases the UI uses to say that something failed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from html.parser import HTMLParser

SKIPPED_ELEMENTS = frozenset({"script", "style", "noscript", "svg", "head", "template"})
VOID_ELEMENTS = frozenset(
    {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "wbr"}
)
ERROR_CLASS = re.compile(
    r"(?:^|[\s-])(?:alert|message|notification-notice|result)-(?:error|404|500|403)(?:\s|$)"
)
RUN_LINK = re.compile(r"#/experiments/[^/?#]+/runs/([0-9a-f]{32})(?:[/?]|$)")
# Phrases of the MLflow UI (3.x) and of its API errors that mean a page did not load what it
# should; matched case-insensitively on the page text. Bare words ("Error", "404") are not
# enough: the experiment is called thermal-error and scores can read 0.404.
ERROR_PATTERNS = (
    r"something went wrong",
    r"(?:experiment|run|model|model version|resource|page|artifact)s? (?:was )?not found",
    r"requested (?:experiment|resource) (?:was not found|does not exist)",
    r"model \S+ does not exist",
    r"run (?:with id=)?'?[0-9a-f]{32}'? not found",
    r"failed to (?:fetch|load)",
    r"request failed",
    r"\b(?:load|request) error\b",
    r"\bno (?:experiment|run|registered model|model version)s? with (?:id|name)=\S+ exists",
    r"invalid clause",
    r"(?:loading artifact|image) failed",
    r"error (?:while )?loading",
    r"\b404\b\s*[:\-]|\berror 404\b|\b404 not found\b",
    r"\b(?:RESOURCE_DOES_NOT_EXIST|INTERNAL_ERROR|INVALID_PARAMETER_VALUE|BAD_REQUEST)\b",
)
_ERROR_RE = re.compile("|".join(f"(?:{pattern})" for pattern in ERROR_PATTERNS), re.IGNORECASE)
_SPACES = re.compile(r"\s+")


def normalise(text: str) -> str:
    """Collapse every run of whitespace (no-break spaces included) to one space and strip."""
    return _SPACES.sub(" ", text).strip()


@dataclass
class PageDom:
    """What a rendered page shows.

    Attributes
    ----------
    nodes : list of str
        The text nodes of the body in document order, whitespace-normalised, empty ones left out.
    banners : list of str
        The text of each error banner (alert, message, notification or result of type error).
    images : list of tuple of str
        ``(alt, src)`` of every ``img`` element.
    rows : dict of int to list of str
        Run ids linked from each table row, by the row's ``row-index`` (its position on screen).
    loaded : frozenset of str or None
        ``src`` of the images the browser had loaded (complete, natural width > 0) when the DOM
        was taken; None when unknown (a DOM parsed from its text alone).
    """

    nodes: list[str] = field(default_factory=list)
    banners: list[str] = field(default_factory=list)
    images: list[tuple[str, str]] = field(default_factory=list)
    rows: dict[int, list[str]] = field(default_factory=dict)
    loaded: frozenset[str] | None = None

    @property
    def text(self) -> str:
        """The page text: every text node, joined by single spaces."""
        return " ".join(self.nodes)

    def run_order(self) -> list[str]:
        """Run ids in the order of the table rows that link them (first link per row)."""
        return [ids[0] for _, ids in sorted(self.rows.items()) if ids]


class _DomReader(HTMLParser):
    """Collect :class:`PageDom` while parsing; tracks the open elements on a stack."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.dom = PageDom()
        # One entry per open element: (tag, skipped, banner index or None, row index or None).
        self._stack: list[tuple[str, bool, int | None, int | None]] = []

    def _skipping(self) -> bool:
        return bool(self._stack) and self._stack[-1][1]

    def _banner(self) -> int | None:
        return self._stack[-1][2] if self._stack else None

    def _row(self) -> int | None:
        return self._stack[-1][3] if self._stack else None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = {name: value or "" for name, value in attrs}
        if tag == "img":
            self.dom.images.append((values.get("alt", ""), values.get("src", "")))
        row = self._row()
        if values.get("row-index", "").isdigit():
            row = int(values["row-index"])
        if tag == "a" and row is not None and not self._skipping():
            match = RUN_LINK.search(values.get("href", ""))
            if match and match.group(1) not in self.dom.rows.setdefault(row, []):
                self.dom.rows[row].append(match.group(1))
        if tag in VOID_ELEMENTS:
            return
        banner = self._banner()
        if banner is None and ERROR_CLASS.search(values.get("class", "")):
            self.dom.banners.append("")
            banner = len(self.dom.banners) - 1
        skipped = self._skipping() or tag in SKIPPED_ELEMENTS
        self._stack.append((tag, skipped, banner, row))

    def handle_endtag(self, tag: str) -> None:
        for depth in range(len(self._stack) - 1, -1, -1):
            if self._stack[depth][0] == tag:
                del self._stack[depth:]
                return

    def handle_data(self, data: str) -> None:
        text = normalise(data)
        if not text or self._skipping():
            return
        self.dom.nodes.append(text)
        banner = self._banner()
        if banner is not None:
            self.dom.banners[banner] = normalise(f"{self.dom.banners[banner]} {text}")


def parse_dom(html: str) -> PageDom:
    """Parse the DOM Chromium rendered (``document.documentElement.outerHTML``).

    Parameters
    ----------
    html : str
        The serialised document.

    Returns
    -------
    PageDom
        Text nodes, error banners, images and table rows of the page.
    """
    reader = _DomReader()
    reader.feed(html)
    reader.close()
    return reader.dom


def error_phrases(text: str) -> list[str]:
    """Return the error phrases of the MLflow UI found in ``text``, each once, in page order.

    Parameters
    ----------
    text : str
        A page's text (see :attr:`PageDom.text`).

    Returns
    -------
    list of str
        The phrases as they appear on the page, e.g. ``["Experiment not found"]``.
    """
    found: list[str] = []
    for match in _ERROR_RE.finditer(text):
        phrase = match.group(0).strip(" :-")
        if phrase.lower() not in {seen.lower() for seen in found}:
            found.append(phrase)
    return found

"""Warnings of library code counted, not printed: per fit, per candidate, one line per stage.

statsmodels, scikit-learn, numpy and pandas warn about fits on short or near-singular data
(``SingularMatrixWarning``, ``ConvergenceWarning``, ``RuntimeWarning``...); printed as they come,
hundreds of them bury what a stage says. :func:`captured` records the warnings of a block of
code into a :class:`WarningCounts` -- how many of each category and the first message. Around
one fit (``fit=True``) the counts travel with the fit's result to the comparison report and
MLflow; when the block ends they are also added to the capture around it, and
:func:`pipeline.progress.run_jobs` hands the counts of each joblib job back from its worker
process (:func:`absorb`), where the main process' capture does not reach. So the capture
:func:`summarise_warnings` opens around a stage's ``main`` sees every warning of the stage once,
and logs one line when the stage ends.

Every occurrence is counted (the ``default``, ``module`` and ``once`` actions count each one);
warnings ignored by the filters in force (Python's defaults ignore ``DeprecationWarning`` outside
``__main__``) stay ignored and an ``error`` filter still raises.
"""

from __future__ import annotations

import functools
import logging
import warnings
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

COUNTED_ACTIONS = frozenset({"default", "module", "once"})
"""Filter actions that show a warning once per place; while capturing, each occurrence counts."""


@dataclass
class WarningCounts:
    """Warnings captured in a block of code (a fit, a joblib job, a stage), by category.

    Attributes
    ----------
    by_category : dict of str to int
        Category name (``SingularMatrixWarning``) -> number of warnings.
    first : dict of str to str
        Category name -> its first message, with the file and line that emitted it.
    fits : int
        Fits counted in (captures opened with ``fit=True``).
    fits_warned : int
        Of those, the ones that emitted at least one warning.
    """

    by_category: dict[str, int] = field(default_factory=dict)
    first: dict[str, str] = field(default_factory=dict)
    fits: int = 0
    fits_warned: int = 0

    @property
    def total(self) -> int:
        """Number of warnings."""
        return sum(self.by_category.values())

    def record(self, caught: Iterable[warnings.WarningMessage]) -> None:
        """Count warnings recorded by :class:`warnings.catch_warnings`."""
        for item in caught:
            name = item.category.__name__
            self.by_category[name] = self.by_category.get(name, 0) + 1
            where = f"{Path(item.filename).name}:{item.lineno}"
            self.first.setdefault(name, f"{item.message} ({where})")

    def add(self, other: WarningCounts) -> None:
        """Count in the warnings and fits of ``other``."""
        for name, number in other.by_category.items():
            self.by_category[name] = self.by_category.get(name, 0) + number
        for name, message in other.first.items():
            self.first.setdefault(name, message)
        self.fits += other.fits
        self.fits_warned += other.fits_warned

    def categories(self) -> str:
        """Return the categories, most frequent first: ``ValueWarning 2, ConvergenceWarning 1``."""
        ranked = sorted(self.by_category.items(), key=lambda item: (-item[1], item[0]))
        return ", ".join(f"{name} {number}" for name, number in ranked)

    def text(self) -> str:
        """Return the count and its categories: ``3 (ValueWarning 2, ConvergenceWarning 1)``."""
        return f"{self.total} ({self.categories()})" if self.total else "0"

    def to_dict(self) -> dict:
        """JSON-ready: ``{"by_category": {...}, "first": {...}}`` (the fit counts left out)."""
        return {"by_category": dict(self.by_category), "first": dict(self.first)}

    @classmethod
    def from_dict(cls, data: dict | None) -> WarningCounts:
        """Read :meth:`to_dict`'s form (None or empty: no warning); one fit."""
        data = data or {}
        counts = cls(
            {str(k): int(v) for k, v in (data.get("by_category") or {}).items()},
            {str(k): str(v) for k, v in (data.get("first") or {}).items()},
        )
        counts.fits, counts.fits_warned = 1, int(counts.total > 0)
        return counts


def _count_every_occurrence() -> None:
    """Turn the filters in force into their counting form (inside ``catch_warnings``).

    ``catch_warnings`` works on a copy of the filter list and restores the original on exit.
    """
    warnings.filters[:] = [
        ("always", *item[1:]) if item[0] in COUNTED_ACTIONS else item for item in warnings.filters
    ]
    # what no filter names takes the default action; adding a filter also makes the module
    # drop what it cached of the old list
    warnings.simplefilter("always", append=True)


_OPEN: list[WarningCounts] = []
"""The captures open in this process, innermost last."""


@contextmanager
def captured(fit: bool = False, propagate: bool = True) -> Iterator[WarningCounts]:
    """Record the warnings of the block instead of printing them, and count them.

    Not thread-safe (nor is :class:`warnings.catch_warnings`): open it in the process or
    worker that runs the code and hand the counts back with the result (:func:`absorb`).

    Parameters
    ----------
    fit : bool
        The block is one fit: it counts in ``fits`` (and ``fits_warned``).
    propagate : bool
        When the block ends, add its counts to the capture around it in this process.

    Yields
    ------
    WarningCounts
        Filled when the block ends (also when it raises).
    """
    counts = WarningCounts(fits=int(fit))
    _OPEN.append(counts)
    try:
        with warnings.catch_warnings(record=True) as caught:
            _count_every_occurrence()
            try:
                yield counts
            finally:
                counts.record(caught)
                if fit:
                    counts.fits_warned = int(counts.total > 0)
    finally:
        _OPEN.pop()
        if propagate:
            absorb(counts)


def absorb(counts: WarningCounts) -> None:
    """Add counts captured elsewhere (a worker process) to the innermost open capture, if any."""
    if _OPEN:
        _OPEN[-1].add(counts)


def summary_line(counts: WarningCounts, details: str = "") -> str:
    """Return one line on a stage's warnings.

    Parameters
    ----------
    counts : WarningCounts
        Everything the stage's processes emitted, its fits' included.
    details : str
        Where the per-candidate counts are, if anywhere.

    Returns
    -------
    str
        E.g. ``412 warnings captured (SingularMatrixWarning 380, ConvergenceWarning 32); 37 of
        480 fits warned, per candidate in reports/model_comparison.md``.
    """
    fits = f"{counts.fits_warned} of {counts.fits} fits warned" if counts.fits else ""
    if not counts.total:
        return f"no warnings ({counts.fits} fits)" if counts.fits else "no warnings"
    line = f"{counts.total} warnings captured ({counts.categories()})"
    if fits and details and counts.fits_warned:
        return f"{line}; {fits}, per candidate in {details}"
    return f"{line}; {fits}" if fits else line


def summarise_warnings(details: str = "") -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a stage's ``main``: capture its warnings and log one summary line at its end.

    The line goes to the logger of the stage's module at INFO; each category's first message
    at DEBUG. Fits captured inside it (:func:`captured` with ``fit=True``, in this process or
    handed back from workers by :func:`pipeline.progress.run_jobs`) count in it.

    Parameters
    ----------
    details : str
        Where the stage writes per-candidate counts (e.g. ``reports/model_comparison.md``).
    """

    def decorate(main: Callable[..., int]) -> Callable[..., int]:
        logger = logging.getLogger(main.__module__)

        @functools.wraps(main)
        def wrapped(*args, **kwargs) -> int:
            counts, succeeded = WarningCounts(), False
            try:
                with captured() as counts:
                    status = main(*args, **kwargs)
                    succeeded = status in (0, None)
                    return status
            finally:  # the block has ended: its warnings are counted
                if counts.total or succeeded:  # a failed stage without warnings: its error says it
                    logger.info("%s", summary_line(counts, details))
                for name, message in counts.first.items():
                    logger.debug("first %s: %s", name, message)

        return wrapped

    return decorate

"""How far a long loop is: a bar on a terminal, a plain line now and then in a log.

On a terminal (standard error is a TTY) :class:`Progress` draws a ``tqdm`` bar; in CI logs and
under ``dvc repro``, which captures the output, it logs plain lines instead, each time another
tenth of the work is done or half a minute has passed, e.g. ``axis Z candidates: 120/480 fits
(25 %), 1 min 40 s``. A loop done within :data:`QUIET_FOR_S` logs nothing, so short loops do
not fill the log. :func:`run_jobs` runs joblib jobs with it, each job's warnings captured in
its worker and counted in the main process (:mod:`pipeline.warnings_capture`); a short loop runs
in the stage's own process (see :data:`SERIAL_UNDER_S`).
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterable
from typing import IO, Any

from joblib import Parallel, delayed
from tqdm import tqdm

from pipeline import cluster
from pipeline.warnings_capture import WarningCounts, absorb, captured

LOGGER = logging.getLogger(__name__)

LINE_EVERY_SHARE = 0.1
"""A plain line each time another such share of the work is done..."""
LINE_EVERY_S = 30.0
"""...or this many seconds passed since the last line."""
QUIET_FOR_S = 30.0
"""No line (nor the final one) before the loop has run this many seconds."""
SERIAL_UNDER_S = 15.0
"""Jobs run one after the other in this process while the rest of them is projected (from the
mean time of those done) to take less than this many seconds; then the rest goes to the worker
processes. Starting the workers costs seconds of every core (each imports the model libraries
again), more than they save on a short loop; a long one pays that once."""


def duration_text(seconds: float) -> str:
    """Return a duration as people read it: ``12 s``, ``1 min 40 s``, ``2 h 05 min``."""
    whole = int(round(seconds))
    if whole < 60:
        return f"{whole} s"
    if whole < 3600:
        return f"{whole // 60} min {whole % 60:02d} s"
    return f"{whole // 3600} h {whole % 3600 // 60:02d} min"


class Progress:
    """Count the items of a long loop as they are done and show how far it is.

    Parameters
    ----------
    label : str
        What is counted, e.g. ``axis Z candidates``.
    total : int
        Number of items.
    unit : str
        Their name, plural (``fits``).
    logger : logging.Logger, optional
        Where the plain lines go (this module's logger by default).
    stream : file, optional
        Where a bar would be drawn: ``sys.stderr`` by default; a bar only if it is a TTY.
    clock : callable, optional
        Seconds (``time.monotonic``); tests pass their own.
    """

    def __init__(
        self,
        label: str,
        total: int,
        unit: str = "fits",
        *,
        logger: logging.Logger | None = None,
        stream: IO[str] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.label, self.total, self.unit = label, int(total), unit
        self.logger = logger or LOGGER
        self.clock = clock
        self.done = 0
        self.start = self.last_time = clock()
        self.last_done = 0
        stream = sys.stderr if stream is None else stream
        is_terminal = getattr(stream, "isatty", lambda: False)()
        self.bar = (
            tqdm(total=self.total, desc=label, unit=f" {unit}", file=stream, leave=False)
            if is_terminal and self.total
            else None
        )

    def line(self) -> str:
        """Return the plain line: ``label: done/total unit (share %), elapsed``."""
        share = 100.0 * self.done / self.total if self.total else 100.0
        elapsed = duration_text(self.clock() - self.start)
        return f"{self.label}: {self.done}/{self.total} {self.unit} ({share:.0f} %), {elapsed}"

    def update(self, n: int = 1) -> None:
        """Count ``n`` more items done."""
        self.done += n
        if self.bar is not None:
            self.bar.update(n)
            return
        now = self.clock()
        if now - self.start < QUIET_FOR_S:
            return
        finished = self.done >= self.total
        if finished or self._share_step() or now - self.last_time >= LINE_EVERY_S:
            self.logger.info("%s", self.line())
            self.last_done, self.last_time = self.done, now

    def _share_step(self) -> bool:
        """Whether another :data:`LINE_EVERY_SHARE` of the work is done since the last line."""
        steps = round(1 / LINE_EVERY_SHARE)
        return steps * self.done // self.total > steps * self.last_done // self.total

    def close(self) -> None:
        """End the bar and log the final line (the plain lines end with the last item)."""
        if self.bar is not None:
            self.bar.close()
            if self.clock() - self.start >= QUIET_FOR_S:
                self.logger.info("%s", self.line())

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_WORKERS = {"started": False}
"""Whether this process has started joblib's worker processes (they stay for the next call)."""


def run_jobs(
    jobs: Iterable[Any],
    n_jobs: int,
    label: str,
    unit: str = "fits",
    logger: logging.Logger | None = None,
) -> list:
    """Run joblib ``delayed`` jobs in up to ``n_jobs`` processes and show how far they are.

    The jobs start in this process, one after the other; once the rest of them is projected to
    take :data:`SERIAL_UNDER_S` or more, the rest runs in ``n_jobs`` worker processes (at once,
    when an earlier call of this process started them). Where a Dask cluster is named
    (:mod:`pipeline.cluster`), every job of a loop with ``n_jobs`` > 1 runs on its workers,
    which stay up from one stage to the next. Each job's warnings are captured where
    it runs and added to the capture open here (:func:`pipeline.warnings_capture.absorb`), so
    none is printed from a worker.

    Parameters
    ----------
    jobs : iterable of tuple
        ``joblib.delayed(function)(*args, **kwargs)`` calls.
    n_jobs : int
        Worker processes at most (a Dask cluster uses all its workers); 1 runs every job in
        this process.
    label, unit : str
        What :class:`Progress` shows.
    logger : logging.Logger, optional
        Where its plain lines go.

    Returns
    -------
    list
        The jobs' results, in the order of ``jobs``.
    """
    jobs = list(jobs)
    results: list = []
    with Progress(label, len(jobs), unit, logger=logger) as progress:
        started = time.monotonic()
        while len(results) < len(jobs):
            if _workers_pay(n_jobs, started, len(results), len(jobs)):
                break
            function, args, kwargs = jobs[len(results)]
            result, counts = _call_captured(function, args, kwargs)
            absorb(counts)
            results.append(result)
            progress.update()
        rest = [delayed(_call_captured)(f, a, k) for f, a, k in jobs[len(results) :]]
        if rest:
            _WORKERS["started"] = True
            with cluster.backend():
                for result, counts in Parallel(n_jobs=n_jobs, return_as="generator")(rest):
                    absorb(counts)
                    results.append(result)
                    progress.update()
    return results


def _workers_pay(n_jobs: int, started: float, done: int, total: int) -> bool:
    """Whether the rest of the jobs should go to the worker processes (see :func:`run_jobs`)."""
    if n_jobs == 1:
        return False
    if _WORKERS["started"] or cluster.scheduler_address() is not None:
        return True
    projected = (time.monotonic() - started) / done * (total - done) if done else 0.0
    return projected >= SERIAL_UNDER_S


def _call_captured(function: Callable, args: tuple, kwargs: dict) -> tuple[Any, WarningCounts]:
    """Run one job (in a worker or in this process); return its result and its warnings."""
    with captured(propagate=False) as counts:
        result = function(*args, **kwargs)
    return result, counts

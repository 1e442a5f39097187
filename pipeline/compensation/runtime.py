"""The compensation runtime: read a source, compute each axis' offset, write it to a sink.

One *cycle* per new reading of the source (a file row, an OPC UA time-node change): the
reading is checked (:mod:`pipeline.compensation.guard`), appended to the run's history, and
each axis' offset is computed (:class:`pipeline.compensation.axis.AxisCompensator`) and written,
all axes in one write. When no reading arrives for ``stall_s`` of wall-clock time (or the
source fails: a lost connection is logged and retried at the next poll) the source is
*stalled*: each axis holds its last good offset, then decays it to zero, one write per
``cycle_s``. A write the sink refuses is retried ``write_retries`` times, then reported; the
axes keep the offset last written. Every write, every change of mode (fallback, hold, decay,
recovery), every bad input, stall, new run and refused write is an event of the log
(JSON lines, :class:`EventLog`).

A *run* starts at the first reading and again whenever the source's run label changes or its
time goes backwards (the machine was restarted): rises and speed responses start afresh from
its first reading, as in training.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from pipeline.compensation.axis import AxisCompensator, AxisStep
from pipeline.compensation.bundle import AxisBundle
from pipeline.compensation.guard import RPM, bad_inputs
from pipeline.settings.compensation import CompensationSettings

LOGGER = logging.getLogger(__name__)


@dataclass(frozen=True)
class Reading:
    """One sample of the machine's inputs.

    Attributes
    ----------
    t_s : float, s
        Machine time (seconds since the source's epoch; only differences matter).
    values : dict of str to float
        Sensor -> degC, ``rpm`` -> spindle speed; an input absent or NaN is missing.
    run : str or None
        The run label (e.g. a file's ``campaign_id``); a change starts a new run.
    """

    t_s: float
    values: dict[str, float]
    run: str | None = None


class Source(Protocol):
    """Where readings come from."""

    def poll(self, timeout_s: float) -> list[Reading]:
        """Return the readings since the last poll, waiting up to ``timeout_s`` for one."""

    @property
    def exhausted(self) -> bool:
        """True when no reading will ever come again (a replayed table, a file not followed)."""

    def close(self) -> None:
        """Release the connection or file."""


class Sink(Protocol):
    """Where offsets go."""

    def write(self, t_s: float, offsets: Mapping[str, float]) -> None:
        """Write every axis' offset (um) of the cycle at machine time ``t_s``; raise if refused."""

    def close(self) -> None:
        """Release the connection or file."""


class EventLog:
    """JSON-lines log of the runtime's events (and the Python log at INFO/WARNING).

    Parameters
    ----------
    path : Path or None
        File appended to; None keeps the events in memory only (``events``).
    echo : bool
        Also write them to the Python log (a replay keeps quiet).
    """

    def __init__(self, path: Path | None = None, echo: bool = True) -> None:
        self.path = None if path is None else Path(path)
        self.echo = echo
        self.events: list[dict] = []
        self._file = None
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("a", encoding="utf-8")

    def record(self, event: str, t_s: float | None, warn: bool = False, **details) -> None:
        """Log one event at machine time ``t_s``."""
        entry = {"event": event, "t_s": t_s, "wall_time": time.time(), **details}
        self.events.append(entry)
        if self._file is not None:
            self._file.write(json.dumps(entry, default=_plain) + "\n")
            self._file.flush()
        if self.echo and (warn or event != "write"):
            (LOGGER.warning if warn else LOGGER.info)("%s %s", event, details)

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


def _plain(value):
    if isinstance(value, float | np.floating):
        return None if not math.isfinite(value) else float(value)
    return str(value)


class RunHistory:
    """The current run's readings (raw) and, per axis, which cells were bad.

    Rows are kept in a growing array (doubled when full), so a cycle costs one pass over the
    run, not one Python operation per past sample.
    """

    def __init__(self, sensors: list[str], axes: list[str]) -> None:
        self.columns = ["elapsed_s", RPM, *sensors]
        self.axes = axes
        self.reset(None, None)

    def reset(self, run: str | None, t0_s: float | None) -> None:
        """Start a new run."""
        self.run, self.t0_s = run, t0_s
        self.n = 0
        self._values = np.empty((64, len(self.columns)))
        self._bad = {axis: np.zeros((64, len(self.columns)), dtype=bool) for axis in self.axes}

    @property
    def last_elapsed_s(self) -> float:
        """Time of the newest reading since the run's first, s."""
        return float(self._values[self.n - 1, 0])

    def append(self, reading: Reading) -> None:
        """Append one reading (its time counted from the run's first reading)."""
        if self.t0_s is None:
            self.t0_s = reading.t_s
        if self.n == len(self._values):
            self._values = np.vstack([self._values, np.empty_like(self._values)])
            self._bad = {a: np.vstack([m, np.zeros_like(m)]) for a, m in self._bad.items()}
        values = [_number(reading.values.get(name)) for name in self.columns[1:]]
        self._values[self.n] = [reading.t_s - self.t0_s, *values]
        self.n += 1

    def mark_bad(self, axis: str, names: set[str]) -> None:
        """Mark inputs of the newest reading bad for ``axis``."""
        for name in names:
            self._bad[axis][self.n - 1, self.columns.index(name)] = True

    def columns_now(self) -> dict[str, np.ndarray]:
        """Return the run's readings as read, one array (a view, not a copy) per column."""
        return {name: self._values[: self.n, j] for j, name in enumerate(self.columns)}

    def clean(self, axis: str) -> dict[str, np.ndarray]:
        """Return the run's readings, one array per column, every cell bad for ``axis`` NaN."""
        values = self._values[: self.n]
        bad = self._bad[axis][: self.n]
        if bad.any():
            values = np.where(bad, np.nan, values)
        return {name: values[:, j] for j, name in enumerate(self.columns)}


def _number(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


@dataclass
class RuntimeCounts:
    """What a runtime did: cycles, writes, refusals, per-axis modes."""

    cycles: int = 0
    writes: int = 0
    refused: int = 0
    failed: int = 0
    stalls: int = 0
    source_errors: int = 0
    modes: dict[str, dict[str, int]] = field(default_factory=dict)


class CompensationRuntime:
    """The cycle loop between a source and a sink (see the module docstring).

    Parameters
    ----------
    bundles : list of AxisBundle
    settings : CompensationSettings
    source : Source
    sink : Sink
    log : EventLog
    clock : callable, optional
        Wall clock in s (``time.monotonic``); replaced in tests.
    sleep : callable, optional
        ``time.sleep``; replaced in tests.
    """

    def __init__(
        self,
        bundles: list[AxisBundle],
        settings: CompensationSettings,
        source: Source,
        sink: Sink,
        log: EventLog,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.bundles = {b.axis: b for b in bundles}
        self.axes = {b.axis: AxisCompensator(b, settings) for b in bundles}
        sensors = list(dict.fromkeys(s for b in bundles for s in b.sensors))
        self.history = RunHistory(sensors, list(self.axes))
        self.settings, self.source, self.sink, self.log = settings, source, sink, log
        self.clock, self.sleep = clock, sleep
        self.counts = RuntimeCounts(modes={axis: {} for axis in self.axes})
        self.steps: list[AxisStep] = []
        self._last_reading_wall: float | None = None
        self._last_t_s: float | None = None
        self._last_reading_t_s: float | None = None
        self._bad: dict[str, dict[str, str]] = {axis: {} for axis in self.axes}
        self._modes: dict[str, str] = {}

    def run(self, max_cycles: int | None = None) -> None:
        """Cycle until the source is exhausted or ``max_cycles``; a stop is the source's to raise.

        The ``stop`` event is logged however the loop ends.
        """
        self.log.record("start", None, axes=sorted(self.axes), settings=self.settings.model_dump())
        try:
            while max_cycles is None or self.counts.cycles < max_cycles:
                readings = self._poll()
                for reading in readings:
                    self.cycle([reading])
                if readings:
                    continue
                if self.source.exhausted:
                    break
                self.check_stall()
        finally:
            self.log.record("stop", self._last_t_s, counts=asdict(self.counts))

    def _poll(self) -> list[Reading]:
        """Return the source's readings; a source that fails is logged and counts as silent."""
        try:
            return self.source.poll(self.settings.cycle_s)
        except Exception as error:  # a lost connection must not stop the runtime: it stalls
            self.counts.source_errors += 1
            self.log.record("source_error", self._last_reading_t_s, warn=True, error=repr(error))
            self.sleep(self.settings.retry_wait_s)
            return []

    def warm_up(self, readings: list[Reading]) -> None:
        """Take readings of the run's past into the history without predicting or writing.

        What a runtime started in the middle of a run reads first: the run's earlier samples
        are checked and kept (rises and speed responses count from the run's start), and the
        first cycle after them may move each axis' offset as far as the time they span allows.
        """
        for reading in readings:
            self._take(reading)
        if readings:
            for compensator in self.axes.values():
                compensator.last_t_s = readings[0].t_s

    def cycle(self, readings: list[Reading]) -> list[AxisStep]:
        """One cycle: take the readings, compute and write every axis' offset."""
        for reading in readings:
            self._take(reading)
        self._last_reading_wall = self.clock()
        t_s = self._last_reading_t_s = readings[-1].t_s
        steps = [
            compensator.step(self.history.clean(axis), self._bad[axis], t_s)
            for axis, compensator in self.axes.items()
        ]
        return self._write(t_s, steps)

    def check_stall(self) -> list[AxisStep]:
        """Hold and decay every axis when no reading came for ``stall_s`` (one write per call)."""
        if self._last_reading_wall is None or self._last_reading_t_s is None:
            return []
        waited = self.clock() - self._last_reading_wall
        if waited < self.settings.stall_s:
            return []
        self.counts.stalls += 1
        t_s = self._last_reading_t_s + waited
        why = f"source stalled: no reading for {waited:.0f} s"
        return self._write(t_s, [axis.hold(t_s, why) for axis in self.axes.values()])

    def _take(self, reading: Reading) -> None:
        history = self.history
        if (
            not history.n
            or reading.run != history.run
            or reading.t_s < history.t0_s + history.last_elapsed_s
        ):
            if history.n:
                self.log.record("new_run", reading.t_s, run=reading.run, previous=history.run)
            history.reset(reading.run, reading.t_s)
        history.append(reading)
        columns = history.columns_now()
        for axis, bundle in self.bundles.items():
            spec = bundle.champion.spec
            bad = bad_inputs(
                columns,
                bundle.sensors,
                bundle.checks,
                ranges=bundle.input_ranges,
                features=spec.features,
                reference=(spec.reference, spec.reference_n),
                needs_speed=bundle.needs_speed,
            )
            history.mark_bad(axis, set(bad) & set(history.columns))
            if bad != self._bad[axis]:
                self.log.record("inputs", reading.t_s, warn=bool(bad), axis=axis, bad=bad)
            self._bad[axis] = bad

    def _write(self, t_s: float, steps: list[AxisStep]) -> list[AxisStep]:
        self.counts.cycles += 1
        self._last_t_s = t_s
        for step in steps:
            counts = self.counts.modes[step.axis]
            counts[step.mode] = counts.get(step.mode, 0) + 1
            if self._modes.get(step.axis) != step.mode:
                self.log.record(
                    "mode",
                    t_s,
                    warn=step.mode not in ("champion", "off"),
                    axis=step.axis,
                    mode=step.mode,
                    model=step.model,
                    reason=step.reason,
                )
                self._modes[step.axis] = step.mode
        offsets = {step.axis: step.offset_um for step in steps}
        if self._send(t_s, offsets, steps):
            self.steps.extend(steps)
        else:
            for step in steps:
                self.axes[step.axis].rollback()
        return steps

    def _send(self, t_s: float, offsets: dict[str, float], steps: list[AxisStep]) -> bool:
        for attempt in range(1 + self.settings.write_retries):
            try:
                self.sink.write(t_s, offsets)
            except Exception as error:  # a refused write must never stop the runtime
                self.counts.refused += 1
                self.log.record(
                    "write_refused", t_s, warn=True, attempt=attempt + 1, error=repr(error)
                )
                self.sleep(self.settings.retry_wait_s)
                continue
            self.counts.writes += 1
            self.log.record(
                "write",
                t_s,
                offsets=offsets,
                modes={s.axis: s.mode for s in steps},
                predicted={s.axis: s.predicted_um for s in steps},
            )
            return True
        self.counts.failed += 1
        self.log.record("write_failed", t_s, warn=True, offsets=offsets)
        return False

"""One axis' offset, once per cycle: the champion, else a fallback, else hold and decay; bounded.

Order of fallback, per axis and per cycle:

1. **the champion**, when every input it reads is good and it predicts;
2. **a model trained without the failed sensor** (the champion's family refitted without it,
   in the bundle's order), when exactly the sensors it does not read have failed;
3. **hold** the last good offset for ``hold_s``, then **decay** it to zero with time constant
   ``decay_s`` (a stale correction is worse than none once the machine has cooled or warmed).

An axis returns from a fallback to its champion only after ``recover_cycles`` good cycles in a
row, so a flickering sensor does not toggle the model every cycle. Whatever the source, the
offset is then bounded: at most ``max_offset_um`` in magnitude and a change of at most
``max_rate_um_per_s`` per second of machine time since the last write (the controller's own
limits, e.g. SINUMERIK MD32760, stay a second line).

Predictions are :func:`pipeline.protocol.serving.predict_run` on the run so far -- the code
the registered model (:func:`pipeline.protocol.serving.predict_table`) and the training scores
use (windows of the training's ``resample_s``, rises from the run's reference, speed responses
from rest at its start) -- read at the newest sample: the inputs are causal, so the newest value
is what the whole-run prediction gives at that instant. The cost of a cycle grows with the
length of the run (one pass over it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pipeline.compensation.bundle import AxisBundle, ModelEntry
from pipeline.compensation.guard import RPM
from pipeline.protocol.serving import predict_run
from pipeline.settings.compensation import AxisLimits, CompensationSettings

CHAMPION, FALLBACK, HOLD, DECAY, OFF = "champion", "fallback", "hold", "decay", "off"


@dataclass(frozen=True)
class AxisStep:
    """What one cycle wrote for one axis.

    Attributes
    ----------
    t_s : float, s
        Machine time of the cycle.
    axis : str
    mode : str
        ``champion``, ``fallback``, ``hold``, ``decay`` or ``off`` (champion ``none``).
    model : str
        The model that predicted (``champion``, ``without_<sensor>``) or ``-``.
    predicted_um : float, um
        The model's thermal error (NaN when no model ran).
    target_um : float, um
        Offset wanted before the limits.
    offset_um : float, um
        Offset written, after the size and rate limits.
    limited : bool
        Whether a limit changed the offset.
    reason : str
        Why this mode (the bad inputs, the stall).
    """

    t_s: float
    axis: str
    mode: str
    model: str
    predicted_um: float
    target_um: float
    offset_um: float
    limited: bool
    reason: str


def bound(previous: float, target: float, dt_s: float, limits: AxisLimits) -> float:
    """Offset after the size and rate limits.

    Parameters
    ----------
    previous : float, um
        Offset written last.
    target : float, um
    dt_s : float, s
        Machine time since the last write (negative counts as 0).
    limits : AxisLimits

    Returns
    -------
    float, um
        ``target`` clipped to +-``max_offset_um``, then moved from ``previous`` by at most
        ``max_rate_um_per_s * dt_s``.
    """
    wanted = float(np.clip(target, -limits.max_offset_um, limits.max_offset_um))
    step = limits.max_rate_um_per_s * max(float(dt_s), 0.0)
    return float(np.clip(wanted, previous - step, previous + step))


def predict_latest(entry: ModelEntry, history: Mapping[str, np.ndarray]) -> float:
    """Return the thermal error (um) the model predicts at the run's newest sample (NaN: none).

    ``history``: the run so far, one array per column (``elapsed_s``, ``rpm``, the sensors).
    """
    t_s = history["elapsed_s"]
    if not len(t_s):
        return float("nan")
    sensors = entry.spec.sensors
    temperatures = (
        np.column_stack([history[name] for name in sensors]) if sensors else np.empty((len(t_s), 0))
    )
    rpm = history[RPM] if entry.spec.needs_speed else np.full(len(t_s), np.nan)
    return float(predict_run(entry.estimator, t_s, temperatures, rpm, entry.spec)[-1])


def usable(entry: ModelEntry, bad: Mapping[str, str]) -> bool:
    """Whether none of the inputs ``entry`` reads is bad."""
    reads = set(entry.spec.sensors) | ({RPM} if entry.spec.needs_speed else set())
    return not reads & set(bad)


class AxisCompensator:
    """The offset of one axis, cycle after cycle (see the module docstring for the order).

    Parameters
    ----------
    bundle : AxisBundle
    settings : CompensationSettings
    """

    def __init__(self, bundle: AxisBundle, settings: CompensationSettings) -> None:
        self.bundle = bundle
        self.settings = settings
        self.limits = settings.limits_of(bundle.axis)
        self.offset_um = 0.0
        self.last_t_s: float | None = None
        self.good_offset_um = 0.0
        self.good_t_s: float | None = None
        self.mode = CHAMPION
        self.good_streak = 0
        self.faulted = False
        self._written: tuple[float, float | None] = (0.0, None)

    def step(
        self, history: Mapping[str, np.ndarray], bad: Mapping[str, str], t_s: float
    ) -> AxisStep:
        """Offset of this cycle from the run so far and its bad inputs.

        ``history``: one array per column (``elapsed_s``, ``rpm``, the sensors), the newest
        reading last, bad cells NaN.
        """
        if not self.bundle.compensate:
            return self._write(t_s, OFF, "-", float("nan"), 0.0, "champion is none")
        entry, why = self._choose(bad)
        predicted = predict_latest(entry, history) if entry is not None else float("nan")
        if entry is not None and math.isfinite(predicted):
            target = self.settings.offset_sign * predicted
            self.good_offset_um, self.good_t_s = target, t_s
            mode = CHAMPION if entry is self.bundle.champion else FALLBACK
            return self._write(t_s, mode, entry.name, predicted, target, why)
        if entry is not None:
            why = f"{entry.name} cannot predict (an input missing in its window)"
        return self.hold(t_s, why)

    def hold(self, t_s: float, why: str) -> AxisStep:
        """Hold the last good offset for ``hold_s``, then decay it to zero (``decay_s``)."""
        since = 0.0 if self.good_t_s is None else max(t_s - self.good_t_s, 0.0)
        over = since - self.settings.hold_s
        if over <= 0:
            return self._write(t_s, HOLD, "-", float("nan"), self.good_offset_um, why)
        target = self.good_offset_um * math.exp(-over / self.settings.decay_s)
        return self._write(t_s, DECAY, "-", float("nan"), target, why)

    def _choose(self, bad: Mapping[str, str]) -> tuple[ModelEntry | None, str]:
        champion = self.bundle.champion
        if usable(champion, bad):
            self.good_streak += 1
            if self.good_streak >= self.settings.recover_cycles:
                self.faulted = False
            if not self.faulted:
                return champion, "inputs good"
        else:
            self.good_streak, self.faulted = 0, True
        failed = ", ".join(f"{name}: {why}" for name, why in sorted(bad.items())) or (
            f"recovering ({self.good_streak}/{self.settings.recover_cycles} good cycles)"
        )
        for entry in self.bundle.fallbacks:
            if usable(entry, bad):
                return entry, failed
        return None, failed or "no model left"

    def rollback(self) -> None:
        """Forget the last offset: the sink refused it, the controller still has the one before."""
        self.offset_um, self.last_t_s = self._written

    def _write(
        self, t_s: float, mode: str, model: str, predicted: float, target: float, why: str
    ) -> AxisStep:
        self._written = (self.offset_um, self.last_t_s)
        dt = 0.0 if self.last_t_s is None else t_s - self.last_t_s
        offset = bound(self.offset_um, target, dt, self.limits)
        limited = not math.isclose(offset, target, abs_tol=1e-9)
        self.offset_um, self.last_t_s, self.mode = offset, t_s, mode
        return AxisStep(t_s, self.bundle.axis, mode, model, predicted, target, offset, limited, why)

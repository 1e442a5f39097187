"""Each cycle's input checks: a bad reading never reaches a model, let alone the controller.

The checks are those the ``validate`` stage runs on a campaign (``docs/data-contract.md``),
applied to the newest reading with the recent history of the run, through the same check
functions (:mod:`schemas.checks`):

- missing (NaN, no value, an OPC UA value with a bad status);
- a sensor fault code (DS18B20 power-on 85.0 degC, disconnected -127.0 degC);
- outside the physical temperature range (``validate.temperature_range_degC``);
- stuck: the same reading ``stuck_min_samples`` times in a row over ``stuck_min_minutes``
  while another sensor moved ``stuck_min_other_change_degC`` (:func:`schemas.checks.stuck_free`
  on the last samples);
- outside the range seen in training: a model input (the rise since the run's reference, or
  the temperature for models on absolute temperatures) further than ``range_margin_K`` outside
  its training range: the model was never shown such a state.

Not applied: the spike check, which needs the reading *after* the one it judges; the runtime's
rate limit bounds what one spike can do to the offset (at most ``max_rate_um_per_s`` times the
cycle). A spindle speed that is missing is a bad ``rpm`` for the models that read it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from pipeline.compensation.bundle import InputChecks
from pipeline.separation.features import reference_value
from schemas.checks import stuck_free

RPM = "rpm"
Columns = pd.DataFrame | Mapping[str, np.ndarray]
"""A run's readings: a table, or its columns as arrays of equal length (newest last)."""


def reading_problem(value: float, checks: InputChecks) -> str | None:
    """Why one temperature reading (degC) is bad, or None."""
    if value is None or not np.isfinite(value):
        return "missing reading"
    if value in checks.fault_codes:
        return f"sensor fault code {value:g} degC (DS18B20 power-on 85 / disconnected -127)"
    low, high = checks.temperature_range_degC
    if not low <= value <= high:
        return f"{value:g} degC outside the physical range [{low:g}, {high:g}] degC"
    return None


def _column(history: Columns, name: str) -> np.ndarray:
    return np.asarray(history[name], dtype=float)


def stuck_sensors(history: Columns, sensors: Sequence[str], checks: InputChecks) -> dict:
    """Return the sensors whose newest reading ends a stuck run (:func:`schemas.checks.stuck_free`).

    Parameters
    ----------
    history : DataFrame or mapping of str to ndarray
        The run's samples in time order: ``elapsed_s`` (s) and one column per sensor, degC.
    sensors : sequence of str
    checks : InputChecks

    Returns
    -------
    dict of str to str
        Sensor -> why.
    """
    elapsed = _column(history, "elapsed_s")
    k = checks.stuck_min_samples
    if len(elapsed) < k:
        return {}
    # a stuck run ending now repeats the newest reading over the last stuck_min_samples at least
    candidates = [s for s in sensors if (_column(history, s)[-k:] == _column(history, s)[-1]).all()]
    if not candidates:
        return {}
    step = np.diff(elapsed[-k:])
    interval = float(np.median(step)) if step.size else 0.0
    needed = k
    if interval > 0:
        needed = max(needed, int(np.ceil(checks.stuck_min_s / interval)))
    names = ["elapsed_s", *sensors]
    recent = pd.DataFrame({name: _column(history, name)[-(needed + 1) :] for name in names})
    ok = stuck_free(
        recent,
        list(sensors),
        min_samples=k,
        min_other_change=checks.stuck_min_other_change_degC,
        ignore={s: checks.fault_codes for s in sensors},
        min_duration_s=checks.stuck_min_s,
    )
    last = ok.iloc[-1]
    return {
        s: f"stuck at {recent[s].iloc[-1]:g} degC for {len(recent)} samples while others moved"
        for s in candidates
        if not bool(last[s])
    }


def out_of_training_range(
    history: Columns,
    sensors: Sequence[str],
    features: str,
    spec_reference: tuple[str, int],
    ranges: Mapping[str, tuple[float, float]],
    margin: float,
) -> dict:
    """Sensors whose newest input lies further than ``margin`` outside its training range.

    The input is the rise since the run's reference (:func:`reference_value`, as in training)
    for ``temperature_rise`` models, the reading for ``absolute`` ones.
    """
    problems = {}
    reference, n = spec_reference
    for sensor in sensors:
        rise = features == "temperature_rise"
        column = f"rise_{sensor}" if rise else sensor
        if column not in ranges or sensor not in history:
            continue
        values = _column(history, sensor)
        value = values[-1] - reference_value(values, reference, n) if rise else values[-1]
        low, high = ranges[column]
        if np.isfinite(value) and not (low - margin <= value <= high + margin):
            unit = "K rise" if rise else "degC"
            problems[sensor] = (
                f"{value:.2f} {unit} outside the range seen in training [{low:.2f}, {high:.2f}] "
                f"+- {margin:g} K"
            )
    return problems


def bad_inputs(
    history: Columns,
    sensors: Sequence[str],
    checks: InputChecks,
    *,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    features: str = "temperature_rise",
    reference: tuple[str, int] = ("first_sample", 1),
    needs_speed: bool = False,
) -> dict[str, str]:
    """Every bad input of the newest reading, with the reason.

    Parameters
    ----------
    history : DataFrame or mapping of str to ndarray
        The run so far, newest last: ``elapsed_s``, ``rpm`` and sensor columns (degC), bad
        readings of earlier cycles already set to NaN. The runtime passes its history's columns
        as arrays (:meth:`pipeline.compensation.runtime.RunHistory.columns_now`): a cycle then
        costs no table built from the whole run.
    sensors : sequence of str
        The sensors the axis' models read.
    checks : InputChecks
    ranges : mapping, optional
        Training range of each model input column
        (:func:`pipeline.compensation.bundle.input_ranges`).
    features, reference
        How the models' temperature inputs are prepared (``InputSpec.features``,
        ``(InputSpec.reference, InputSpec.reference_n)``).
    needs_speed : bool
        Whether a missing ``rpm`` is bad.

    Returns
    -------
    dict of str to str
        Input (a sensor or ``rpm``) -> why it is bad; empty when all are good.
    """
    problems = {}
    for sensor in sensors:
        value = float(_column(history, sensor)[-1]) if sensor in history else float("nan")
        why = reading_problem(value, checks)
        if why:
            problems[sensor] = why
    speed = _column(history, RPM)[-1] if RPM in history else np.nan
    if needs_speed and not np.isfinite(float(speed)):
        problems[RPM] = "spindle speed missing"
    good = [s for s in sensors if s not in problems]
    problems |= stuck_sensors(history, good, checks)
    good = [s for s in good if s not in problems]
    problems |= out_of_training_range(
        history, good, features, reference, ranges or {}, checks.range_margin_K
    )
    return problems

"""Model inputs of the spindle thermal error: temperature rises and spindle-speed responses.

The same functions prepare the inputs when a model is trained (the ``separate_spindle`` stage,
one run of campaigns at a time) and when the registered model is used (its pyfunc, one run of
the user's table at a time), so training and serving cannot drift apart:

- **temperature rise** (K) of a sensor: its reading minus its value at the run's reference
  (the first sample, or the mean of the first ``n`` samples: ``separate.cold_reference``,
  ``cold_n``). A *run* is a stretch of measurement without a break: one campaign, or several
  campaigns cut from one long record (:mod:`pipeline.separation.runs`); its first sample is the
  only one that can be the cold state.
- **speed responses** (dimensionless, in (krpm)^a): the response of first-order lags with time
  constants tau to the spindle speed raised to a power a,

  ``s_{a,tau}(t_{k+1}) = s_{a,tau}(t_k) exp(-dt/tau) + (rpm_k / 1000)^a (1 - exp(-dt/tau))``,

  exact for a speed held between samples (zero-order hold), starting from rest
  (``s = 0``) at the run's first sample. A missing speed is 0 rpm (outside the segments of a
  ``spindle_program`` the spindle stands, as for the twin); across a break longer than
  :data:`MAX_HOLD_INTERVALS` sampling intervals (a declared ``follows:`` over a gap) the spindle
  is taken as stopped; a run with no speed at all has no speed responses (NaN). This is the
  input of the speed-based spindle growth compensation of machine-tool controllers: the growth
  as a sum of first-order responses to the friction power, which grows with speed like n^a
  (a = 1 for load-dependent friction, 5/3 for viscous friction after Palmgren; two exponents, 1
  and 2, span that range linearly). The spindle shaft that carries much of the drift has no
  sensor; these inputs stand in for its temperature.

Inputs are named ``rise_<sensor>`` (or the sensor name for absolute temperatures) and
``speed_lag_<tau>min`` (a = 1) / ``speed<a>_lag_<tau>min`` (other a). Records sampled faster
than the model's window (``separate.resample_s``) are averaged into windows of that length
before the inputs are computed, in training (:func:`resample`) and in serving
(:mod:`pipeline.protocol.serving`) alike.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.machines import by_machine

COLD_REFERENCES = ("first_sample", "mean_first_n")
FEATURE_KINDS = ("temperature_rise", "absolute")
RPM_SCALE = 1000.0
"""Speeds enter the responses in krpm."""
MAX_HOLD_INTERVALS = 3.0
"""A speed is held over at most this many median sampling intervals; longer breaks: stopped."""

_SPEED_NAME = re.compile(r"^speed(?P<a>[0-9.]+)?_lag_(?P<tau>[0-9.]+)min$")


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def speed_feature_name(exponent: float, tau_min: float) -> str:
    """Name of the response of a lag of ``tau_min`` (min) to (rpm/1000)^``exponent``."""
    power = "" if float(exponent) == 1.0 else _number(exponent)
    return f"speed{power}_lag_{_number(tau_min)}min"


def is_speed_feature(name: str) -> bool:
    """Return True for a speed-response input name (``speed_lag_30min``, ``speed2_lag_90min``)."""
    return bool(_SPEED_NAME.match(str(name)))


@dataclass(frozen=True)
class SpeedResponses:
    """Which speed responses are computed.

    Attributes
    ----------
    time_constants_min : tuple of float, min
        Time constants tau of the first-order lags.
    exponents : tuple of float
        Powers a of the speed (friction power ~ n^a).
    """

    time_constants_min: tuple[float, ...] = (10.0, 30.0, 90.0, 270.0)
    exponents: tuple[float, ...] = (1.0, 2.0)

    def __post_init__(self) -> None:
        """Check that time constants are positive and exponents finite and positive."""
        if any(not (t > 0 and math.isfinite(t)) for t in self.time_constants_min):
            raise ValueError(
                f"speed time constants must be positive minutes, got {self.time_constants_min}; "
                "fix params.yaml separate.speed_responses.time_constants_min"
            )
        if any(not (a > 0 and math.isfinite(a)) for a in self.exponents):
            raise ValueError(
                f"speed exponents must be positive, got {self.exponents}; fix params.yaml "
                "separate.speed_responses.exponents"
            )

    @classmethod
    def from_dict(cls, section: Mapping | None) -> SpeedResponses | None:
        """Inverse of :meth:`to_dict`; None or empty: no speed responses."""
        if not section:
            return None
        return cls(
            tuple(float(t) for t in section["time_constants_min"]),
            tuple(float(a) for a in section["exponents"]),
        )

    def names(self) -> list[str]:
        """Input names, exponent-major: ``speed_lag_10min``, ..., ``speed2_lag_10min``..."""
        return [
            speed_feature_name(a, tau) for a in self.exponents for tau in self.time_constants_min
        ]

    def to_dict(self) -> dict:
        """JSON-ready form (model card)."""
        return {
            "time_constants_min": list(self.time_constants_min),
            "exponents": list(self.exponents),
        }


def reference_value(values: np.ndarray, reference: str, n: int) -> float:
    """Return the reference value of a series: its first finite value or the mean of the first n.

    Parameters
    ----------
    values : ndarray of shape (n_samples,)
        Time-ordered readings (um or degC); NaN are missing readings.
    reference : {"first_sample", "mean_first_n"}
    n : int
        Number of finite samples averaged for ``mean_first_n``.

    Returns
    -------
    float
        NaN when no value is finite.

    Raises
    ------
    ValueError
        For an unknown ``reference``.
    """
    if reference not in COLD_REFERENCES:
        raise ValueError(
            f"params.yaml separate.cold_reference is '{reference}'; use one of {COLD_REFERENCES}"
        )
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return float("nan")
    return float(finite[0]) if reference == "first_sample" else float(np.mean(finite[: int(n)]))


def check_feature_kind(features: str) -> str:
    """Return ``features`` if it is ``temperature_rise`` or ``absolute``.

    Raises
    ------
    ValueError
        Naming params.yaml select.features and the kinds it may take.
    """
    if features not in FEATURE_KINDS:
        raise ValueError(
            f"params.yaml select.features is '{features}'; use one of {list(FEATURE_KINDS)}"
        )
    return features


def known_speed(rpm: np.ndarray) -> np.ndarray:
    """Speed with missing entries as 0 rpm (the spindle stands); all-NaN when none is known."""
    speed = np.asarray(rpm, dtype=float)
    if not np.isfinite(speed).any():
        return np.full(speed.shape, np.nan)
    return np.where(np.isfinite(speed), speed, 0.0)


def speed_responses(t_s: np.ndarray, rpm: np.ndarray, spec: SpeedResponses) -> pd.DataFrame:
    """First-order responses to the spindle speed, from rest at the first sample.

    The table of :func:`speed_response_values`, columns :meth:`SpeedResponses.names`.
    """
    return pd.DataFrame(speed_response_values(t_s, rpm, spec), columns=spec.names())


def speed_response_values(t_s: np.ndarray, rpm: np.ndarray, spec: SpeedResponses) -> np.ndarray:
    """First-order responses to the spindle speed, from rest at the first sample.

    Parameters
    ----------
    t_s : ndarray of shape (n,), s
        Sample instants of one run, increasing.
    rpm : ndarray of shape (n,), rpm
        Speed at each instant, held until the next sample (missing: 0 rpm, see
        :func:`known_speed`; all missing gives NaN responses); over an interval longer than
        :data:`MAX_HOLD_INTERVALS` median intervals the spindle is taken as stopped.
    spec : SpeedResponses

    Returns
    -------
    ndarray of shape (n, len(spec.names()))
        In the order of :meth:`SpeedResponses.names`, in (krpm)^a; the first row is 0.
    """
    t = np.asarray(t_s, dtype=float)
    speed = known_speed(rpm)
    n_names = len(spec.exponents) * len(spec.time_constants_min)
    if t.size == 0 or not np.isfinite(speed).any():
        return np.full((t.size, n_names), np.nan)
    steps = np.diff(t)
    if steps.size:
        speed[:-1] = np.where(steps > MAX_HOLD_INTERVALS * np.median(steps), 0.0, speed[:-1])
    drive = np.column_stack(
        [
            np.repeat(
                (np.clip(speed, 0.0, None) / RPM_SCALE) ** a, len(spec.time_constants_min)
            ).reshape(-1, len(spec.time_constants_min))
            for a in spec.exponents
        ]
    )
    taus = np.tile(np.asarray(spec.time_constants_min, dtype=float) * 60.0, len(spec.exponents))
    return first_order_lag(np.diff(t), drive, taus)


def first_order_lag(steps_s: np.ndarray, drive: np.ndarray, taus_s: np.ndarray) -> np.ndarray:
    """First-order lags of ``drive`` (held over each step), from rest at the first sample.

    ``out[k + 1] = out[k] d_k + drive[k] (1 - d_k)`` with ``d_k = exp(-steps_s[k] / tau)``: the
    exact response of ``tau y' + y = u`` to a zero-order hold. Steps all equal (resampled
    windows): one linear filter per column (:func:`scipy.signal.lfilter`); else step by step.

    Parameters
    ----------
    steps_s : ndarray of shape (n - 1,), s
    drive : ndarray of shape (n, m)
    taus_s : ndarray of shape (m,), s

    Returns
    -------
    ndarray of shape (n, m)
    """
    out = np.zeros(drive.shape)
    if steps_s.size and np.all(steps_s == steps_s[0]):
        # imported here: scipy.signal takes about a second to import, and most of the stages
        # that import this module never compute a speed response
        from scipy.signal import lfilter

        for j, decay in enumerate(np.exp(-steps_s[0] / taus_s)):
            out[:, j] = lfilter([0.0, 1.0 - decay], [1.0, -decay], drive[:, j])
        return out
    decay = np.exp(-steps_s[:, None] / taus_s[None, :])
    for k in range(steps_s.size):
        out[k + 1] = out[k] * decay[k] + drive[k] * (1.0 - decay[k])
    return out


def run_inputs(
    t_s: np.ndarray,
    temperatures: pd.DataFrame,
    rpm: np.ndarray,
    *,
    features: str,
    reference: str,
    n: int,
    speed: SpeedResponses | None,
) -> pd.DataFrame:
    """Every model input of one run, referenced to the run's first sample(s).

    Parameters
    ----------
    t_s : ndarray of shape (n_samples,), s
        Instants since the run's start, increasing.
    temperatures : DataFrame of shape (n_samples, m), degC
        One column per sensor.
    rpm : ndarray of shape (n_samples,), rpm
    features : {"temperature_rise", "absolute"}
        Temperature inputs: rise since the run's reference (K, column ``rise_<sensor>``) or the
        reading itself (degC, column ``<sensor>``).
    reference : {"first_sample", "mean_first_n"}
    n : int
        Samples averaged for ``mean_first_n``.
    speed : SpeedResponses or None
        Speed responses to add (None: none).

    Returns
    -------
    DataFrame of shape (n_samples, m + k)
        Temperature inputs then speed responses (:func:`run_input_values`), numbered from 0.

    Raises
    ------
    ValueError
        For an unknown ``features`` or ``reference``.
    """
    values = run_input_values(
        t_s,
        temperatures.to_numpy(dtype=float, na_value=np.nan),
        rpm,
        features=features,
        reference=reference,
        n=n,
        speed=speed,
    )
    names = [input_column(str(sensor), features) for sensor in temperatures.columns]
    return pd.DataFrame(values, columns=names + ([] if speed is None else speed.names()))


def run_input_values(
    t_s: np.ndarray,
    temperatures: np.ndarray,
    rpm: np.ndarray,
    *,
    features: str,
    reference: str,
    n: int,
    speed: SpeedResponses | None,
) -> np.ndarray:
    """Return the values of :func:`run_inputs`: temperature inputs, then speed responses.

    Parameters
    ----------
    t_s : ndarray of shape (n_samples,), s
    temperatures : ndarray of shape (n_samples, m), degC
        One column per sensor; NaN is a missing reading.
    rpm : ndarray of shape (n_samples,), rpm
    features, reference, n, speed
        As for :func:`run_inputs`.

    Returns
    -------
    ndarray of shape (n_samples, m + k)
        Rises (K) or readings (degC) of each sensor, then the speed responses in the order of
        :meth:`SpeedResponses.names`.
    """
    check_feature_kind(features)
    values = np.array(temperatures, dtype=float, ndmin=2)
    if features == "temperature_rise":
        cold = [reference_value(values[:, j], reference, n) for j in range(values.shape[1])]
        values = values - np.asarray(cold, dtype=float)
    else:
        reference_value(np.array([]), reference, n)  # the reference must still be valid
    if speed is None:
        return values
    return np.hstack([values, speed_response_values(t_s, rpm, speed)])


def resample(rows: pd.DataFrame, window_s: float | None) -> pd.DataFrame:
    """Average one run's (or campaign's) samples into windows of ``window_s`` if sampled faster.

    Parameters
    ----------
    rows : DataFrame
        Samples in time order with ``elapsed_s`` (s) and numeric columns (``rpm``,
        temperatures, ``disp_<A>``...); optional ``campaign_id`` and ``source_row``.
    window_s : float or None, s

    Returns
    -------
    DataFrame
        ``rows`` unchanged when the median interval is at least ``window_s`` (or None, or there is
        no ``elapsed_s``); else one row per window ``[first + k w, first + (k + 1) w)``: the
        means of every numeric column (missing readings left out; ``elapsed_s`` the mean
        instant), ``source_row`` the window's first data row, ``campaign_id`` kept.
    """
    if window_s is None or len(rows) < 2 or "elapsed_s" not in rows:
        return rows
    t = rows["elapsed_s"].to_numpy(dtype=float)
    if not needs_windows(t, window_s):
        return rows
    numeric = [
        c
        for c, dtype in rows.dtypes.items()
        if c not in ("campaign_id", "source_row") and pd.api.types.is_numeric_dtype(dtype)
    ]
    firsts, means = window_means(t, rows[numeric].to_numpy(dtype=float, na_value=np.nan), window_s)
    out = pd.DataFrame(means, columns=numeric)
    for column in ("source_row", "campaign_id"):
        if column in rows:
            out.insert(0, column, rows[column].to_numpy()[firsts])
    return out


def needs_windows(t_s: np.ndarray, window_s: float | None) -> bool:
    """Whether samples at times ``t_s`` (s) are averaged into windows of ``window_s`` (s).

    True when there is a window, two samples or more, and a median interval below it.
    """
    return window_s is not None and len(t_s) > 1 and np.median(np.diff(t_s)) < window_s * 0.999


def window_means(
    t_s: np.ndarray, values: np.ndarray, window_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Average samples into windows ``[t0 + k w, t0 + (k + 1) w)``, missing readings left out.

    The array core of :func:`resample`.

    Parameters
    ----------
    t_s : ndarray of shape (n,), s
        Sample times; ``t_s[0]`` starts the first window.
    values : ndarray of shape (n, m)
        Float columns; NaN is a missing reading.
    window_s : float, s

    Returns
    -------
    firsts : ndarray of int
        Row of each window's first sample (in ``t_s``' order).
    means : ndarray of shape (n_windows, m)
        Mean of each column in each window (NaN where a window has no reading of it).
    """
    window = np.floor((t_s - t_s[0]) / window_s).astype(np.int64)
    order = np.argsort(window, kind="stable")
    ordered = window[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    values = values[order]
    missing = np.isnan(values)
    sums = np.add.reduceat(np.where(missing, 0.0, values), starts, axis=0)
    counts = np.add.reduceat((~missing).astype(float), starts, axis=0)
    with np.errstate(invalid="ignore"):
        return order[starts], sums / counts


def input_column(name: str, features: str) -> str:
    """Column of the separated table holding input ``name`` (a sensor or a speed response)."""
    if is_speed_feature(name) or features == "absolute":
        return name
    return f"rise_{name}"


@dataclass(frozen=True)
class InputSpec:
    """How a model's inputs are prepared; travels with the registered model (its card).

    Attributes
    ----------
    inputs : tuple of str
        Model inputs in order: sensor names (degC columns of the user's table) and speed
        responses (computed from the table's ``rpm`` and ``elapsed_s``).
    features : str
        ``temperature_rise`` or ``absolute``.
    reference : str
        ``first_sample`` or ``mean_first_n``: the run's reference for rises.
    reference_n : int
    speed : SpeedResponses or None
        How the speed responses were computed (None when the model uses none).
    resample_s : float or None, s
        Records sampled faster are averaged into windows of this length first (None: never).
    """

    inputs: tuple[str, ...]
    features: str
    reference: str
    reference_n: int
    speed: SpeedResponses | None = None
    resample_s: float | None = None

    @property
    def sensors(self) -> list[str]:
        """Temperature sensors among the inputs."""
        return [name for name in self.inputs if not is_speed_feature(name)]

    @property
    def needs_speed(self) -> bool:
        """Whether the table must carry ``rpm`` and ``elapsed_s``."""
        return any(is_speed_feature(name) for name in self.inputs)

    def to_dict(self) -> dict:
        """JSON-ready form (model card)."""
        return {
            "inputs": list(self.inputs),
            "features": self.features,
            "reference": self.reference,
            "reference_n": int(self.reference_n),
            "speed": None if self.speed is None else self.speed.to_dict(),
            "resample_s": self.resample_s,
        }

    @classmethod
    def from_dict(cls, card: Mapping) -> InputSpec:
        """Inverse of :meth:`to_dict`."""
        window = card.get("resample_s")
        return cls(
            tuple(card["inputs"]),
            str(card["features"]),
            str(card["reference"]),
            int(card["reference_n"]),
            SpeedResponses.from_dict(card.get("speed")),
            None if window is None else float(window),
        )


def model_inputs(table: pd.DataFrame, spec: InputSpec) -> pd.DataFrame:
    """Model inputs from a user's table, prepared exactly as in training.

    Parameters
    ----------
    table : DataFrame
        One row per sample in time order: a column per sensor of ``spec`` (degC); ``rpm``
        (spindle speed) and ``elapsed_s`` (s since the run's start) when the model uses speed
        responses; optional ``campaign_id`` (several runs in one table, each a contiguous block of
        rows). The first row (or the first ``reference_n`` rows) of each run is its reference:
        the cold state when the run starts cold, the state the compensation is counted from
        otherwise.

    Returns
    -------
    DataFrame of shape (n, len(spec.inputs))
        Indexed by (``campaign_id``, ``elapsed_s``), columns ``spec.inputs``.

    Raises
    ------
    ValueError
        If a column the model needs is missing, naming it and the columns found.
    """
    check_input_columns(table.columns, spec)
    runs = (
        table["campaign_id"].astype(str).to_numpy()
        if "campaign_id" in table
        else np.full(len(table), "run")
    )
    elapsed = (
        table["elapsed_s"].to_numpy(dtype=float)
        if "elapsed_s" in table
        else np.arange(len(table), dtype=float)
    )
    rpm = table["rpm"].to_numpy(dtype=float) if "rpm" in table else np.full(len(table), np.nan)
    temperatures = table[spec.sensors].to_numpy(dtype=float, na_value=np.nan)
    values = np.full((len(table), len(spec.inputs)), np.nan)
    for run in pd.unique(runs):
        rows = np.flatnonzero(runs == run)
        values[rows] = spec_input_values(spec, elapsed[rows], temperatures[rows], rpm[rows])
    return pd.DataFrame(values, index=run_time_index(runs, elapsed), columns=list(spec.inputs))


def check_input_columns(columns: Sequence[str], spec: InputSpec) -> None:
    """Raise ValueError, naming them, if columns that ``spec`` reads are not in ``columns``."""
    needed = list(spec.sensors) + (["rpm", "elapsed_s"] if spec.needs_speed else [])
    missing = [c for c in needed if c not in columns]
    if missing:
        raise ValueError(
            f"the table lacks column(s) {missing} (found {list(columns)}); this model needs "
            f"{needed}: temperatures in degC"
            + (", the spindle speed rpm and elapsed_s in s" if spec.needs_speed else "")
        )


def spec_input_values(
    spec: InputSpec, t_s: np.ndarray, temperatures: np.ndarray, rpm: np.ndarray
) -> np.ndarray:
    """Return one run's model inputs as :func:`model_inputs` computes them, as an array.

    Parameters
    ----------
    spec : InputSpec
    t_s : ndarray of shape (n,), s
        Time of each sample since the run's start.
    temperatures : ndarray of shape (n, len(spec.sensors)), degC
        The readings of ``spec.sensors``, in that order (NaN: missing).
    rpm : ndarray of shape (n,), rpm
        Spindle speed (read only when ``spec.needs_speed``).

    Returns
    -------
    ndarray of shape (n, len(spec.inputs))
        Columns in the order of ``spec.inputs``.
    """
    speed = spec.speed if spec.needs_speed else None
    produced = [input_column(name, spec.features) for name in spec.sensors]
    produced += [] if speed is None else speed.names()
    take = [produced.index(input_column(name, spec.features)) for name in spec.inputs]
    inputs = run_input_values(
        t_s,
        temperatures,
        rpm,
        features=spec.features,
        reference=spec.reference,
        n=spec.reference_n,
        speed=speed,
    )
    return inputs[:, take]


def run_time_index(runs: np.ndarray, elapsed_s: np.ndarray) -> pd.MultiIndex:
    """Return the (``campaign_id``, ``elapsed_s``) index of a table of runs.

    What ``pd.MultiIndex.from_arrays`` builds, from codes (a quarter of its time: the runtime
    builds one per cycle; for one run in time order, without sorting anything).
    """
    n = len(runs)
    if n and (runs == runs[0]).all() and (np.diff(elapsed_s) > 0).all():
        return pd.MultiIndex(
            levels=[pd.Index(runs[:1]), pd.Index(elapsed_s)],
            codes=[np.zeros(n, dtype=np.int8), np.arange(n)],
            names=["campaign_id", "elapsed_s"],
            verify_integrity=False,
        )
    run_codes, run_names = pd.factorize(runs, sort=True)
    time_codes, times = pd.factorize(elapsed_s, sort=True)
    return pd.MultiIndex(
        levels=[pd.Index(run_names), pd.Index(times)],
        codes=[run_codes, time_codes],
        names=["campaign_id", "elapsed_s"],
        verify_integrity=False,
    )


def input_names(columns: Sequence[str], features: str) -> list[str]:
    """Input names offered by a separated table: sensors (from ``rise_`` columns) then speed."""
    sensors = [c.removeprefix("rise_") for c in columns if str(c).startswith("rise_")]
    if features == "absolute":
        sensors = [s for s in sensors if s in columns]
    speed = [c for c in columns if is_speed_feature(c)]
    return [*natural_sorted(sensors), *speed]


def input_columns(columns: Sequence[str]) -> set[str]:
    """Columns of a separated table that are a machine's own inputs: sensors, rises, speeds."""
    sensors = {str(c).removeprefix("rise_") for c in columns if str(c).startswith("rise_")}
    rises = {f"rise_{s}" for s in sensors}
    return {c for c in columns if c in sensors or c in rises or is_speed_feature(c)}


def separated_by_machine(table: pd.DataFrame) -> Iterator[tuple[str, pd.DataFrame]]:
    """Yield each machine of a separated table and its rows alone, by name.

    A table of several machines holds the union of their sensor and speed columns; each
    machine's rows come without the input columns only the other machines fill
    (:func:`pipeline.machines.machine_rows`).
    """
    inputs = input_columns(list(table.columns))
    yield from by_machine(table, [c for c in table.columns if c not in inputs])


def natural_sorted(names: Sequence[str]) -> list[str]:
    """Names in natural order: T2 before T10."""
    return sorted(
        names, key=lambda name: [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name)]
    )

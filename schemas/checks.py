"""Pure check functions used by the Pandera models: frames/series in, boolean masks out.

Each function returns ``True`` where the data pass (Pandera's convention) and never modifies its
input. Functions that look at one campaign at a time take a ``groups`` series (the
``campaign_id`` column) so the same check works on a single campaign and on a table of many.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

COLD_RUN_ATOL_MIN = 1e-9
"""A laser run is the cold run when ``|elapsed_min| <= COLD_RUN_ATOL_MIN``."""


def increasing_within(values: pd.Series, groups: pd.Series) -> pd.Series:
    """Return True where ``values`` is larger than the previous row of the same group.

    Parameters
    ----------
    values : Series of shape (n,)
        E.g. ``elapsed_s`` in s, in file order.
    groups : Series of shape (n,)
        Group label per row (``campaign_id``).

    Returns
    -------
    Series of bool, shape (n,)
        False where a value is not strictly larger than its predecessor in the group; the first
        row of each group and rows next to a missing value pass.
    """
    step = values.groupby(groups, sort=False).diff()
    return step.isna() | (step > 0)


def interval_consistent(elapsed_s: pd.Series, tolerance: float) -> pd.Series:
    """Return True where the sampling interval before a row is close to the median interval.

    Parameters
    ----------
    elapsed_s : Series of shape (n,), s
        Time of each sample of one campaign, in file order.
    tolerance : float
        Allowed relative deviation from the median of the positive intervals (0.2 = 20 %).

    Returns
    -------
    Series of bool, shape (n,)
        False at a row whose preceding interval ``dt`` satisfies ``|dt - median| > tolerance *
        median``. Non-positive intervals, and intervals next to a missing time, pass here
        (:func:`increasing_within` and the not-null check report those).
    """
    step = elapsed_s.diff()
    positive = step[step > 0]
    if positive.empty:
        return pd.Series(True, index=elapsed_s.index)
    median = float(positive.median())
    return ~((step > 0) & ((step - median).abs() > tolerance * median))


def median_interval(elapsed_s: pd.Series) -> float:
    """Return the median positive sampling interval of one campaign, s (NaN when none)."""
    step = elapsed_s.diff()
    return float(step[step > 0].median())


def not_in(values: pd.Series, codes: Iterable[float]) -> pd.Series:
    """Return True where a value is none of ``codes`` (exact comparison)."""
    return ~values.isin(list(codes))


def in_range_except(
    values: pd.Series, low: float, high: float, exempt: Iterable[float] = ()
) -> pd.Series:
    """Return True where ``low <= value <= high``, or the value is one of ``exempt``.

    ``exempt`` holds fault codes reported by their own check, so one reading is reported once.
    """
    return values.between(low, high) | values.isin(list(exempt))


def spike_free(values: pd.Series, threshold: float, ignore: Iterable[float] = ()) -> pd.Series:
    """Return False at a reading that jumps away from both its neighbours.

    Parameters
    ----------
    values : Series of shape (n,), degC
        One sensor of one campaign in file order; missing readings and ``ignore`` values (fault
        codes) are skipped, so the neighbours are the nearest real readings.
    threshold : float, degC
        A reading is a spike when it differs by more than this from the previous and from the
        next reading, in the same direction (both neighbours below it, or both above).
    ignore : iterable of float
        Values that are not readings (e.g. DS18B20 fault codes).

    Returns
    -------
    Series of bool, shape (n,)
    """
    real = values.where(~values.isin(list(ignore))).dropna()
    before = real - real.shift(1)
    after = real - real.shift(-1)
    spike = ((before > threshold) & (after > threshold)) | (
        (before < -threshold) & (after < -threshold)
    )
    return (~spike).reindex(values.index, fill_value=True)


def stuck_free(
    frame: pd.DataFrame,
    sensors: Sequence[str],
    min_samples: int,
    min_other_change: float,
    ignore: Mapping[str, Iterable[float]] | None = None,
    min_duration_s: float = 0.0,
) -> pd.DataFrame:
    """Flag runs of identical readings of a sensor while the other sensors moved.

    Parameters
    ----------
    frame : DataFrame of shape (n, m)
        One campaign's samples in file order; ``sensors`` columns in degC.
    sensors : sequence of str
        Temperature columns to examine (those absent from ``frame`` are skipped).
    min_samples : int
        A sensor is stuck when it repeats exactly the same reading for at least this many
        consecutive samples (a missing reading ends the run), covering at least
        ``min_duration_s`` of ``frame["elapsed_s"]`` (n samples cover n median sampling
        intervals; a quiet sensor sampled every few seconds can honestly repeat one 0.0625 degC
        code for minutes)...
    min_other_change : float, degC
        ...while at least one other sensor changed by at least this much (max - min) over the
        same samples.
    ignore : mapping of str to iterable of float, optional
        Per sensor, values that are not readings (fault codes): treated as missing.
    min_duration_s : float, s
        Shortest time span of a stuck run (needs an ``elapsed_s`` column; 0: samples only).

    Returns
    -------
    DataFrame of bool, shape (n, m)
        Same index and columns as ``frame``; False at every sample of a stuck run.
    """
    ignore = ignore or {}
    ok = pd.DataFrame(True, index=frame.index, columns=frame.columns)
    present = [s for s in sensors if s in frame.columns]
    if len(present) < 2 or min_samples < 2:
        return ok
    readings = pd.DataFrame(
        {s: frame[s].where(~frame[s].isin(list(ignore.get(s, ())))) for s in present}
    )
    elapsed = (
        frame["elapsed_s"].to_numpy(dtype=float)
        if "elapsed_s" in frame
        else np.arange(len(frame), dtype=float)
    )
    steps = np.diff(elapsed)
    steps = steps[np.isfinite(steps)]
    interval = float(np.median(steps)) if steps.size else 0.0  # n samples cover n intervals
    for sensor in present:
        values = readings[sensor].to_numpy(dtype=float)
        others = readings.drop(columns=sensor).to_numpy(dtype=float)
        start = 0
        while start < len(values):
            stop = start + 1
            if not np.isnan(values[start]):
                while stop < len(values) and values[stop] == values[start]:
                    stop += 1
            long_enough = not elapsed[stop - 1] - elapsed[start] + interval < min_duration_s
            if stop - start >= min_samples and long_enough:
                window = others[start:stop]
                with np.errstate(invalid="ignore"):
                    spread = np.nanmax(window, axis=0) - np.nanmin(window, axis=0)
                if np.any(spread >= min_other_change):
                    ok.iloc[start:stop, ok.columns.get_loc(sensor)] = False
            start = stop
    return ok


def mode_within(values: pd.Series, groups: pd.Series | list[pd.Series]) -> pd.Series:
    """Return True where a row's value equals the most frequent value of its group.

    Used for "each laser run has one direction / one elapsed_min": the minority rows of a run
    are reported. Ties keep the first value in file order.
    """

    def _first_mode(group: pd.Series) -> object:
        counts = group.value_counts(sort=False, dropna=False)
        return counts.index[int(np.argmax(counts.to_numpy()))]

    modes = values.groupby(groups, sort=False, dropna=False).transform(_first_mode)
    return (values == modes) | (values.isna() & modes.isna())


def is_cold(elapsed_min: pd.Series) -> pd.Series:
    """Return True for laser rows of the cold run (``elapsed_min`` 0)."""
    return elapsed_min.abs() <= COLD_RUN_ATOL_MIN


def first_row_of_group_without(mask: pd.Series, keys: pd.DataFrame) -> pd.Series:
    """Return False at the first row of each group where ``mask`` is never True.

    Used for group-level laser checks ("the campaign has a cold run", "the pass has both
    directions"): the failure is reported once, at the group's first row in file order.

    Parameters
    ----------
    mask : Series of bool, shape (n,)
    keys : DataFrame of shape (n, k)
        The group key columns (e.g. ``campaign_id`` and ``elapsed_min``).

    Returns
    -------
    Series of bool, shape (n,)
    """
    grouped = mask.groupby([keys[c] for c in keys.columns], sort=False, dropna=False)
    has = grouped.transform("any").astype(bool)
    first = ~keys.duplicated(keep="first")
    return ~(first & ~has)


def reference_run(laser: pd.DataFrame) -> int:
    """Return the run whose targets all runs of one campaign are compared with.

    It is the first cold run (``elapsed_min`` 0) in file order, else the first run.
    """
    cold = laser.loc[is_cold(laser["elapsed_min"]), "run"]
    return int(cold.iloc[0] if not cold.empty else laser["run"].iloc[0])


def unmatched(targets: np.ndarray, reference: np.ndarray, tolerance: float) -> np.ndarray:
    """Return a boolean mask of ``targets`` (mm) with no ``reference`` target within tolerance."""
    if reference.size == 0:
        return np.ones(targets.shape, dtype=bool)
    distance = np.abs(targets[:, None] - reference[None, :]).min(axis=1)
    return ~(distance <= tolerance)


def missing_targets(laser: pd.DataFrame, run: int, tolerance: float) -> list[float]:
    """Return the reference-run targets (mm) that ``run`` of one campaign does not measure."""
    reference = laser.loc[laser["run"] == reference_run(laser), "target_mm"].dropna()
    targets = laser.loc[laser["run"] == run, "target_mm"].dropna().to_numpy(float)
    reference = reference.to_numpy(float)
    return [float(t) for t in reference[unmatched(reference, targets, tolerance)]]


def targets_in_reference(laser: pd.DataFrame, tolerance: float) -> pd.Series:
    """Return False at laser rows whose target matches no target of the reference run.

    Parameters
    ----------
    laser : DataFrame
        Laser table (one or many campaigns): ``campaign_id``, ``run``, ``elapsed_min``,
        ``target_mm`` (mm).
    tolerance : float, mm
        Two targets are the same when they differ by at most this.

    Returns
    -------
    Series of bool, one per row
        Missing targets pass (reported as missing values).
    """
    ok = pd.Series(True, index=laser.index)
    for _, one in laser.groupby("campaign_id", sort=False):
        if one.empty:
            continue
        reference = one.loc[one["run"] == reference_run(one), "target_mm"].dropna()
        targets = one["target_mm"].to_numpy(float)
        bad = unmatched(targets, reference.to_numpy(float), tolerance) & ~np.isnan(targets)
        ok.loc[one.index[bad]] = False
    return ok


def runs_cover_reference(laser: pd.DataFrame, tolerance: float) -> pd.Series:
    """Return False at the first row of each run that misses a target of the reference run.

    See :func:`targets_in_reference` for the parameters.
    """
    ok = pd.Series(True, index=laser.index)
    for _, one in laser.groupby("campaign_id", sort=False):
        for run, rows in one.groupby("run", sort=False):
            if missing_targets(one, int(run), tolerance):
                ok.loc[rows.index[0]] = False
    return ok

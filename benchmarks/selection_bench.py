"""Best-subset selection against a naive loop of independent least-squares fits (``make bench``).

For m = 10, 16 and 20 synthetic sensors (~110 samples, like one campaign of the PCDL paper: 3 min
sampling over 5.5 h) the fast exhaustive search of :mod:`pipeline.selection.best_subset` is timed
against :func:`~pipeline.selection.best_subset.best_subset_naive`, which fits every one of the
2^m - 1 subsets with its own ``numpy.linalg.lstsq``. Where the naive loop would take too long
(above ``naive_limit`` subsets) it is timed on a random sample of subsets and extrapolated
linearly; the report says so.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from pipeline.selection.best_subset import best_subset, best_subset_naive

SAMPLES = 111
STEP_S = 180.0


def synthetic_campaign(m: int, seed: int = 0) -> tuple[pd.DataFrame, np.ndarray]:
    """``m`` correlated warm-up temperature rises (K) and an error (um) driven by three of them."""
    rng = np.random.default_rng(seed)
    t = np.arange(SAMPLES) * STEP_S
    constants = rng.uniform(1500, 12000, m)
    gains = rng.uniform(1, 10, m)
    rises = gains * (1 - np.exp(-t[:, None] / constants)) + rng.normal(0, 0.05, (SAMPLES, m))
    error = 2.0 * rises[:, 0] - 1.2 * rises[:, 1] + 0.6 * rises[:, 2]
    error = error + rng.normal(0, 0.3, SAMPLES)
    index = pd.MultiIndex.from_arrays([["bench"] * SAMPLES, t], names=["campaign_id", "elapsed_s"])
    columns = [f"T{j + 1}" for j in range(m)]
    return pd.DataFrame(rises, columns=columns, index=index), error


def _naive_seconds(X: pd.DataFrame, y: np.ndarray, limit: int, seed: int) -> tuple[float, bool]:
    m = X.shape[1]
    total = 2**m - 1
    if total <= limit:
        begin = time.perf_counter()
        best_subset_naive(X, y)
        return time.perf_counter() - begin, False
    rng = np.random.default_rng(seed)
    design = np.column_stack([np.ones(len(y)), X.to_numpy()])
    masks = rng.integers(1, total + 1, size=limit)
    begin = time.perf_counter()
    for mask in masks:
        columns = [0] + [j + 1 for j in range(m) if mask >> j & 1]
        np.linalg.lstsq(design[:, columns], y, rcond=None)
    return (time.perf_counter() - begin) * total / limit, True


def compare(m_values=(10, 16, 20), naive_limit: int = 70_000, seed: int = 0) -> list[dict]:
    """Time the fast and the naive search for each ``m``.

    Returns
    -------
    list of dict
        ``m``, ``subsets``, ``fast_s``, ``naive_s``, ``naive_extrapolated`` (bool), ``ratio``
        (naive / fast) and ``same_winner`` (checked where the naive loop ran in full).
    """
    rows = []
    for m in m_values:
        X, y = synthetic_campaign(m, seed)
        begin = time.perf_counter()
        fast = best_subset(X, y, max_exhaustive=max(m_values))
        fast_s = time.perf_counter() - begin
        naive_s, extrapolated = _naive_seconds(X, y, naive_limit, seed)
        same = None
        if not extrapolated:
            same = best_subset_naive(X, y).sensors == fast.sensors
        rows.append(
            {
                "m": m,
                "subsets": 2**m - 1,
                "fast_s": fast_s,
                "naive_s": naive_s,
                "naive_extrapolated": extrapolated,
                "ratio": naive_s / fast_s,
                "same_winner": same,
            }
        )
    return rows


def report_lines(rows: list[dict]) -> list[str]:
    """Human-readable table of :func:`compare`."""
    lines = [f"{'m':>3}{'subsets':>10}{'fast s':>9}{'naive s':>10}{'naive/fast':>12}  note"]
    for row in rows:
        note = (
            "naive extrapolated from a sample"
            if row["naive_extrapolated"]
            else ("same winner" if row["same_winner"] else "DIFFERENT winner")
        )
        lines.append(
            f"{row['m']:>3}{row['subsets']:>10}{row['fast_s']:>9.2f}"
            f"{row['naive_s']:>10.2f}{row['ratio']:>12.1f}  {note}"
        )
    return lines

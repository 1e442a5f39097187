"""Best-subset selection of sensitive points by adjusted R^2 and AICc (the patent).

The patent (CN, "thermal temperature sensitive point optimisation for machine-tool linear axes
based on independent-variable selection criteria", steps 2 and [0046]-[0048]): with m candidate
temperature variables there are 2^m - 1 regression subsets (the constant-only model excluded);
each is scored by the adjusted R^2 criterion (maximum) and the corrected AIC, AICc (minimum),
and the best subset is chosen "by comparing both together". Every model has an intercept.

Criteria for a subset of k sensors, n rows, residual sum of squares RSS and total sum of squares
TSS about the mean (um^2):

- adjusted R^2 = 1 - [RSS / (n - k - 1)] / [TSS / (n - 1)];
- AICc = n ln(RSS / n) + 2K + 2K(K + 1) / (n - K - 1) with K = k + 2 parameters (k slopes,
  intercept, error variance; Hurvich and Tsai 1989, Burnham and Anderson 2002). This is SAS
  GLMSELECT's AICC minus the constant n. Subsets with n - K - 1 <= 0 (k >= n - 3) have no AICc;
  they are excluded from both criteria and counted in ``details``.

Choice rule (``criterion``). In the patent's example both criteria picked all seven sensors;
"after comprehensive analysis" it took the AICc = -89.66 subset {T1, T2, T5} instead, three
sensors with little loss. The rules offered:

- ``"aicc"`` (default): the AICc minimum.
- ``"adj_r2"``: the adjusted-R^2 maximum.
- ``"parsimonious"``: the patent's compromise made explicit -- the smallest subset whose AICc is
  within ``delta_aicc`` (default 2, Burnham and Anderson's "substantial support") of the minimum.

At a fixed size k both criteria are monotone in RSS, so the winners of both are among the
minimum-RSS subsets of each size; the evidence lists exactly those.

Computation (exact, fast). Columns are centred (which removes the intercept exactly) and scaled
to unit norm, and ``[Z, y_c]`` is reduced once by a Householder QR to its (m + 1) x (m + 1)
triangular factor R: for any subset S, regressing R's y column on R's S columns gives the same
RSS as on the n rows, because Q is orthogonal. All subsets of one size are then solved together
by batched Householder QR of the small (m + 1) x (k + 1) blocks R[:, S + y] (``numpy.linalg.qr``
on stacked matrices); RSS is the square of the block's last diagonal entry. This never forms
normal equations, so near-collinear temperature rises (typical) lose no more accuracy than
``lstsq``. A subset is singular -- excluded and counted -- when a diagonal entry of its block is
below 1e-10, i.e. one sensor is a linear combination of the others to 1e-20 in 1 - R^2 (e.g. a
duplicated sensor). m = 16 (65,535 subsets) takes a fraction of a second.

Above ``max_exhaustive`` sensors (default 25) the exhaustive search is replaced by an
approximate per-size search, stated in ``details["search"]``: forward selection gives a start
subset of every size, then the sequential replacement algorithm (Miller 2002, "Subset Selection
in Regression", section 3.5) swaps one sensor in and one out while RSS falls, until no swap
improves it. Both criteria then choose among these per-size subsets.

:func:`best_subset_naive` is the reference: the same enumeration and criteria, but each subset
fitted independently by ``numpy.linalg.lstsq`` on the raw design [1, X_S]; it must give the same
answer (used by the tests and the benchmark).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from math import comb

import numpy as np
import pandas as pd

from pipeline.selection.result import CleanInputs, Selection, clean_inputs

logger = logging.getLogger(__name__)

CRITERIA = ("aicc", "adj_r2", "parsimonious")
SINGULAR_TOLERANCE = 1e-10
_BATCH = 20_000
_MIN_ROWS = 5  # the smallest n with an AICc for a one-sensor model (n - K - 1 > 0, K = 3)

#: Residual sums of squares (um^2) of a batch of subsets (B, k) of column positions, and a
#: flag per subset when its design is singular.
RssFunction = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class _Search:
    """Minimum-RSS subset of each size and what the search counted."""

    subsets: list[tuple[int, ...]]
    rss: list[float]
    n_evaluated: int
    n_undefined: int
    n_singular: int
    description: str


def aicc_defined(k: int, n: int) -> bool:
    """Whether a model with k sensors (plus intercept and variance) has an AICc on n rows.

    Parameters
    ----------
    k : int
        Number of sensors in the subset.
    n : int
        Number of rows.

    Returns
    -------
    bool
        True when n - K - 1 > 0 with K = k + 2.
    """
    return n - (k + 2) - 1 > 0


def criteria(rss: np.ndarray, k: np.ndarray, n: int, tss: float) -> tuple[np.ndarray, np.ndarray]:
    """Compute adjusted R^2 and AICc of intercept models with k sensors.

    Parameters
    ----------
    rss : ndarray of shape (s,)
        Residual sums of squares, um^2.
    k : ndarray of int, shape (s,)
        Number of sensors of each model; ``aicc_defined(k, n)`` must hold.
    n : int
        Number of rows.
    tss : float
        Total sum of squares of the error about its mean, um^2.

    Returns
    -------
    adj_r2, aicc : ndarray of shape (s,)
        Adjusted R^2 (dimensionless) and AICc (dimensionless; -inf for a perfect fit).
    """
    rss = np.asarray(rss, dtype=float)
    k = np.asarray(k)
    n_params = k + 2
    adj_r2 = 1.0 - (rss / (n - k - 1)) / (tss / (n - 1))
    with np.errstate(divide="ignore"):
        log_term = n * np.log(rss / n)
    aicc = log_term + 2 * n_params + 2 * n_params * (n_params + 1) / (n - n_params - 1)
    return adj_r2, aicc


def _combination_chunks(m: int, k: int) -> Iterator[np.ndarray]:
    """All k-subsets of range(m) in lexicographic order, in arrays of at most _BATCH rows."""
    iterator = itertools.combinations(range(m), k)
    while True:
        flat = itertools.chain.from_iterable(itertools.islice(iterator, _BATCH))
        chunk = np.fromiter(flat, dtype=np.intp)
        if chunk.size == 0:
            return
        yield chunk.reshape(-1, k)


def qr_rss_function(temperatures: np.ndarray, error: np.ndarray) -> RssFunction:
    """RSS of subsets by batched Householder QR of the reduced triangular factor.

    Parameters
    ----------
    temperatures : ndarray of shape (n, m)
        Complete, non-constant sensor columns (K).
    error : ndarray of shape (n,)
        Thermal error, um.

    Returns
    -------
    RssFunction
        Maps subsets (B, k) of column positions to (RSS in um^2 (B,), singular flags (B,)).
    """
    centred = temperatures - temperatures.mean(axis=0)
    scaled = centred / np.linalg.norm(centred, axis=0)
    design = np.column_stack([scaled, error - error.mean()])
    r_factor = np.linalg.qr(design, mode="r")
    y_column = design.shape[1] - 1

    def rss_of(subsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        columns = np.concatenate([subsets, np.full((len(subsets), 1), y_column)], axis=1)
        blocks = np.moveaxis(r_factor[:, columns], 0, 1)
        diagonal = np.abs(np.diagonal(np.linalg.qr(blocks, mode="r"), axis1=1, axis2=2))
        k = subsets.shape[1]
        return diagonal[:, k] ** 2, (diagonal[:, :k] < SINGULAR_TOLERANCE).any(axis=1)

    return rss_of


def lstsq_rss_function(temperatures: np.ndarray, error: np.ndarray) -> RssFunction:
    """RSS of subsets by one independent ``numpy.linalg.lstsq`` fit of [1, X_S] per subset.

    Parameters
    ----------
    temperatures : ndarray of shape (n, m)
        Complete, non-constant sensor columns (K).
    error : ndarray of shape (n,)
        Thermal error, um.

    Returns
    -------
    RssFunction
        Maps subsets (B, k) of column positions to (RSS in um^2 (B,), singular flags (B,)):
        singular when lstsq's rank (rcond 1e-10) is below k + 1.
    """
    ones = np.ones((temperatures.shape[0], 1))

    def rss_of(subsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rss = np.empty(len(subsets))
        singular = np.zeros(len(subsets), dtype=bool)
        for row, subset in enumerate(subsets):
            design = np.hstack([ones, temperatures[:, subset]])
            coefficients, _, rank, _ = np.linalg.lstsq(design, error, rcond=SINGULAR_TOLERANCE)
            rss[row] = float(np.sum((error - design @ coefficients) ** 2))
            singular[row] = rank < design.shape[1]
        return rss, singular

    return rss_of


def _exhaustive(rss_of: RssFunction, m: int, n: int, description: str) -> _Search:
    """Minimum-RSS subset of each size over all 2^m - 1 subsets."""
    subsets: list[tuple[int, ...]] = []
    best_rss: list[float] = []
    n_evaluated = n_undefined = n_singular = 0
    for k in range(1, m + 1):
        if not aicc_defined(k, n):
            n_undefined += comb(m, k)
            continue
        size_best, size_rss = None, np.inf
        for chunk in _combination_chunks(m, k):
            rss, singular = rss_of(chunk)
            n_evaluated += len(chunk)
            n_singular += int(singular.sum())
            rss = np.where(singular, np.inf, rss)
            position = int(np.argmin(rss))
            if rss[position] < size_rss:
                size_best, size_rss = tuple(int(i) for i in chunk[position]), float(rss[position])
        if size_best is not None:
            subsets.append(size_best)
            best_rss.append(size_rss)
    return _Search(subsets, best_rss, n_evaluated, n_undefined, n_singular, description)


def _best_of(
    rss_of: RssFunction, candidates: list[tuple[int, ...]]
) -> tuple[tuple[int, ...] | None, float, int]:
    """Lowest-RSS non-singular candidate (first on ties), its RSS, and the singular count."""
    rss, singular = rss_of(np.array(candidates, dtype=np.intp))
    rss = np.where(singular, np.inf, rss)
    position = int(np.argmin(rss))
    if not np.isfinite(rss[position]):
        return None, np.inf, int(singular.sum())
    return candidates[position], float(rss[position]), int(singular.sum())


def _replacement(rss_of: RssFunction, m: int, n: int, max_exhaustive: int) -> _Search:
    """Forward selection, then sequential replacement at each size (approximate)."""
    sizes = [k for k in range(1, m + 1) if aicc_defined(k, n)]
    n_undefined = sum(comb(m, k) for k in range(1, m + 1) if not aicc_defined(k, n))
    n_evaluated = n_singular = 0
    starts: list[tuple[int, ...]] = []
    current: tuple[int, ...] = ()
    for _ in sizes:
        candidates = [tuple(sorted((*current, j))) for j in range(m) if j not in current]
        best, _, singular = _best_of(rss_of, candidates)
        n_evaluated, n_singular = n_evaluated + len(candidates), n_singular + singular
        if best is None:
            break
        starts.append(current := best)
    subsets, best_rss = [], []
    for start in starts:
        subset = start
        rss, _ = rss_of(np.array([subset], dtype=np.intp))
        subset_rss = float(rss[0])
        while True:
            outside = [j for j in range(m) if j not in subset]
            swaps = [
                tuple(sorted((*subset[:p], *subset[p + 1 :], j)))
                for p in range(len(subset))
                for j in outside
            ]
            if not swaps:
                break
            best, swap_rss, singular = _best_of(rss_of, swaps)
            n_evaluated, n_singular = n_evaluated + len(swaps), n_singular + singular
            if best is None or swap_rss >= subset_rss * (1.0 - 1e-12):
                break
            subset, subset_rss = best, swap_rss
        subsets.append(subset)
        best_rss.append(subset_rss)
    description = (
        f"approximate: forward selection + sequential replacement (Miller 2002) because "
        f"m={m} > max_exhaustive={max_exhaustive}"
    )
    return _Search(subsets, best_rss, n_evaluated, n_undefined, n_singular, description)


def _preference_order(rss_of: RssFunction, subset: tuple[int, ...], rss: float) -> list[int]:
    """Sensors of a subset ordered by how much RSS rises when each is dropped (most first)."""
    if len(subset) == 1:
        return list(subset)
    reduced = np.array([[j for j in subset if j != i] for i in subset], dtype=np.intp)
    dropped_rss, _ = rss_of(reduced)
    order = np.argsort(-(dropped_rss - rss), kind="stable")
    return [subset[i] for i in order]


def _check_params(criterion: str, delta_aicc: float) -> None:
    if criterion not in CRITERIA:
        raise ValueError(f"criterion={criterion!r} is unknown; use one of {list(CRITERIA)}")
    if not delta_aicc >= 0.0:
        raise ValueError(f"delta_aicc={delta_aicc} must be >= 0 (AICc units)")


def _selection(
    method: str,
    inputs: CleanInputs,
    search: _Search,
    rss_of: RssFunction,
    criterion: str,
    delta_aicc: float,
) -> Selection:
    """Score the per-size subsets, apply the choice rule and assemble the Selection."""
    if not search.subsets:
        raise ValueError(
            "no subset of sensors has a defined AICc and a non-singular design; supply more rows "
            "or fewer, less collinear sensors"
        )
    names = list(inputs.temperatures.columns)
    y = inputs.error
    n = len(y)
    tss = float(np.sum((y - y.mean()) ** 2))
    sizes = np.array([len(s) for s in search.subsets])
    rss = np.array(search.rss)
    adj_r2, aicc = criteria(rss, sizes, n, tss)
    win_aicc, win_adj = int(np.argmin(aicc)), int(np.argmax(adj_r2))
    if criterion == "aicc":
        chosen, rule = win_aicc, "AICc minimum"
    elif criterion == "adj_r2":
        chosen, rule = win_adj, "adjusted R^2 maximum"
    else:
        chosen = int(np.flatnonzero(aicc <= aicc[win_aicc] + delta_aicc)[0])
        rule = f"smallest subset with AICc <= min AICc + {delta_aicc}"
    evidence = pd.DataFrame(
        {
            "n_sensors": sizes,
            "sensors": ["+".join(names[i] for i in s) for s in search.subsets],
            "rss_um2": rss,
            "adj_r2": adj_r2,
            "aicc": aicc,
            "best_adj_r2": np.arange(len(sizes)) == win_adj,
            "best_aicc": np.arange(len(sizes)) == win_aicc,
            "chosen": np.arange(len(sizes)) == chosen,
            "status": "best of its size",
        }
    )
    ignored = inputs.status_rows().rename(columns={"sensor": "sensors"})
    evidence = pd.concat([evidence, ignored], ignore_index=True)
    order = _preference_order(rss_of, search.subsets[chosen], float(rss[chosen]))
    sensors = [names[i] for i in order]
    details: dict[str, int | float | str] = {
        "criterion": criterion,
        "rule": rule,
        "search": search.description,
        "winner_aicc": evidence.loc[win_aicc, "sensors"],
        "aicc_min": float(aicc[win_aicc]),
        "winner_adj_r2": evidence.loc[win_adj, "sensors"],
        "adj_r2_max": float(adj_r2[win_adj]),
        "n_chosen": len(sensors),
        "n_subsets_evaluated": search.n_evaluated,
        "n_subsets_aicc_undefined": search.n_undefined,
        "n_subsets_singular": search.n_singular,
        "n_rows": n,
        "n_rows_dropped": inputs.n_rows_dropped,
        "n_sensors_used": len(names),
        "n_sensors_ignored": len(inputs.ignored),
    }
    if criterion == "parsimonious":
        details["delta_aicc"] = float(delta_aicc)
    logger.info("%s (%s): %s; %s", method, rule, sensors, search.description)
    return Selection(method, sensors, evidence, details)


def best_subset(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    criterion: str = "aicc",
    max_exhaustive: int = 25,
    delta_aicc: float = 2.0,
) -> Selection:
    """Best subset of sensors by adjusted R^2 and AICc over all 2^m - 1 subsets (fast, exact).

    Parameters
    ----------
    temperatures : DataFrame of shape (n, m)
        Temperature rises (K) or temperatures (degC), one column per sensor; one or several
        campaigns (rows pooled).
    error : array-like of shape (n,)
        Thermal error, um.
    criterion : {"aicc", "adj_r2", "parsimonious"}, default "aicc"
        Choice rule (module docstring).
    max_exhaustive : int, default 25
        Most sensors searched exhaustively; above it the approximate sequential-replacement
        search is used and ``details["search"]`` says so.
    delta_aicc : float, default 2.0
        AICc tolerance of the ``"parsimonious"`` rule; unused otherwise.

    Returns
    -------
    Selection
        ``sensors``: the chosen subset, ordered by the rise in RSS when each is dropped (largest
        first). ``evidence``: one row per subset size with the minimum-RSS subset:
        ``n_sensors``, ``sensors`` (names joined by "+"), ``rss_um2``, ``adj_r2``, ``aicc``,
        ``best_adj_r2``, ``best_aicc``, ``chosen``, ``status``; plus one row per ignored sensor.
        ``details``: ``criterion``, ``rule``, ``search``, ``winner_aicc``, ``aicc_min``,
        ``winner_adj_r2``, ``adj_r2_max``, ``n_chosen``, ``n_subsets_evaluated``,
        ``n_subsets_aicc_undefined``, ``n_subsets_singular``, ``n_rows``, ``n_rows_dropped``,
        ``n_sensors_used``, ``n_sensors_ignored`` (and ``delta_aicc`` for "parsimonious").

    Raises
    ------
    ValueError
        If the inputs are unusable (fewer than 5 complete rows, ...) or a parameter is invalid.
    """
    _check_params(criterion, delta_aicc)
    if not (isinstance(max_exhaustive, int | np.integer) and max_exhaustive >= 1):
        raise ValueError(f"max_exhaustive={max_exhaustive!r} must be a positive integer")
    inputs = clean_inputs(temperatures, error, min_rows=_MIN_ROWS)
    x = inputs.temperatures.to_numpy(dtype=float)
    m, n = x.shape[1], x.shape[0]
    rss_of = qr_rss_function(x, inputs.error)
    if m <= max_exhaustive:
        description = f"exhaustive: all {2**m - 1} subsets, batched QR of the reduced R factor"
        search = _exhaustive(rss_of, m, n, description)
    else:
        search = _replacement(rss_of, m, n, max_exhaustive)
    return _selection("best_subset", inputs, search, rss_of, criterion, delta_aicc)


def best_subset_naive(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    criterion: str = "aicc",
    delta_aicc: float = 2.0,
) -> Selection:
    """Find the best subset by one independent ``lstsq`` fit per subset (the reference).

    Same inputs, rules and outputs as :func:`best_subset` (which must agree with it); slow by
    design -- 2^m - 1 separate least-squares fits -- for tests and the benchmark.

    Parameters
    ----------
    temperatures : DataFrame of shape (n, m)
        Temperature rises (K) or temperatures (degC), one column per sensor.
    error : array-like of shape (n,)
        Thermal error, um.
    criterion : {"aicc", "adj_r2", "parsimonious"}, default "aicc"
        Choice rule.
    delta_aicc : float, default 2.0
        AICc tolerance of the ``"parsimonious"`` rule.

    Returns
    -------
    Selection
        As :func:`best_subset`, with method ``"best_subset_naive"``.
    """
    _check_params(criterion, delta_aicc)
    inputs = clean_inputs(temperatures, error, min_rows=_MIN_ROWS)
    x = inputs.temperatures.to_numpy(dtype=float)
    m, n = x.shape[1], x.shape[0]
    rss_of = lstsq_rss_function(x, inputs.error)
    description = f"naive: all {2**m - 1} subsets, one numpy.linalg.lstsq fit each"
    search = _exhaustive(rss_of, m, n, description)
    return _selection("best_subset_naive", inputs, search, rss_of, criterion, delta_aicc)

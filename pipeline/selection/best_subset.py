"""Best-subset selection of sensitive points by adjusted R^2 and AICc (the patent).

The linear-axis patent (Chinese invention patent "Optimal selection method for the thermal
temperature-sensitive points of a machine tool's linear axis based on independent-variable
selection criteria", published 2022; step 2 and paragraphs [0046]-[0048]): with m candidate
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
triangular factor R: for any subset, regressing R's y column on R's subset columns gives the same
RSS as on the n rows, because Q is orthogonal. The subsets are then the nodes of a tree in which
a child adds one sensor with a larger column position than its parent's last one, and each node
keeps its parent's orthogonalisation: its later columns and y, with the projection on every
chosen column removed (modified Gram-Schmidt, one rank-one update per child; Bjorck's result
that MGS on [A, y] gives a backward-stable residual makes RSS as accurate as ``lstsq``, without
forming normal equations, so near-collinear temperature rises -- typical -- are safe). RSS is
the squared norm of the node's y column. The tree is walked breadth-first, all nodes of a level
with the same last sensor updated together as one array operation; subtrees larger than 2^18
nodes are first split at their root, which bounds memory. A subset is singular -- excluded,
counted, and its whole subtree pruned -- when a sensor's distance from the span of the earlier
ones is below 1e-10 (unit-norm columns: 1 - R^2 < 1e-20, e.g. a duplicated sensor). On 110
rows and one core, m = 16 (65,535 subsets) takes about 0.1 s, m = 20 about 1 s, m = 25 about
40 s (peak memory ~250 MB); the naive loop of lstsq fits is 20-70 times slower.

Ties: among subsets of one size whose RSS agree within 1e-10 (relative), the first in
lexicographic order of column positions is taken, by every search, so the results do not
depend on the enumeration order.

Above ``max_exhaustive`` sensors (default 25) the exhaustive search is replaced by an
approximate per-size search, stated in ``details["search"]``: forward selection gives a start
subset of every size, then the sequential replacement algorithm (Miller 2002, "Subset Selection
in Regression", section 3.5) swaps one sensor in and one out while RSS falls, until no swap
improves it. Both criteria then choose among these per-size subsets.

:func:`best_subset_naive` is the reference: the same criteria over all 2^m - 1 subsets, each
fitted independently by ``numpy.linalg.lstsq`` on the raw design [1, X_S] (singular when its
rank at rcond 1e-10 is below k + 1); it must give the same answer (tests and benchmark).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from math import comb

import numpy as np
import pandas as pd

from pipeline.fit_statistics import information_criteria
from pipeline.selection.result import CleanInputs, Selection, clean_inputs

logger = logging.getLogger(__name__)

CRITERIA = ("aicc", "adj_r2", "parsimonious")
SINGULAR_TOLERANCE = 1e-10
TIE_TOLERANCE = 1e-10
_SUBTREE_SENSORS = 18  # subtrees over at most this many sensors are walked in one go
_BATCH = 20_000  # subsets per lstsq batch of the naive search
_MIN_ROWS = 5  # the smallest n with an AICc for a one-sensor model (n - K - 1 > 0, K = 3)

#: Residual sums of squares (um^2) of a batch of subsets (B, k) of column positions, and a
#: flag per subset when its design is singular.
RssFunction = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def aicc_defined(k: int, n: int) -> bool:
    """Tell whether a model with k sensors (plus intercept and variance) has an AICc on n rows.

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
    adj_r2 = 1.0 - (rss / (n - k - 1)) / (tss / (n - 1))
    _, aicc, _ = information_criteria(rss, n, k + 2)
    return adj_r2, aicc


@dataclass
class _SizeBest:
    """Running minimum-RSS subset of each size, with the search's counts."""

    best: dict[int, tuple[float, tuple[int, ...]]] = field(default_factory=dict)
    n_evaluated: int = 0
    n_singular: int = 0

    def offer(self, subsets: np.ndarray, rss: np.ndarray) -> None:
        """Merge a batch of non-singular subsets of one size (ties: lexicographically first)."""
        if len(rss) == 0:
            return
        tied = np.flatnonzero(rss <= rss.min() * (1.0 + TIE_TOLERANCE))
        position = min(tied, key=lambda i: tuple(subsets[i]))
        candidate = (float(rss[position]), tuple(int(i) for i in subsets[position]))
        k = subsets.shape[1]
        current = self.best.get(k)
        if (
            current is None
            or candidate[0] < current[0] * (1.0 - TIE_TOLERANCE)
            or (candidate[0] <= current[0] * (1.0 + TIE_TOLERANCE) and candidate[1] < current[1])
        ):
            self.best[k] = candidate


@dataclass(frozen=True)
class _Search:
    """Minimum-RSS subset of each size found by a search, and what it counted."""

    subsets: list[tuple[int, ...]]
    rss: list[float]
    n_evaluated: int
    n_undefined: int
    n_singular: int
    description: str


def _finish(sizes: _SizeBest, m: int, n: int, description: str) -> _Search:
    ordered = sorted(sizes.best)
    return _Search(
        subsets=[sizes.best[k][1] for k in ordered],
        rss=[sizes.best[k][0] for k in ordered],
        n_evaluated=sizes.n_evaluated,
        n_undefined=sum(comb(m, k) for k in range(1, m + 1) if not aicc_defined(k, n)),
        n_singular=sizes.n_singular,
        description=description,
    )


def reduced_factor(temperatures: np.ndarray, error: np.ndarray) -> np.ndarray:
    """Triangular factor R of [Z, y_c]: centred unit-norm sensor columns and the centred error.

    Parameters
    ----------
    temperatures : ndarray of shape (n, m)
        Complete, non-constant sensor columns (K).
    error : ndarray of shape (n,)
        Thermal error, um.

    Returns
    -------
    ndarray of shape (min(n, m + 1), m + 1)
        Upper triangular; column j < m stands for sensor j (unit norm), column m for the error
        (norm sqrt(TSS), um). Regressions on its columns have the RSS of those on the rows.
    """
    centred = temperatures - temperatures.mean(axis=0)
    scaled = centred / np.linalg.norm(centred, axis=0)
    return np.linalg.qr(np.column_stack([scaled, error - error.mean()]), mode="r")


def qr_rss_function(r_factor: np.ndarray) -> RssFunction:
    """RSS of any batch of subsets by batched Householder QR of blocks of the reduced factor.

    Parameters
    ----------
    r_factor : ndarray of shape (p, m + 1)
        Output of :func:`reduced_factor`.

    Returns
    -------
    RssFunction
        Maps subsets (B, k) of column positions to (RSS in um^2 (B,), singular flags (B,)).
    """
    y_column = r_factor.shape[1] - 1

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
    temperatures, error : ndarray of shape (n, m), ndarray of shape (n,)
        As for :func:`reduced_factor`.

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


@dataclass(frozen=True)
class _Nodes:
    """Tree nodes of one level sharing their last sensor ``last``.

    ``subsets`` (N, k) column positions; ``columns`` (N, p, m - last): the columns after
    ``last`` and the error, orthogonalised against each node's sensors (R coordinates); ``rss``
    (N,) the squared norm of the error column, um^2.
    """

    subsets: np.ndarray
    columns: np.ndarray
    last: int
    rss: np.ndarray


class _TreeSearch:
    """Exhaustive search over the subset tree by modified Gram-Schmidt updates."""

    def __init__(self, r_factor: np.ndarray, n: int) -> None:
        self.m = r_factor.shape[1] - 1
        defined = [k for k in range(1, self.m + 1) if aicc_defined(k, n)]
        self.max_k = max(defined, default=0)
        self.root = _Nodes(np.empty((1, 0), dtype=np.intp), r_factor[None, :, :], -1, np.empty(1))
        self.sizes = _SizeBest(n_evaluated=sum(comb(self.m, k) for k in defined))

    def run(self) -> _SizeBest:
        """Walk the whole tree; return the minimum-RSS subset of each defined size."""
        if self.max_k:
            self._explore(self.root)
        return self.sizes

    def _children(self, nodes: _Nodes, new: int) -> _Nodes:
        """Children adding sensor ``new``: one rank-one (MGS) update each; singular pruned."""
        k = nodes.subsets.shape[1] + 1
        offset = new - nodes.last - 1
        pivot = nodes.columns[:, :, offset]
        norm = np.sqrt(np.einsum("nr,nr->n", pivot, pivot))
        regular = norm >= SINGULAR_TOLERANCE
        parents, columns = nodes.subsets, nodes.columns
        if not regular.all():
            free = self.m - 1 - new
            pruned = sum(comb(free, t) for t in range(self.max_k - k + 1))
            self.sizes.n_singular += int((~regular).sum()) * pruned
            parents, columns, pivot, norm = (a[regular] for a in (parents, columns, pivot, norm))
        unit = pivot / norm[:, None]
        later = columns[:, :, -1:] if k == self.max_k else columns[:, :, offset + 1 :]
        later = later - unit[:, :, None] * np.einsum("nr,nrc->nc", unit, later)[:, None, :]
        subsets = np.column_stack([parents, np.full(len(parents), new)])
        rss = np.einsum("nr,nr->n", later[:, :, -1], later[:, :, -1])
        return _Nodes(subsets, later, new, rss)

    def _explore(self, node: _Nodes) -> None:
        """Split a large subtree at its root; walk a small one breadth-first."""
        if self.m - 1 - node.last <= _SUBTREE_SENSORS:
            self._breadth_first(node)
            return
        for new in range(node.last + 1, self.m):
            child = self._children(node, new)
            self.sizes.offer(child.subsets, child.rss)
            if len(child.subsets) and child.subsets.shape[1] < self.max_k:
                self._explore(child)

    def _breadth_first(self, root: _Nodes) -> None:
        """Grow the subtree of ``root`` one level at a time, nodes batched by last sensor."""
        level = [root]
        for _ in range(root.subsets.shape[1], self.max_k):
            grown: dict[int, list[_Nodes]] = {}
            for nodes in level:
                for new in range(nodes.last + 1, self.m):
                    grown.setdefault(new, []).append(self._children(nodes, new))
            level = [
                _Nodes(
                    subsets=np.concatenate([g.subsets for g in group]),
                    columns=np.concatenate([g.columns for g in group]),
                    last=new,
                    rss=np.concatenate([g.rss for g in group]),
                )
                for new, group in grown.items()
            ]
            if not level:
                return
            self.sizes.offer(
                np.concatenate([nodes.subsets for nodes in level]),
                np.concatenate([nodes.rss for nodes in level]),
            )


def _combination_chunks(m: int, k: int) -> Iterator[np.ndarray]:
    """All k-subsets of range(m) in lexicographic order, in arrays of at most _BATCH rows."""
    iterator = itertools.combinations(range(m), k)
    while True:
        flat = itertools.chain.from_iterable(itertools.islice(iterator, _BATCH))
        chunk = np.fromiter(flat, dtype=np.intp)
        if chunk.size == 0:
            return
        yield chunk.reshape(-1, k)


def _naive_search(rss_of: RssFunction, m: int, n: int) -> _SizeBest:
    """Every subset of every defined size through ``rss_of``, one batch at a time."""
    sizes = _SizeBest()
    for k in range(1, m + 1):
        if not aicc_defined(k, n):
            continue
        for chunk in _combination_chunks(m, k):
            rss, singular = rss_of(chunk)
            sizes.n_evaluated += len(chunk)
            sizes.n_singular += int(singular.sum())
            sizes.offer(chunk[~singular], rss[~singular])
    return sizes


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


def _replacement(rss_of: RssFunction, m: int, n: int) -> _SizeBest:
    """Forward selection, then sequential replacement at each size (approximate)."""
    sizes = _SizeBest()
    starts: list[tuple[int, ...]] = []
    current: tuple[int, ...] = ()
    for _ in (k for k in range(1, m + 1) if aicc_defined(k, n)):
        candidates = [tuple(sorted((*current, j))) for j in range(m) if j not in current]
        best, _, singular = _best_of(rss_of, candidates)
        sizes.n_evaluated += len(candidates)
        sizes.n_singular += singular
        if best is None:
            break
        starts.append(current := best)
    for subset in starts:
        subset_rss = float(rss_of(np.array([subset], dtype=np.intp))[0][0])
        outside = [j for j in range(m) if j not in subset]
        while outside:
            swaps = [
                tuple(sorted((*subset[:p], *subset[p + 1 :], j)))
                for p in range(len(subset))
                for j in outside
            ]
            best, swap_rss, singular = _best_of(rss_of, swaps)
            sizes.n_evaluated += len(swaps)
            sizes.n_singular += singular
            if best is None or swap_rss >= subset_rss * (1.0 - TIE_TOLERANCE):
                break
            subset, subset_rss = best, swap_rss
            outside = [j for j in range(m) if j not in subset]
        sizes.offer(np.array([subset], dtype=np.intp), np.array([subset_rss]))
    return sizes


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
    rows = np.arange(len(sizes))
    evidence = pd.DataFrame(
        {
            "n_sensors": sizes,
            "sensors": ["+".join(names[i] for i in s) for s in search.subsets],
            "rss_um2": rss,
            "adj_r2": adj_r2,
            "aicc": aicc,
            "best_adj_r2": rows == win_adj,
            "best_aicc": rows == win_aicc,
            "chosen": rows == chosen,
            "status": "best of its size",
        }
    )
    ignored = inputs.status_rows().rename(columns={"sensor": "sensors"})
    ignored[["best_adj_r2", "best_aicc"]] = False
    evidence = pd.concat([evidence, ignored], ignore_index=True)
    evidence["n_sensors"] = evidence["n_sensors"].astype("Int64")
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
        **inputs.counts(),
    }
    if criterion == "parsimonious":
        details["delta_aicc"] = float(delta_aicc)
    logger.debug("%s (%s): %s; %s", method, rule, sensors, search.description)
    return Selection(method, sensors, evidence, details)


def best_subset(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    criterion: str = "aicc",
    max_exhaustive: int = 25,
    delta_aicc: float = 2.0,
) -> Selection:
    """Find the best subset of sensors by adjusted R^2 and AICc over all 2^m - 1 (fast, exact).

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (:mod:`pipeline.selection.result`); campaigns' rows are pooled.
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
        ``best_adj_r2``, ``best_aicc``, ``chosen``, ``status``; plus one row per ignored sensor
        (``sensors`` its name, ``status`` why). ``details``: ``criterion``, ``rule``,
        ``search``, ``winner_aicc``, ``aicc_min``, ``winner_adj_r2``, ``adj_r2_max``,
        ``n_chosen``, ``n_subsets_evaluated`` (exhaustive: subsets of sizes with an AICc;
        approximate: RSS evaluations), ``n_subsets_aicc_undefined``, ``n_subsets_singular``,
        ``n_rows``, ``n_rows_dropped``, ``n_sensors_used``, ``n_sensors_ignored`` (and
        ``delta_aicc`` for "parsimonious").

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
    n, m = x.shape
    r_factor = reduced_factor(x, inputs.error)
    rss_of = qr_rss_function(r_factor)
    if m <= max_exhaustive:
        sizes = _TreeSearch(r_factor, n).run()
        description = f"exhaustive: all {2**m - 1} subsets, MGS updates along the subset tree"
    else:
        sizes = _replacement(rss_of, m, n)
        description = (
            f"approximate: forward selection + sequential replacement (Miller 2002) because "
            f"m={m} > max_exhaustive={max_exhaustive}"
        )
    search = _finish(sizes, m, n, description)
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
    temperatures, error, criterion, delta_aicc
        As for :func:`best_subset`.

    Returns
    -------
    Selection
        As :func:`best_subset`, with method ``"best_subset_naive"``.
    """
    _check_params(criterion, delta_aicc)
    inputs = clean_inputs(temperatures, error, min_rows=_MIN_ROWS)
    x = inputs.temperatures.to_numpy(dtype=float)
    n, m = x.shape
    rss_of = lstsq_rss_function(x, inputs.error)
    description = f"naive: all {2**m - 1} subsets, one numpy.linalg.lstsq fit each"
    search = _finish(_naive_search(rss_of, m, n), m, n, description)
    return _selection("best_subset_naive", inputs, search, rss_of, criterion, delta_aicc)

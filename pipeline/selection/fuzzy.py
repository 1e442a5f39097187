"""FC-GRD: fuzzy clustering of the sensors plus grey relational degree (the PCDL paper).

Miao et al. 2016 (the PCDL paper), section 4.1 and table 3: "all temperature variables are
classified by correlation, so that variables in one class are strongly correlated and variables
in different classes weakly; the measuring point of each class with the largest relational
degree to the thermal deformation is taken as a temperature-sensitive point". The capture gives
no equations; this is the standard fuzzy-equivalence clustering:

1. Fuzzy similarity matrix R (m x m): r_ij = |Pearson correlation| of sensors i and j over the
   pooled complete rows (reflexive and symmetric).
2. Fuzzy equivalence matrix R* = transitive closure of R by max-min composition,
   (R o R)_ij = max_k min(r_ik, r_kj), squaring R -> R^2 -> R^4 ... until R o R = R.
3. Lambda cut: sensors i and j are in one group when r*_ij >= lambda. Each distinct value of R*
   is a level; higher lambda gives more, smaller groups.
4. Number of groups: ``n_groups`` from params (the coarsest cut with at least that many groups),
   or, when None, the classic fuzzy-clustering F test over the levels with 1 < r < m groups
   (objects = the m sensors, each described by its z-scored series; n_j members in group j):

       F = [sum_j n_j ||xbar_j - xbar||^2 / (r - 1)] / [sum_j sum_{i in j} ||x_i - xbar_j||^2
           / (m - r)]  ~  F(r - 1, m - r),

   choosing the level with the largest F among those with F > F_crit = F_{1-alpha}(r - 1, m - r);
   if none is significant, the level with the largest F. When no level has 1 < r < m (e.g.
   fewer than three sensors), the finest cut (largest lambda) is used.
5. In each group the sensor with the largest grey relational degree to the error (rho = 0.5,
   :mod:`pipeline.selection.grey`, degrees computed over all used sensors together).

Deviation: the z-scored series in the F statistic make squared distances proportional to
1 - correlation, consistent with clustering by correlation; a negatively correlated pair (rare
for temperature rises) is close in R but far in F.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
from scipy.special import fdtri

from pipeline.selection.grey import RESOLUTION_COEFFICIENT, grey_relational_degree
from pipeline.selection.result import STATUS_USED, Selection, clean_inputs

logger = logging.getLogger(__name__)


def similarity_matrix(temperatures: pd.DataFrame) -> np.ndarray:
    """Fuzzy similarity matrix of the sensors: absolute Pearson correlations.

    Parameters
    ----------
    temperatures : DataFrame of shape (n, m)
        Complete rows, no constant column (K).

    Returns
    -------
    ndarray of shape (m, m)
        Symmetric, ones on the diagonal, entries in [0, 1].
    """
    similarity = np.abs(np.corrcoef(temperatures.to_numpy(dtype=float), rowvar=False))
    similarity = np.atleast_2d(np.clip(similarity, 0.0, 1.0))
    np.fill_diagonal(similarity, 1.0)
    return similarity


def max_min_compose(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Max-min composition of two fuzzy relations, ``max_k min(left[i, k], right[k, j])``.

    Parameters
    ----------
    left, right : ndarray of shape (m, m)
        Fuzzy relations with entries in [0, 1].

    Returns
    -------
    ndarray of shape (m, m)
    """
    return np.minimum(left[:, :, None], right[None, :, :]).max(axis=1)


def transitive_closure(similarity: np.ndarray) -> np.ndarray:
    """Fuzzy equivalence matrix: transitive closure of a fuzzy similarity matrix.

    Parameters
    ----------
    similarity : ndarray of shape (m, m)
        Reflexive, symmetric fuzzy relation, entries in [0, 1].

    Returns
    -------
    ndarray of shape (m, m)
        The smallest transitive relation containing ``similarity`` (repeated squaring by
        max-min composition; at most ceil(log2 m) + 1 squarings).

    Raises
    ------
    ValueError
        If the matrix is not square, symmetric and reflexive with entries in [0, 1].
    """
    relation = np.asarray(similarity, dtype=float)
    if relation.ndim != 2 or relation.shape[0] != relation.shape[1]:
        raise ValueError(f"similarity matrix must be square, got shape {relation.shape}")
    if not (
        np.allclose(relation, relation.T)
        and np.allclose(np.diag(relation), 1.0)
        and relation.min() >= 0.0
        and relation.max() <= 1.0
    ):
        raise ValueError("similarity matrix must be symmetric, reflexive (ones on the diagonal)")
    while True:
        squared = max_min_compose(relation, relation)
        if np.array_equal(squared, relation):
            return relation
        relation = squared


def lambda_cut_groups(equivalence: np.ndarray, level: float) -> np.ndarray:
    """Label the groups of the lambda cut of a fuzzy equivalence matrix.

    Parameters
    ----------
    equivalence : ndarray of shape (m, m)
        Fuzzy equivalence matrix (transitive closure).
    level : float
        Lambda; i and j share a group when ``equivalence[i, j] >= level``.

    Returns
    -------
    ndarray of int, shape (m,)
        Group labels 1..r, numbered in order of each group's first sensor.
    """
    labels = np.zeros(equivalence.shape[0], dtype=int)
    next_label = 1
    for i in range(equivalence.shape[0]):
        if labels[i] == 0:
            labels[(equivalence[i] >= level) & (labels == 0)] = next_label
            next_label += 1
    return labels


def f_statistic(series: np.ndarray, labels: np.ndarray) -> float:
    """Fuzzy-clustering F statistic of a partition of objects.

    Parameters
    ----------
    series : ndarray of shape (m, p)
        One object (sensor) per row, described by p features (its z-scored series).
    labels : ndarray of int, shape (m,)
        Group of each object; needs 1 < r < m groups.

    Returns
    -------
    float
        Between-group over within-group mean square; inf when the groups have no spread.
    """
    groups = np.unique(labels)
    r, m = len(groups), series.shape[0]
    centre = series.mean(axis=0)
    between = within = 0.0
    for group in groups:
        members = series[labels == group]
        group_centre = members.mean(axis=0)
        between += len(members) * float(np.sum((group_centre - centre) ** 2))
        within += float(np.sum((members - group_centre) ** 2))
    if within == 0.0:
        return float("inf")
    return (between / (r - 1)) / (within / (m - r))


def cluster_levels(temperatures: pd.DataFrame, alpha: float = 0.05) -> pd.DataFrame:
    """Every lambda level of the sensors' fuzzy equivalence matrix with its groups and F test.

    Parameters
    ----------
    temperatures : DataFrame of shape (n, m)
        Complete rows, no constant column (K).
    alpha : float, default 0.05
        Significance level of the F test.

    Returns
    -------
    DataFrame
        One row per level, lambda descending: ``lambda``, ``n_groups``, ``F``, ``F_crit``
        (NaN where 1 < n_groups < m does not hold), ``groups`` (labels joined by commas).
    """
    equivalence = transitive_closure(similarity_matrix(temperatures))
    values = temperatures.to_numpy(dtype=float)
    zscored = ((values - values.mean(axis=0)) / values.std(axis=0)).T
    m = values.shape[1]
    rows = []
    for level in np.unique(equivalence)[::-1]:
        labels = lambda_cut_groups(equivalence, float(level))
        r = int(labels.max())
        testable = 1 < r < m
        rows.append(
            {
                "lambda": float(level),
                "n_groups": r,
                "F": f_statistic(zscored, labels) if testable else float("nan"),
                "F_crit": float(fdtri(r - 1, m - r, 1.0 - alpha)) if testable else np.nan,
                "groups": ",".join(map(str, labels)),
            }
        )
    return pd.DataFrame(rows)


def _choose_level(levels: pd.DataFrame, n_groups: int | None, alpha: float) -> tuple[int, str]:
    """Row position in ``levels`` of the chosen cut, and the rule that chose it."""
    if n_groups is not None:
        position = int(np.flatnonzero(levels["n_groups"].to_numpy() >= n_groups)[-1])
        return position, f"n_groups={n_groups} from params (coarsest cut with at least that many)"
    testable = levels["F"].notna().to_numpy()
    if not testable.any():
        return 0, "no cut with 1 < n_groups < m: no F test; finest cut"
    significant = testable & (levels["F"] > levels["F_crit"]).to_numpy()
    candidates = significant if significant.any() else testable
    f_values = np.where(candidates, levels["F"].to_numpy(), -np.inf)
    position = int(np.argmax(f_values))
    if significant.any():
        return position, f"F test: largest F among F > F_crit (alpha={alpha})"
    return position, f"F test: no F > F_crit (alpha={alpha}); largest F"


def fc_grd(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    n_groups: int | None = None,
    rho: float = RESOLUTION_COEFFICIENT,
    alpha: float = 0.05,
) -> Selection:
    """FC-GRD sensitive points: fuzzy clustering by correlation, then grey relational degree.

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (:mod:`pipeline.selection.result`); campaigns' rows are pooled.
    n_groups : int or None, default None
        Number of groups; None chooses it by the F test (module docstring).
    rho : float, default 0.5
        Resolution coefficient of the grey relational degree.
    alpha : float, default 0.05
        Significance level of the F test.

    Returns
    -------
    Selection
        ``sensors``: one per group, by grey relational degree descending. ``evidence``: one row
        per sensor with ``sensor``, ``group``, ``grd``, ``chosen``, ``status`` (ignored sensors
        have NaN group and grd). ``details``: ``lambda``, ``n_groups``, ``F``, ``F_crit``,
        ``rule``, ``rho``, ``n_rows``, ``n_rows_dropped``, ``n_sensors_used``,
        ``n_sensors_ignored``.

    Raises
    ------
    ValueError
        If the inputs are unusable or ``n_groups`` is not between 1 and the number of used
        sensors.
    """
    inputs = clean_inputs(temperatures, error)
    used = list(inputs.temperatures.columns)
    if n_groups is not None and not (
        isinstance(n_groups, int | np.integer) and 1 <= n_groups <= len(used)
    ):
        raise ValueError(
            f"n_groups={n_groups!r} must be an integer between 1 and the {len(used)} usable "
            f"sensors {used}, or None to choose it by the F test"
        )
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha={alpha} must lie in (0, 1)")
    levels = cluster_levels(inputs.temperatures, alpha)
    position, rule = _choose_level(levels, n_groups, alpha)
    chosen_level = levels.iloc[position]
    labels = np.array(chosen_level["groups"].split(","), dtype=int)
    degrees = grey_relational_degree(inputs.error, inputs.temperatures.to_numpy(), rho)
    evidence = pd.DataFrame(
        {"sensor": used, "group": labels, "grd": degrees, "status": STATUS_USED}
    )
    best = evidence.sort_values(["grd"], ascending=False, kind="stable").groupby("group").head(1)
    evidence["chosen"] = evidence.index.isin(best.index)
    sensors = list(best["sensor"])
    evidence = evidence.sort_values(["group", "grd"], ascending=[True, False], kind="stable")
    evidence = inputs.with_ignored(evidence, "group")
    details: dict[str, int | float | str] = {
        "lambda": float(chosen_level["lambda"]),
        "n_groups": int(chosen_level["n_groups"]),
        "F": float(chosen_level["F"]),
        "F_crit": float(chosen_level["F_crit"]),
        "rule": rule,
        "rho": float(rho),
        **inputs.counts(),
    }
    logger.debug("fc_grd: %d groups at lambda=%.4f -> %s", len(best), details["lambda"], sensors)
    return Selection("fc_grd", sensors, evidence, details)

"""Correlation grouping of temperature sensors (Lo, Yuan and Ni 1999, cited by the PCDL paper).

Lo, C.-H., Yuan, J. and Ni, J., "Optimal temperature variable selection by grouping approach for
thermal error modeling and compensation", Int. J. Mach. Tools Manuf. 39 (1999) 1383-1396
(reference [16] of the PCDL paper): sensors whose readings are strongly correlated carry the same
information, so they are put in one group and only one representative per group -- the one most
correlated with the thermal error -- enters the model.

Grouping rule (the PCDL paper does not spell it out; greedy leader clustering, documented here):
order the usable sensors by |correlation with the error| descending (ties: column order); the
first sensor not yet grouped leads a new group, which takes every ungrouped sensor whose
|correlation| with the leader exceeds ``threshold``; repeat until every sensor is grouped. Each
leader is by construction the member most correlated with the error, so the leaders are the
selection, in order. Unlike connected components, a group never chains through intermediate
sensors: every member exceeds the threshold with its representative. Correlations are Pearson
over the pooled complete rows.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from pipeline.selection.result import STATUS_USED, Selection, clean_inputs

logger = logging.getLogger(__name__)


def correlation_grouping(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    threshold: float = 0.9,
) -> Selection:
    """Group mutually correlated sensors; keep the one most correlated with the error per group.

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (:mod:`pipeline.selection.result`); campaigns' rows are pooled.
    threshold : float, default 0.9
        A sensor joins a leader's group when their |correlation| exceeds this, in (0, 1).

    Returns
    -------
    Selection
        ``sensors``: the group leaders by |correlation with the error| descending.
        ``evidence``: one row per sensor with ``sensor``, ``group`` (1 = leader most correlated
        with the error), ``r_error`` (signed correlation with the error), ``abs_r_leader``
        (|correlation| with its group's leader, 1 for the leader), ``chosen``, ``status``.
        ``details``: ``threshold``, ``n_groups``, ``rule``, ``n_rows``, ``n_rows_dropped``,
        ``n_sensors_used``, ``n_sensors_ignored``.

    Raises
    ------
    ValueError
        If the inputs are unusable or ``threshold`` is outside (0, 1).
    """
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold={threshold} must lie in (0, 1); the default is 0.9")
    inputs = clean_inputs(temperatures, error)
    used = list(inputs.temperatures.columns)
    values = np.column_stack([inputs.temperatures.to_numpy(dtype=float), inputs.error])
    correlation = np.atleast_2d(np.corrcoef(values, rowvar=False))
    r_error = correlation[:-1, -1]
    mutual = np.abs(correlation[:-1, :-1])
    group = np.zeros(len(used), dtype=int)
    abs_r_leader = np.full(len(used), np.nan)
    leaders: list[int] = []
    for candidate in np.argsort(-np.abs(r_error), kind="stable"):
        if group[candidate]:
            continue
        leaders.append(int(candidate))
        members = (group == 0) & (mutual[candidate] > threshold)
        members[candidate] = True
        group[members] = len(leaders)
        abs_r_leader[members] = mutual[candidate, members]
        abs_r_leader[candidate] = 1.0
    evidence = pd.DataFrame(
        {
            "sensor": used,
            "group": group,
            "r_error": r_error,
            "abs_r_leader": abs_r_leader,
            "chosen": np.isin(np.arange(len(used)), leaders),
            "status": STATUS_USED,
        }
    ).sort_values(["group", "abs_r_leader"], ascending=[True, False], kind="stable")
    evidence = inputs.with_ignored(evidence, "group")
    sensors = [used[i] for i in leaders]
    details: dict[str, int | float | str] = {
        "threshold": float(threshold),
        "n_groups": len(leaders),
        "rule": "greedy leaders by |r| with the error; members |r| with leader > threshold",
        **inputs.counts(),
    }
    logger.debug("correlation_grouping: %d groups -> %s", len(leaders), sensors)
    return Selection("correlation_grouping", sensors, evidence, details)

"""Shared views of the run list: each machine and axis' candidates ranked, scores as columns.

The MLflow UI (3.x) keeps a run list's columns in the browser, not in its address, but it opens
a *shared view* stored as the experiment tag ``mlflow.sharedViewState.<key>`` (JSON: the
search facets ``searchFilter``, ``orderByKey``, ``orderByAsc`` and the UI state
``selectedColumns``, ``runsHiddenMode``...) when the address carries
``viewStateShareKey=<key>``. The track stage writes two per machine and axis, pointing at the
machine's latest pipeline run (the machine as :func:`pipeline.machines.machine_key` writes it):

- ``ranked-<machine>-<axis>``: the eligible candidates, best first on the axis' ranking score,
  with the held-out and validation scores per season as columns;
- ``all-<machine>-<axis>``: every candidate, ineligible ones included, with ``eligible`` and
  ``ineligible_reason``.

Pure: :mod:`pipeline.tracking.store` writes the tags.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from urllib.parse import quote

from pipeline.machines import machine_key
from pipeline.tracking.records import GROUPS_TABLE, PARENT_RUN_TAG, RunRecord

SHARED_VIEW_TAG = "mlflow.sharedViewState."
SHOW_ALL_RUNS = "SHOW_ALL"
"""``runsHiddenMode``: the chart view plots every run, not the first ten."""


def column(kind: str, name: str) -> str:
    """Return the UI's column key, e.g. ``metrics.`loso_Mn_rms_um```."""
    return f"{kind}.`{name}`"


def view_key(kind: str, machine: str, axis: str) -> str:
    """Return the share key of a view, e.g. ``ranked-vmc-450-Z``."""
    return f"{kind}-{machine_key(machine)}-{axis}"


def _score_columns(children: Sequence[RunRecord], ranked_by: str) -> list[str]:
    """Ranking score, its eta, the per-group scores logged as metrics, the validation score."""
    logged = {name for child in children for name in child.metrics}
    groups = {
        (row["split"], str(row["held_out"])): row["name"]
        for child in children
        for row in child.tables.get(GROUPS_TABLE, [])
    }
    scheme = ranked_by.split("_", 1)[0]
    wanted = [ranked_by, f"{scheme}_eta"]
    wanted += [groups[key] for key in sorted(groups) if key[0] == "train"]
    wanted += ["pooled_Mn_val_rms_um"]
    wanted += [groups[key] for key in sorted(groups) if key[0] == "validation"]
    return [column("metrics", name) for name in wanted if name in logged]


def shared_views(
    parent_id: str, children: Sequence[RunRecord], ranked_by: dict[str, str], machine: str
) -> dict[str, str]:
    """Return the shared views of every axis of a machine: share key -> JSON state.

    Parameters
    ----------
    parent_id : str
        The pipeline run whose children the views list.
    children : sequence of RunRecord
        Its child records (tags ``axis``, metrics).
    ranked_by : dict
        Axis -> the score its candidates are ranked by (``loso_Mn_rms_um``...).
    machine : str
        The machine the parent run is of.
    """
    views = {}
    for axis, score in ranked_by.items():
        mine = [child for child in children if child.tags.get("axis") == axis]
        if not score or not mine:
            continue
        scores = _score_columns(mine, score)
        where = f"tags.`{PARENT_RUN_TAG}` = '{parent_id}' and tags.axis = '{axis}'"
        common = {
            "orderByKey": column("metrics", score),
            "orderByAsc": True,
            "runsHiddenMode": SHOW_ALL_RUNS,
        }
        ranked = [column("tags", "rank"), column("tags", "champion"), *scores]
        every = [column("tags", name) for name in ("eligible", "rank", "ineligible_reason")]
        views[view_key("ranked", machine, axis)] = json.dumps(
            {
                **common,
                "searchFilter": f"{where} and tags.eligible = 'true'",
                "selectedColumns": ranked,
            }
        )
        views[view_key("all", machine, axis)] = json.dumps(
            {**common, "searchFilter": where, "selectedColumns": [*every, *scores[:2]]}
        )
    return views


def view_path(experiment_id: str, key: str) -> str:
    """Return the UI path (after the host) of a shared view of the experiment's run list."""
    return (
        f"/#/experiments/{experiment_id}/runs?workflowType=machine_learning"
        f"&viewStateShareKey={quote(key)}"
    )

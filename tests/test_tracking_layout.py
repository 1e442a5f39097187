"""The MLflow layout: every score name explained, the headline capped, evidence complete."""

from __future__ import annotations

import json
import logging
import re

import pandas as pd

from pipeline.protocol.scoring import SCHEME_PREFIX, candidate_summary, group_score_name, summarise
from pipeline.tracking import guide, records, views
from tests.helpers.score_rows import two_campaigns_and_a_season


def _statistic(column: str) -> str:
    """``loso_Mn_val_rms_um`` -> ``Mn_val_um``: the statistic the guide explains."""
    for prefix in sorted(SCHEME_PREFIX.values(), key=len, reverse=True):
        if prefix and column.startswith(prefix):
            column = column[len(prefix) :]
            break
    return column.replace("_rms_um", "_um")


def test_the_experiment_description_explains_every_score_name():
    scores = two_campaigns_and_a_season()
    columns = [c for c in candidate_summary(scores).columns if c not in records.KEY_COLUMNS]
    assert {_statistic(c) for c in columns} <= set(guide.STATISTICS)
    statistics = "S Mn Sd Mn_val Sd_val S_rms Mn_rms Sd_rms Mn_val_rms Sd_val_rms".split()
    assert set(summarise(scores)) - {"eta", "eta_val"} <= {f"{s}_um" for s in statistics}
    text = guide.experiment_description("thermal-error")
    for statistic in guide.STATISTICS:
        assert f"`{statistic}`" in text
    for scheme, prefix in SCHEME_PREFIX.items():
        assert scheme in guide.SCHEMES and (not prefix or f"`{prefix}`" in text)
    for mode in ("static", "free_run", "one_step"):
        assert f"`{mode}`" in text
    for pattern in guide.GROUPS:  # the per-group names follow the documented patterns
        assert f"`{pattern}`" in text
    names = [
        group_score_name("loso", "train", "winter", "rms_um"),
        group_score_name("loco", "train", "K07", "rms_um"),
        group_score_name("pooled", "validation", "winter", "rms_um"),
    ]
    patterns = [
        re.escape(p)
        .replace(re.escape("<season>"), "[a-z]+")
        .replace(re.escape("<campaign>"), "K[0-9]+")
        for p in guide.GROUPS
    ]
    assert all(any(re.fullmatch(p, name) for p in patterns) for name in names)


def _inputs(n_groups: int) -> records.ChildInputs:
    key = ("Z", "mlr", "all", "static")
    groups = [
        {
            "scheme": "loco",
            "split": "train",
            "held_out": f"K{i:03d}",
            "n_campaigns": 1,
            "rms_um": 1.0 + i,
            "uncompensated_rms_um": 50.0,
            "eta": 1 - (1.0 + i) / 50.0,
            "name": group_score_name("loco", "train", f"K{i:03d}", "rms_um"),
        }
        for i in range(n_groups)
    ]
    summary = {"loco_Mn_rms_um": 3.0, "loco_eta": 0.9, "S_um": 0.2}
    standing = records.Standing(True, "", 1, True)
    return records.ChildInputs(
        scores={
            key: [
                {
                    "train_unit": "not_K000",
                    "test_campaign": "K000",
                    "rmse_um": 1.0,
                    "resid_std_um": 0.5,
                    "eta": 0.98,
                }
            ]
        },
        summaries={key: (summary, standing)},
        groups={key: groups},
        units={key: []},
        fits={},
        ranked_by={"Z": "loco_Mn_rms_um"},
        heatmaps={},
        champions=frozenset({key}),
    )


def test_a_child_carries_at_most_100_metrics_and_the_rest_in_its_tables(caplog):
    with caplog.at_level(logging.WARNING):
        (child,) = records.child_records(_inputs(80))
    assert len(child.metrics) == records.MAX_CHILD_METRICS
    assert {"loco_Mn_rms_um", "loco_eta", "S_um", "loco_K000_rms_um", "loco_K000_eta"} <= set(
        child.metrics
    )
    assert len(child.tables[records.GROUPS_TABLE]) == 80  # every group in the table
    assert "the rest are in heldout_scores.json" in caplog.text
    (small,) = records.child_records(_inputs(3))
    assert len(small.metrics) == 3 + 2 * 3
    assert small.tags["champion"] == "true" and small.tags["rank"] == "1"
    assert "K002 3.00 um" in small.tags[records.NOTE_TAG]


def test_group_scores_read_back_from_csv_give_the_same_child_metrics(tmp_path):
    rows = pd.DataFrame(_inputs(2).groups[("Z", "mlr", "all", "static")])
    rows.insert(0, "axis", "Z")
    path = tmp_path / "heldout.csv"
    rows.assign(model="mlr", selection="all", mode="static").to_csv(path, index=False)
    read = pd.read_csv(path, keep_default_na=False).to_dict("records")
    metrics = records.group_metrics(records.groups_by_child(read)[("Z", "mlr", "all", "static")])
    assert metrics == {
        "loco_K000_rms_um": 1.0,
        "loco_K000_eta": 0.98,
        "loco_K001_rms_um": 2.0,
        "loco_K001_eta": 0.96,
    }


def test_the_shared_views_list_an_axis_children_ranked_with_their_scores_as_columns():
    (child,) = records.child_records(_inputs(3))
    other = records.RunRecord("X/mlr/all/static", tags={"axis": "X"}, metrics={"S_um": 1.0})
    ranked_by = {"Z": "loco_Mn_rms_um", "X": ""}
    shared = views.shared_views("p1", [child, other], ranked_by, "DMU 50")
    assert set(shared) == {"ranked-DMU-50-Z", "all-DMU-50-Z"}  # X has no ranking score: no view
    ranked = json.loads(shared["ranked-DMU-50-Z"])
    assert ranked["searchFilter"] == (
        "tags.`mlflow.parentRunId` = 'p1' and tags.axis = 'Z' and tags.eligible = 'true'"
    )
    assert (ranked["orderByKey"], ranked["orderByAsc"]) == ("metrics.`loco_Mn_rms_um`", True)
    assert ranked["selectedColumns"] == [
        "tags.`rank`",
        "tags.`champion`",
        "metrics.`loco_Mn_rms_um`",
        "metrics.`loco_eta`",
        "metrics.`loco_K000_rms_um`",
        "metrics.`loco_K001_rms_um`",
        "metrics.`loco_K002_rms_um`",
    ]
    assert "eligible" not in json.loads(shared["all-DMU-50-Z"])["searchFilter"]
    assert views.view_path("4", "ranked-DMU-50-Z") == (
        "/#/experiments/4/runs?workflowType=machine_learning&viewStateShareKey=ranked-DMU-50-Z"
    )

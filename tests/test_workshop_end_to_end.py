"""End-to-end on a user-shaped folder: the real `dvc repro` on the twin's workshop preset.

Six back-to-back campaigns cut from one 46-h run (every campaign but the first starts warm),
sampled every two minutes (slower than the models' 60-s window: a sixth of the preset's rows),
16 sensors whose places are unknown (all ``role: other``), X, Y and Z probes, one season, no
validation split, a measured speed log. Nothing in the pipeline may stop on it: the twin is
untestable, every axis is scored leave-one-campaign-out (neighbours in the record buffered) and
forward in time, ranked forward (the campaigns are cut from one record), registered and never
worse than no compensation. Test data for robustness, not a target to tune to.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml
from mlflow.tracking import MlflowClient

from pipeline.twin.workshop import WORKSHOP_MACHINE as MACHINE
from tests.helpers.mlflow_server import running_mlflow_server
from tests.helpers.repository import copy_repository

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
AXES = ["X", "Y", "Z"]
CANDIDATES = {
    "none": "none",
    "mlr": ["all", "best_subset"],
    "ridge": ["all", "all_speed"],
    "twin": "roles",
}
METHODS = ("all", "all_speed", "best_subset")


def _run(command: list[str], cwd: Path, env: dict[str, str]) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True)
    assert result.returncode == 0, f"{command} failed:\n{result.stdout}\n{result.stderr}"
    return result.stdout + result.stderr


@pytest.fixture(scope="module")
def workshop(tmp_path_factory):
    """A copy of the repository whose data/raw is the workshop preset, after one dvc repro."""
    tmp = tmp_path_factory.mktemp("workshop")
    work = copy_repository(ROOT, tmp / "repo")
    shutil.rmtree(work / "data" / "raw")
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["evaluate"]["candidates"] = CANDIDATES  # the slow series models are left out
    params["select"]["methods"] = {m: params["select"]["methods"][m] for m in METHODS}
    (work / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    with running_mlflow_server(tmp / "server") as uri:
        env = {
            **os.environ,
            "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}",
            "MLFLOW_TRACKING_URI": uri,
        }
        _run(
            [str(BIN / "thermal"), "simulate", "--preset", "workshop", "--out", "data/raw"]
            + ["--interval-s", "120"],
            work,
            env,
        )
        output = _run([str(BIN / "dvc"), "repro"], work, env)
        client = MlflowClient(tracking_uri=uri)
        experiment = client.get_experiment_by_name(params["track"]["experiment"])
        runs = client.search_runs([experiment.experiment_id], max_results=1000)
        versions = {
            axis: client.get_model_version_by_alias(
                f"thermal-error-spindle-{MACHINE}-{axis}", "champion"
            )
            for axis in AXES
        }
        yield work, output, runs, versions


def _json(work: Path, relative: str):
    return json.loads((work / relative).read_text())


def test_the_twin_comparison_is_untestable_and_the_pipeline_goes_on(workshop):
    work, output, _, _ = workshop
    assert "Running stage 'track'" in output
    disc = _json(work, f"reports/discrepancy/{MACHINE}/discrepancy.json")
    assert disc["status"] == "untestable" and disc["roles_present"] == ["other"]
    assert "spindle_front_bearing" in disc["needed_roles"]
    metrics = _json(work, "metrics/cross_season.json")["machines"][MACHINE]
    assert "structure role" in metrics["Z"]["skipped"]["twin/roles"]
    assert "Z drift only" in metrics["X"]["skipped"]["twin/roles"]
    report = (work / "reports" / "model_comparison.md").read_text()
    assert "`twin/roles` not scored" in report


def test_back_to_back_campaigns_are_one_run_counted_from_its_cold_start(workshop):
    work, _, _, _ = workshop
    runs = _json(work, "data/separated/spindle_runs.json")["machines"][MACHINE]
    (run,) = runs["runs"]
    assert run["campaigns"] == [f"W0{i}" for i in range(1, 7)]
    assert all(link["how"] == "detected" and link["contiguous"] for link in run["links"])
    table = pd.read_parquet(work / "data" / "separated" / "spindle_thermal_error.parquet")
    warm = table.groupby("campaign_id")["warm_start"].first()
    assert not warm["W01"] and warm.drop("W01").all()
    assert set(table["axis"]) == set(AXES)
    speed = [c for c in table.columns if c.startswith("speed")]
    assert len(speed) == 8 and table[speed].notna().all().all()
    report = (work / "reports" / "model_comparison.md").read_text()
    assert "continues run W01 without a break and starts warm" in report


def test_every_axis_is_scored_held_out_ranked_forward_and_registered(workshop):
    work, _, runs, versions = workshop
    scores = pd.read_csv(work / "reports" / "cross_season_scores.csv")
    assert set(scores["axis"]) == set(AXES)
    assert set(scores["scheme"]) == {"campaign", "loco", "forward", "pooled"}
    assert {f"not_W0{i}" for i in range(1, 7)} <= set(scores["train_unit"])
    # the rolling origin: W04-W06 each forecast by the campaigns before it (at least 3 of 6)
    forward = scores[scores["scheme"] == "forward"]
    pairs = set(zip(forward["train_unit"], forward["test_campaign"], strict=True))
    assert pairs == {(f"before_W0{i}", f"W0{i}") for i in (4, 5, 6)}
    # leave-one-campaign-out leaves the neighbours in the record out: W02 and W04 for W03
    not_w03 = scores[(scores["train_unit"] == "not_W03")]
    assert not {"W02", "W04"} & set(not_w03["test_campaign"])
    assert scores["eta"].notna().all()
    children = [r for r in runs if "mlflow.parentRunId" in r.data.tags]
    keys = scores.groupby(["axis", "model", "selection", "mode"]).ngroups
    assert len(children) == keys
    report = (work / "reports" / "model_comparison.md").read_text()
    assert report.count("Ranked by **rolling origin (forward in time)**") == 3
    assert report.count("No independent check exists") == 3
    for axis in AXES:
        card = _json(work, f"data/models/champion/{MACHINE}/{axis}/champion.json")
        version = versions[axis]
        champion = next(r for r in children if r.info.run_id == version.run_id)
        assert champion.data.tags["champion"] == "true" and champion.data.tags["axis"] == axis
        assert card["protocol"] == "forward" and card["other_protocols"] == ["loco"]
        assert "continuous record" in card["ranking_reason"]
        held_out = card["scores"]["forward_Mn_rms_um"]
        assert held_out <= card["none_score_um"]  # never worse than no compensation
        if card["compensate"]:
            assert held_out <= 0.9 * card["none_score_um"]
        needs_speed = any(name.startswith("speed") for name in card["inputs"])
        assert version.tags["needs_speed_log"] == str(needs_speed).lower()


def test_the_replayed_compensation_leaves_what_the_champion_left_offline(workshop):
    work, _, _, _ = workshop
    document = _json(work, "reports/compensation/compensation.json")["machines"][MACHINE]
    assert set(document["axes"]) == set(AXES)
    for axis, record in document["axes"].items():
        proof = record["proof"]
        # W04-W06, each forecast by the campaigns before it, replayed from the run's cold start
        assert proof["n_campaigns"] == 3, axis
        assert proof["ratio"] <= 1.1, (axis, proof)
        table = pd.read_csv(work / "reports" / "compensation" / MACHINE / axis / "proof.csv")
        assert set(table["campaign_id"]) == {"W04", "W05", "W06"}
        assert set(table["unit"]) == {"before_W04", "before_W05", "before_W06"}
    budget = pd.read_csv(work / "reports" / "sensor_budget.csv")
    assert set(budget["axis"]) == set(AXES) and budget["heldout_rms_um"].notna().all()

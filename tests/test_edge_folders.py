"""Contract-valid folders with nothing, or too little, to model: every stage says so and goes on.

Each test copies a few demo campaigns into a fresh folder and runs the stages' ``main`` there in
order (the commands `dvc repro` runs), with a local MLflow store.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from pipeline.stages import evaluate, ingest, select, separate_spindle, track, validate

ROOT = Path(__file__).resolve().parents[1]
MACHINE = "vmc-450-twin"
"""The demo campaigns' machine."""


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """A working folder with params.yaml (three candidates) and an empty data/raw."""
    params = yaml.safe_load((ROOT / "params.yaml").read_text())
    params["evaluate"]["candidates"] = {"none": "none", "mlr": "all", "twin": "roles"}
    params["select"]["methods"] = {"all": {"inputs": "temperatures"}}
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    (tmp_path / "data" / "raw").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    return tmp_path


def _stages(folder: Path, *campaigns: str) -> dict:
    for campaign in campaigns:
        shutil.copytree(ROOT / "data" / "raw" / campaign, folder / "data" / "raw" / campaign)
    for stage, argv in (
        (ingest, []),
        (validate, []),
        (separate_spindle, []),
        (select, []),
        (evaluate, []),
        (track, []),
    ):
        assert stage.main(argv) == 0, stage.__name__
    return json.loads((folder / "metrics" / "cross_season.json").read_text())


def test_a_folder_without_spindle_campaigns_writes_empty_outputs_and_says_why(folder):
    metrics = _stages(folder, "Y01", "Y02")
    assert metrics == {"machines": {}}
    runs = json.loads((folder / "data" / "separated" / "spindle_runs.json").read_text())
    assert runs["machines"] == {} and "no spindle thermal error to model" in runs["note"]
    assert pd.read_parquet(folder / "data" / "separated" / "spindle_thermal_error.parquet").empty
    assert pd.read_csv(folder / "reports" / "cross_season_scores.csv").empty
    report = (folder / "reports" / "model_comparison.md").read_text()
    assert "**Nothing to model**" in report
    record = json.loads((folder / "reports" / "mlflow_run.json").read_text())
    assert record["machines"] == {}  # no machine has a model: no run


def test_validation_campaigns_alone_give_no_model_and_the_reason(folder):
    metrics = _stages(folder, "V01", "V02")
    skipped = metrics["machines"][MACHINE]["Z"]["skipped"]["axis"]
    assert "no training campaign measured axis Z" in skipped
    report = (folder / "reports" / "model_comparison.md").read_text()
    assert f"## Machine {MACHINE}, axis Z\n\nNo model: no training campaign" in report


def test_a_single_training_campaign_registers_no_compensation(folder):
    metrics = _stages(folder, "K01", "V01")
    assert metrics["machines"][MACHINE]["Z"]["champion"]["compensate"] is False
    card_path = folder / "data" / "models" / "champion" / MACHINE / "Z" / "champion.json"
    card = json.loads(card_path.read_text())
    assert card["model"] == "none" and card["protocol"] is None and card["machine"] == MACHINE
    assert "single training campaign" in card["reason"]
    record = json.loads((folder / "reports" / "mlflow_run.json").read_text())["machines"][MACHINE]
    assert record["champions"]["Z"]["version"] == "1"
    report = (folder / "reports" / "model_comparison.md").read_text()
    assert "**Do not compensate axis Z with these inputs.**" in report

"""The discrepancy stage on campaigns the twin cannot be compared with: a report, exit 0."""

from __future__ import annotations

import json
import logging
import re
import shutil

import yaml

from benchmarks.discrepancy_trials import write_hidden_campaigns
from pipeline.config import load_section
from pipeline.discrepancy.workflow import STRUCTURE_ROLES
from pipeline.stages.discrepancy import main
from pipeline.twin.campaigns import MACHINE
from tests.helpers.processes import free_port


def _params(tmp_path, *more: str):
    params = {
        "ingest": load_section("ingest"),
        "validate": load_section("validate"),
        "discrepancy": {"candidates": ["motor_heat"], "n_folds": 2, "n_jobs": 1},
        **{name: load_section(name) for name in more},
    }
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(params), encoding="utf-8")
    return path


def _run(tmp_path):
    argv = ["--raw", str(tmp_path / "raw"), "--out", str(tmp_path / "out")]
    code = main([*argv, "--params", str(_params(tmp_path)), "--no-mlflow"])
    out = tmp_path / "out" / MACHINE  # one folder per machine
    doc = json.loads((out / "discrepancy.json").read_text(encoding="utf-8"))
    md = (out / "discrepancy.md").read_text(encoding="utf-8")
    return code, doc, md


def test_campaigns_whose_sensors_have_no_role_are_untestable_not_an_error(tmp_path):
    write_hidden_campaigns(tmp_path / "raw", frozenset(), seed=5, n=3)
    for folder in (tmp_path / "raw").iterdir():
        path = folder / "campaign.yaml"
        path.write_text(re.sub(r"role: \w+", "role: other", path.read_text()), encoding="utf-8")

    code, doc, md = _run(tmp_path)

    assert code == 0
    assert doc["status"] == "untestable"
    assert doc["named_effects"] == []
    assert doc["roles_present"] == ["other"]
    assert doc["needed_roles"] == list(STRUCTURE_ROLES)
    assert "no sensor has a structure role" in doc["reason"]
    assert sorted(doc["campaigns"]) == ["H01", "H02", "H03"]
    assert "Untestable on these campaigns" in md and "`spindle_front_bearing`" in md
    assert not (tmp_path / "out" / MACHINE / "heldout_fit.png").exists()


def test_a_single_campaign_is_untestable_and_says_how_many_are_needed(tmp_path):
    write_hidden_campaigns(tmp_path / "raw", frozenset(), seed=5, n=2)
    shutil.rmtree(tmp_path / "raw" / "H02")

    code, doc, md = _run(tmp_path)

    assert code == 0
    assert doc["status"] == "untestable"
    assert doc["campaigns"] == ["H01"]
    assert "at least 2" in doc["reason"] and "at least 2" in md


def test_an_unreachable_tracking_server_leaves_the_report_and_exits_0(
    tmp_path, monkeypatch, caplog
):
    write_hidden_campaigns(tmp_path / "raw", frozenset(), seed=5, n=2)
    shutil.rmtree(tmp_path / "raw" / "H02")
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"http://127.0.0.1:{free_port()}")
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
    argv = ["--raw", str(tmp_path / "raw"), "--out", str(tmp_path / "out")]
    record = tmp_path / "out" / "run.json"
    params = _params(tmp_path, "tracking")
    with caplog.at_level(logging.WARNING, logger="pipeline.stages.discrepancy"):
        code = main([*argv, "--params", str(params), "--run-record", str(record)])

    assert code == 0
    assert "MLflow logging failed" in caplog.text and "the report files are written" in caplog.text
    doc = json.loads((tmp_path / "out" / MACHINE / "discrepancy.json").read_text(encoding="utf-8"))
    assert doc["status"] == "untestable" and "mlflow_run_id" not in doc
    assert json.loads(record.read_text(encoding="utf-8")) == {"machines": {MACHINE: None}}

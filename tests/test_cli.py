import importlib
import json
import subprocess
import sys

import pytest

from pipeline.cli import COMMANDS, main


def test_python_m_pipeline_lists_every_command():
    result = subprocess.run(
        [sys.executable, "-m", "pipeline", "--help"], capture_output=True, text=True
    )
    assert result.returncode == 0
    for name in COMMANDS:
        assert f"  {name} " in result.stdout


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_module_has_a_main(name):
    module = importlib.import_module(COMMANDS[name][0])
    assert callable(module.main)


def test_unknown_command_is_a_usage_error(capsys):
    assert main(["fly"]) == 2
    assert "unknown command 'fly'" in capsys.readouterr().err


def test_summary_points_at_the_mlflow_ui(tmp_path, capsys):
    assert main(["summary", "--root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "mlflow ui --backend-store-uri sqlite:///mlflow.db" in out
    assert "twin vs data" not in out  # no discrepancy report yet


def test_summary_says_what_the_twin_comparison_named(tmp_path, capsys):
    doc = {
        "named_effects": ["motor_heat"],
        "rmse_um_before": 3.641,
        "rmse_um_after": 3.65,
        "validation": {"rmse_um_before": 5.37, "rmse_um_after": 4.81},
    }
    (tmp_path / "reports" / "discrepancy" / "vmc-450").mkdir(parents=True)
    (tmp_path / "reports" / "discrepancy" / "vmc-450" / "discrepancy.json").write_text(
        json.dumps(doc)
    )
    assert main(["summary", "--root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "  machine vmc-450\n" in out
    assert "named motor_heat; held-out Z 3.64 -> 3.65 um, validation Z 5.37 -> 4.81 um" in out


def test_import_lists_its_sources_and_refuses_an_unknown_one(capsys):
    assert main(["import", "--help"]) == 0
    out = capsys.readouterr().out
    assert "logger" in out and "rtl" in out
    assert main(["import", "csv2000"]) == 2
    assert "unknown source 'csv2000'" in capsys.readouterr().err


def test_import_hands_its_arguments_to_the_importer(tmp_path, capsys):
    missing = tmp_path / "nothing.rtl"
    assert (
        main(["import", "rtl", str(missing), "--out", str(tmp_path / "A01"), "--warmup-min", "0"])
        == 2
    )
    assert "nothing.rtl" in capsys.readouterr().err
    assert not (tmp_path / "A01" / "laser.csv").exists()


def test_summary_says_why_the_twin_comparison_was_untestable(tmp_path, capsys):
    doc = {"status": "untestable", "reason": "no sensor has a structure role"}
    (tmp_path / "reports" / "discrepancy" / "lathe").mkdir(parents=True)
    (tmp_path / "reports" / "discrepancy" / "lathe" / "discrepancy.json").write_text(
        json.dumps(doc)
    )
    assert main(["summary", "--root", str(tmp_path)]) == 0
    assert "untestable (no sensor has a structure role)" in capsys.readouterr().out


def test_a_user_error_is_a_message_and_exit_code_1_not_a_traceback(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # no params.yaml, no data/ingested
    assert main(["validate"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("thermal validate: error: params.yaml not found")
    (tmp_path / "params.yaml").write_text("validate: [not, a, mapping\n")
    assert main(["validate"]) == 1
    assert "params.yaml cannot be read as YAML" in capsys.readouterr().err


def test_an_internal_error_keeps_its_traceback(monkeypatch):
    def broken(argv):
        raise RuntimeError("bug")

    monkeypatch.setattr(importlib.import_module("pipeline.reporting.summary"), "main", broken)
    with pytest.raises(RuntimeError, match="bug"):
        main(["summary"])


def _tracking_record(**extra) -> dict:
    """A ``reports/mlflow_run.json`` of a local store, one machine."""
    return {
        "tracking_uri": "sqlite:///mlflow.db",
        "experiment": "thermal-error",
        "machines": {
            "vmc-450": {"experiment_id": "7", "parent_run_id": "abc", "champions": {}, **extra}
        },
    }


def test_summary_links_the_run_list_not_the_genai_overview(tmp_path, capsys):
    record = _tracking_record()
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "mlflow_run.json").write_text(json.dumps(record))
    assert main(["summary", "--root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "http://127.0.0.1:5000/#/experiments/7?workflowType=machine_learning" in out


def test_summary_says_what_the_promotion_gate_decided(tmp_path, capsys):
    decision = {
        "axis": "Z",
        "action": "keep",
        "challenger_version": "3",
        "reason": "Kept, not better by the margin: 1.20 um against 1.00 um",
    }
    record = _tracking_record(promotion=[decision])
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "mlflow_run.json").write_text(json.dumps(record))
    assert main(["summary", "--root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "gate Z           keep v3: kept, not better by the margin: 1.20 um" in out
    assert "reports/promotion/promotion.md" in out

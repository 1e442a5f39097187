import importlib
import subprocess
import sys

import pytest

from pipeline.cli import COMMANDS, main


def test_python_m_pipeline_lists_every_command():
    result = subprocess.run([sys.executable, "-m", "pipeline", "--help"],
                            capture_output=True, text=True)  # fmt: skip
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
    assert "mlflow ui --backend-store-uri sqlite:///mlflow.db" in capsys.readouterr().out

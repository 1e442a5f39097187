"""Nothing is lost when the MLflow server cannot be reached, and nothing is logged twice.

A real ``mlflow server`` is started and stopped; ``dvc repro`` runs against the stopped server
(its stages' outputs must stay, the message must say how to log later, no traceback), then the
server is restarted on the same backend store and the execution is logged: by ``dvc repro``
(which reruns only ``track``) and by ``thermal track`` (which must reuse the logged run). An
incomplete attempt left in the store by a connection lost mid-way is deleted, not duplicated.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mlflow.entities import RunStatus
from mlflow.tracking import MlflowClient

from pipeline.tracking import records, store
from tests.helpers.mlflow_server import running_mlflow_server
from tests.helpers.repository import copy_repository

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
OUTPUTS = (
    "reports/cross_season_scores.csv",
    "metrics/cross_season.json",
    "reports/model_comparison.md",
    "data/models/champion",
)


def _small_repository(tmp_path: Path) -> Path:
    """A copy of the repository with one demo campaign per season and two candidates."""
    work = copy_repository(ROOT, tmp_path / "repo")
    keep = {"K01", "K04", "K07", "K10"}
    for folder in (work / "data" / "raw").iterdir():
        if folder.name not in keep:
            shutil.rmtree(folder)
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["evaluate"]["candidates"] = {"none": "none", "mlr": "all"}
    params["select"]["methods"] = {"all": {"inputs": "temperatures"}}
    params["discrepancy"].update(candidates=["motor_heat"], n_folds=2)
    (work / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    return work


def _run(command: list[str], work: Path, uri: str) -> subprocess.CompletedProcess:
    env = {
        **os.environ,
        "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}",
        "MLFLOW_TRACKING_URI": uri,
    }
    return subprocess.run(command, cwd=work, env=env, capture_output=True, text=True)


def _parents(client: MlflowClient, identity: str, view: str = "ACTIVE_ONLY") -> list:
    experiment = client.get_experiment_by_name("thermal-error")
    runs = client.search_runs(
        [experiment.experiment_id],
        filter_string=f"tags.{records.IDENTITY_TAG} = '{identity}'",
        run_view_type={"ACTIVE_ONLY": 1, "ALL": 3}[view],
    )
    return [r for r in runs if records.PARENT_RUN_TAG not in r.data.tags]


def test_stopped_server_keeps_the_outputs_and_a_later_track_logs_them_once(tmp_path):
    work = _small_repository(tmp_path)
    with running_mlflow_server(tmp_path) as stopped_uri:
        assert MlflowClient(tracking_uri=stopped_uri).search_experiments()  # up, store made
    # ... and stopped now: the pipeline below runs against an unreachable server

    failed = _run([str(BIN / "dvc"), "repro"], work, stopped_uri)

    assert failed.returncode != 0
    output = failed.stdout + failed.stderr
    assert "Traceback" not in output
    assert "Nothing is lost" in output and "thermal track" in output
    for name in OUTPUTS:
        assert (work / name).exists(), name
    scores = (work / OUTPUTS[0]).read_bytes()
    lock = yaml.safe_load((work / "dvc.lock").read_text())["stages"]
    assert lock["evaluate"]["cmd"] == "bin/thermal evaluate"
    status = _run([str(BIN / "dvc"), "status"], work, stopped_uri).stdout
    assert "evaluate" not in status and "track" in status

    with running_mlflow_server(tmp_path) as uri:
        client = MlflowClient(tracking_uri=uri)
        # A connection lost mid-way left an incomplete attempt of the same execution.
        identity = _identity(work, uri)
        experiment_id = store.ensure_experiment(client, "thermal-error", None)
        partial = client.create_run(experiment_id, tags={records.IDENTITY_TAG: identity})
        client.create_run(experiment_id, tags={records.PARENT_RUN_TAG: partial.info.run_id})
        client.set_terminated(partial.info.run_id, RunStatus.to_string(RunStatus.FAILED))

        repro = _run([str(BIN / "dvc"), "repro"], work, uri)
        assert repro.returncode == 0, repro.stderr
        assert "Running stage 'track'" in repro.stdout
        assert "Running stage 'evaluate'" not in repro.stdout
        logged = json.loads((work / "reports" / "mlflow_run.json").read_text())
        assert logged["reused"] is False and logged["run_identity"] == identity

        again = _run([str(BIN / "thermal"), "track"], work, uri)
        assert again.returncode == 0, again.stderr
        assert json.loads((work / "reports" / "mlflow_run.json").read_text())["reused"] is True

        parents = _parents(client, identity)
        assert [p.info.run_id for p in parents] == [logged["parent_run_id"]]
        assert client.get_run(partial.info.run_id).info.lifecycle_stage == "deleted"
        children = client.search_runs(
            [experiment_id],
            filter_string=f"tags.{records.PARENT_RUN_TAG} = '{logged['parent_run_id']}'",
        )
        assert {r.data.params["model"] for r in children} == {"none", "mlr"}
    assert (work / OUTPUTS[0]).read_bytes() == scores


def _identity(work: Path, uri: str) -> str:
    """The run identity ``thermal track`` computes for the outputs in ``work``."""
    code = (
        "import json, pathlib, pipeline.tracking.pipeline_run as t; "
        "print(t.prepare(pathlib.Path('params.yaml')).identity.value)"
    )
    done = _run([sys.executable, "-c", code], work, uri)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().splitlines()[-1]

"""Two machines in one ``data/raw``: each is modelled on its own, and stays so as campaigns arrive.

The workshop twin writes one two-day run of six campaigns for each of two machines
(``benchmarks.bench_scale.write_fleet``); the second machine's sensors are renamed ``S1..S8`` and
half of them dropped, so the folder's temperature columns are the union of two sensor sets. A
real ``dvc repro`` logs to a real ``mlflow server``. Then a campaign is added to the second
machine and ``dvc repro`` runs again. Each machine's scores are compared with those of the
stages run on that machine's campaigns alone.
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

from benchmarks.bench_scale import write_fleet
from pipeline.stages import evaluate, ingest, select, separate_spindle, validate
from tests.helpers.mlflow_server import running_mlflow_server
from tests.helpers.repository import copy_repository

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
FIRST, SECOND = "workshop-1", "workshop-2"
KEYS = ["axis", "model", "selection", "mode", "scheme", "train_unit", "test_campaign", "role"]
ADDED = "M2X01"
"""The campaign added to the second machine, a week after its run."""


def _run(command: list[str], cwd: Path, env: dict[str, str]) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True)
    assert result.returncode == 0, f"{command} failed:\n{result.stdout}\n{result.stderr}"
    return result.stdout + result.stderr


def _own_sensors(folder: Path) -> None:
    """Give a campaign of the second machine sensors of its own: S1..S8 (T9..T16 dropped)."""
    meta = yaml.safe_load((folder / "campaign.yaml").read_text())
    meta["sensors"] = {
        f"S{name[1:]}": spec for name, spec in meta["sensors"].items() if int(name[1:]) <= 8
    }
    (folder / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    table = pd.read_csv(folder / "temperature.csv", dtype=str)
    table = table[["elapsed_s", *[f"T{i}" for i in range(1, 9)]]]
    table.columns = ["elapsed_s", *[f"S{i}" for i in range(1, 9)]]
    table.to_csv(folder / "temperature.csv", index=False)


def _add_campaign(raw: Path) -> None:
    """Copy the second machine's first campaign as a campaign of a week later, cold."""
    shutil.copytree(raw / "M2R1W01", raw / ADDED)
    path = raw / ADDED / "campaign.yaml"
    meta = yaml.safe_load(path.read_text())
    start = pd.Timestamp(meta["start"]) + pd.Timedelta(days=7)
    meta.update(campaign_id=ADDED, start=start.isoformat(), start_state="cold")
    path.write_text(yaml.safe_dump(meta, sort_keys=False))


def _params(path: Path) -> None:
    """Two candidates, the Z axis, one selection method: the partitions are tested, not models."""
    params = yaml.safe_load(path.read_text())
    params["evaluate"]["candidates"] = {"none": "none", "mlr": "all"}
    params["select"]["methods"] = {"all": {"inputs": "temperatures"}}
    params["separate"]["displacement_axis"] = ["Z"]
    params["discrepancy"].update(candidates=["motor_heat"], n_folds=2)
    path.write_text(yaml.safe_dump(params, sort_keys=False))


def _record(work: Path) -> dict:
    return json.loads((work / "reports" / "mlflow_run.json").read_text())["machines"]


def _scores(path: Path, machine: str) -> pd.DataFrame:
    scores = pd.read_csv(path)
    rows = scores[scores["machine"] == machine].drop(columns="machine")
    return rows.sort_values(KEYS).reset_index(drop=True)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """The two machines' repro, then the repro after a campaign was added to the second."""
    tmp = tmp_path_factory.mktemp("fleet")
    work = copy_repository(ROOT, tmp / "repo")
    raw = work / "data" / "raw"
    shutil.rmtree(raw)
    raw.mkdir()
    write_fleet(raw, machines=2, campaigns=6)
    for folder in raw.glob("M2*"):
        _own_sensors(folder)
    _params(work / "params.yaml")
    with running_mlflow_server(tmp) as uri:
        env = {
            **os.environ,
            "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}",
            "MLFLOW_TRACKING_URI": uri,
        }
        first = _run([str(BIN / "dvc"), "repro"], work, env)
        before = {
            "record": _record(work),
            "scores": (work / "reports" / "cross_season_scores.csv").read_bytes(),
            "card": (work / "data/models/champion" / FIRST / "Z/champion.json").read_bytes(),
        }
        shutil.copy(work / "reports" / "cross_season_scores.csv", tmp / "scores_before.csv")
        _add_campaign(raw)
        second = _run([str(BIN / "dvc"), "repro"], work, env)
        yield {
            "work": work,
            "tmp": tmp,
            "first": first,
            "second": second,
            "before": before,
            "client": MlflowClient(tracking_uri=uri),
        }


def test_each_machine_gets_its_champion_registered_under_its_name(fleet):
    record, client = fleet["before"]["record"], fleet["client"]
    assert sorted(record) == [FIRST, SECOND]
    for machine in (FIRST, SECOND):
        champion = record[machine]["champions"]["Z"]
        assert champion["registered_model"] == f"thermal-error-spindle-{machine}-Z"
        version = client.get_model_version_by_alias(champion["registered_model"], "champion")
        assert version.tags["machine"] == machine
        parent = client.get_run(record[machine]["parent_run_id"])
        assert parent.data.tags["machine"] == machine
        card = json.loads(
            (fleet["work"] / "data/models/champion" / machine / "Z/champion.json").read_text()
        )
        own = "S" if machine == SECOND else "T"
        assert card["machine"] == machine
        assert all(name.startswith((own, "speed")) for name in card["inputs"]), card["inputs"]
    table = pd.read_parquet(fleet["work"] / "data/separated/spindle_thermal_error.parquet")
    first = table[table["machine"] == FIRST]
    assert first["S1"].isna().all() and first["T16"].notna().all()
    assert table.loc[table["machine"] == SECOND, "T1"].isna().all()
    report = (fleet["work"] / "reports" / "model_comparison.md").read_text()
    assert f"## Machine {FIRST}, axis Z" in report and f"## Machine {SECOND}, axis Z" in report


@pytest.mark.parametrize("machine", [FIRST, SECOND])
def test_each_machines_scores_are_those_of_the_machine_alone(fleet, machine, tmp_path, monkeypatch):
    alone = tmp_path / "alone"
    shutil.copytree(fleet["work"] / "data" / "raw", alone / "data" / "raw")
    prefix = "M1" if machine == FIRST else "M2"
    for folder in (alone / "data" / "raw").iterdir():
        if not folder.name.startswith(prefix) or folder.name == ADDED:
            shutil.rmtree(folder)
    shutil.copy(fleet["work"] / "params.yaml", alone / "params.yaml")
    monkeypatch.chdir(alone)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    for stage in (ingest, validate, separate_spindle, select, evaluate):
        assert stage.main([]) == 0, stage.__name__
    together = _scores(fleet["tmp"] / "scores_before.csv", machine)
    own = _scores(alone / "reports" / "cross_season_scores.csv", machine)
    assert len(together) > 50
    pd.testing.assert_frame_equal(together, own)


def test_a_campaign_of_one_machine_leaves_the_other_machines_fits_and_runs(fleet):
    work, before, second = fleet["work"], fleet["before"], fleet["second"]
    for stage in ("select", "evaluate", "discrepancy", "compensation"):
        assert f"{stage}, machine {FIRST}: its inputs, params and code are unchanged" in second
        assert f"{stage}, machine {SECOND}: its inputs" not in second
    after = work / "reports" / "cross_season_scores.csv"
    previous = fleet["tmp"] / "scores_before.csv"
    pd.testing.assert_frame_equal(_scores(after, FIRST), _scores(previous, FIRST))
    assert ADDED in set(_scores(after, SECOND)["test_campaign"])
    card = (work / "data/models/champion" / FIRST / "Z/champion.json").read_bytes()
    assert card == before["card"]
    record = _record(work)
    assert record[FIRST]["reused"] is True
    assert record[FIRST]["parent_run_id"] == before["record"][FIRST]["parent_run_id"]
    assert record[SECOND]["reused"] is False
    assert record[SECOND]["parent_run_id"] != before["record"][SECOND]["parent_run_id"]
    client = fleet["client"]
    versions = {
        machine: len(client.search_model_versions(f"name = 'thermal-error-spindle-{machine}-Z'"))
        for machine in (FIRST, SECOND)
    }
    assert versions == {FIRST: 1, SECOND: 2}

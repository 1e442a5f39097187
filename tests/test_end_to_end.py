"""End-to-end: the real `dvc repro` on a copy of the repository (demo campaigns), real MLflow.

The demo pipeline runs once, in full (on a third of the demo's spindle campaigns,
:data:`DEMO_KEPT`), against a real ``mlflow server`` (:func:`demo`) set up as a team runs it: its
runs in a PostgreSQL server and its artifacts in an S3 server (``docs/team-server.md``), or, where
no PostgreSQL server can be started, in SQLite and a folder (the PostgreSQL test then reports itself
skipped). Its ``evaluate`` runs once more on a real Dask cluster, to the same scores. The tests of
the next campaigns, a new one and a malformed one, share one continuation of a copy of that finished
run (:func:`next_run`), as a user's next ``dvc repro`` does, so that only the stages the change
reaches run again. That continuation runs while no MLflow server answers at its tracking URI (the
server is down): nothing may be lost (the stages' outputs stay, the message says how to log later,
no traceback); then the server is up and the execution is logged once, by ``dvc repro`` (which
reruns only ``track``) and by ``thermal track`` (which reuses the logged run); an incomplete attempt
left by a connection lost mid-way is deleted, not duplicated.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import psycopg
import pytest
import yaml
from distributed import Client
from mlflow.entities import RunStatus
from mlflow.tracking import MlflowClient

from pipeline import cluster
from pipeline.tracking import records, store
from tests.helpers.dask_cluster import running_dask_cluster
from tests.helpers.mlflow_server import running_mlflow_server
from tests.helpers.postgres_server import unavailable_reason
from tests.helpers.processes import free_port
from tests.helpers.repository import copy_repository
from tests.helpers.s3_server import s3_client
from tests.helpers.team_server import BUCKET, TeamServer, running_team_server

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
KEYS = ["axis", "model", "selection", "mode"]
MACHINE = "vmc-450-twin"
"""The demo campaigns' machine."""


def _env(uri: str) -> dict[str, str]:
    return {
        **os.environ,
        "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}",
        "MLFLOW_TRACKING_URI": uri,
    }


def _run(command: list[str], cwd: Path, env: dict[str, str]) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True)
    assert result.returncode == 0, f"{command} failed:\n{result.stdout}\n{result.stderr}"
    return result.stdout + result.stderr


def _repro(work: Path, env: dict[str, str]) -> str:
    return _run([str(BIN / "dvc"), "repro"], work, env)


def _experiment() -> str:
    return yaml.safe_load((ROOT / "params.yaml").read_text())["track"]["experiment"]


def _scores(work: Path) -> pd.DataFrame:
    return pd.read_csv(work / "reports" / "cross_season_scores.csv")


def _record(work: Path) -> dict:
    """The demo machine's track record, beside the store and the experiment it shares."""
    document = json.loads((work / "reports" / "mlflow_run.json").read_text())
    assert list(document["machines"]) == [MACHINE]
    shared = {key: value for key, value in document.items() if key != "machines"}
    return {**shared, **document["machines"][MACHINE]}


@dataclass(frozen=True)
class Demo:
    """The finished demo run: its repository copy, the server's URI and the repro's output."""

    work: Path
    uri: str
    output: str
    team: TeamServer | None


DEMO_CANDIDATES = {
    "none": "none",
    "mlr": ["all", "best_subset"],
    "dl": "fc_grd",
    "pls_dl": "gra_top_k",
    "arma": "none",
    "twin": "roles",
}
"""One candidate of each kind: the plain regression, the lagged models (the demo's champion
family), a model on the error's own history (scored one-step and free-run) and the twin. Every
model's fit is tested on its own; ``make run`` runs them all."""
DEMO_KEPT = ("K01", "K04", "K07", "K10", "V01", "V02")
"""The demo's spindle campaigns of this run: the first training campaign of each season and two
validation campaigns of one validation season (the linear-axis campaigns all stay). Every scheme
(each campaign, each season left out, all training campaigns, the validation split) is still
scored, on a third of the spindle campaigns: the run's cost grows with their number and with its
square, and what it proves (every stage runs, every score reaches MLflow, the next campaign
reruns only what it reaches) does not need more."""
SPINDLE_CAMPAIGNS = sorted(DEMO_KEPT)
"""The spindle campaigns of this run."""
TWIN_CALIBRATION = {"max_nfev": 20}
"""The twin's calibrations cut short: this run proves the twin is calibrated on every training
unit, scored and logged; how well it fits is tested on its own (``test_twin_candidate.py``)."""


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("demo")
    work = copy_repository(ROOT, tmp / "repo")
    for campaign in (work / "data" / "raw").iterdir():
        if campaign.name[0] in "KV" and campaign.name not in DEMO_KEPT:
            shutil.rmtree(campaign)
    _fewer_candidates(work, DEMO_CANDIDATES)
    if unavailable_reason() is not None:
        with running_mlflow_server(tmp / "server") as uri:
            yield Demo(work, uri, _repro(work, _env(uri)), None)
        return
    with running_team_server(tmp / "server") as team:
        yield Demo(work, team.uri, _repro(work, _env(team.uri)), team)


def _continue_from(demo: Demo, destination: Path) -> Path:
    """A copy of the finished demo run (outputs, DVC cache, git) without its MLflow store."""
    ignore = shutil.ignore_patterns("mlflow.db", "mlartifacts")
    shutil.copytree(demo.work, destination, symlinks=True, ignore=ignore)
    return destination


def _fewer_candidates(work: Path, candidates: dict[str, str | list[str]]) -> None:
    """Keep the copy's pipeline short: only these candidates and the selections they read, the
    twin's calibrations cut short, and one candidate effect (the one the demo's twin lacks) in two
    folds in the discrepancy search."""
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["evaluate"]["candidates"] = candidates
    read = {
        m
        for chosen in candidates.values()
        for m in ([chosen] if isinstance(chosen, str) else chosen)
    }
    methods = params["select"]["methods"]
    params["select"]["methods"] = {name: spec for name, spec in methods.items() if name in read}
    params["discrepancy"].update(candidates=["motor_heat"], n_folds=2)
    if "twin" in candidates:
        params["evaluate"]["model_params"] = {"twin": TWIN_CALIBRATION}
    (work / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))


NEXT_CANDIDATES = {"none": "none", "mlr": "all", "dl": "fc_grd"}


OUTPUTS = (
    "reports/cross_season_scores.csv",
    "metrics/cross_season.json",
    "reports/model_comparison.md",
    "data/models/champion",
)
"""Outputs that must stay when ``track`` cannot reach the server."""


@dataclass(frozen=True)
class NextRun:
    """The demo run continued with a new campaign (K13) and a malformed one (K99) in ``data/raw``.

    ``before``: the demo's scores of :data:`NEXT_CANDIDATES`; ``offline``: the continued ``dvc
    repro`` while the server is down, ``output`` its printout, ``status`` the ``dvc status``
    after it, ``scores`` the scores file it wrote; ``again``: one more ``dvc repro`` on unchanged
    inputs, the server up, after an incomplete attempt (``partial``, a run id) of the
    same execution (``identity``) was left in the store; ``logged`` and ``reused``: the run
    records of that repro and of a ``thermal track`` after it; ``client``: the server's, once
    up; ``raw_bytes``: K99's files as written.
    """

    work: Path
    before: pd.DataFrame
    offline: subprocess.CompletedProcess
    output: str
    status: str
    scores: bytes
    again: str
    identity: str
    partial: str
    logged: dict
    reused: dict
    client: MlflowClient
    raw_bytes: dict[Path, bytes]


def _add_malformed_campaign(raw: Path) -> dict[Path, bytes]:
    """K99, a copy of K01 with the DS18B20 power-on value in data row 1 of T3; its bytes."""
    bad = raw / "K99"
    shutil.copytree(raw / "K01", bad)
    meta = yaml.safe_load((bad / "campaign.yaml").read_text())
    meta["campaign_id"] = "K99"
    (bad / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    temperature = pd.read_csv(bad / "temperature.csv", dtype=str)
    temperature.loc[0, "T3"] = "85.0"
    temperature.to_csv(bad / "temperature.csv", index=False)
    return {path: path.read_bytes() for path in bad.iterdir()}


@pytest.fixture(scope="module")
def next_run(demo, tmp_path_factory) -> Iterator[NextRun]:
    """One continued run for the new-campaign, malformed-campaign and stopped-server tests."""
    tmp = tmp_path_factory.mktemp("next")
    work = _continue_from(demo, tmp / "repo")
    before = _scores(work)
    pairs = before[["model", "selection"]].apply(tuple, axis=1)
    before = before[pairs.isin(NEXT_CANDIDATES.items())].reset_index(drop=True)
    _fewer_candidates(work, NEXT_CANDIDATES)
    env = _env(f"http://127.0.0.1:{free_port()}")  # the server down: nothing answers there
    simulate = (
        "simulate --preset single --id K13 --season summer --rpm 4000 --seed 13 --out data/raw"
    )
    _run([str(BIN / "thermal"), *simulate.split()], work, env)
    raw_bytes = _add_malformed_campaign(work / "data" / "raw")
    offline = subprocess.run(
        [str(BIN / "dvc"), "repro"], cwd=work, env=env, capture_output=True, text=True
    )
    status = _run([str(BIN / "dvc"), "status"], work, env)
    scores = (work / OUTPUTS[0]).read_bytes()
    with running_mlflow_server(tmp) as uri:
        client = MlflowClient(tracking_uri=uri)
        identity = _identity(work, uri)
        partial = _incomplete_attempt(client, identity)
        again = _repro(work, _env(uri))
        logged = _record(work)
        _run([str(BIN / "thermal"), "track"], work, _env(uri))
        reused = _record(work)
        yield NextRun(
            work,
            before,
            offline,
            offline.stdout + offline.stderr,
            status,
            scores,
            again,
            identity,
            partial,
            logged,
            reused,
            client,
            raw_bytes,
        )


def _identity(work: Path, uri: str) -> str:
    """The run identity ``thermal track`` computes for the outputs in ``work``."""
    code = (
        "import pathlib, pipeline.tracking.pipeline_run as t; "
        "print(t.prepare(pathlib.Path('params.yaml'), 'vmc-450-twin').identity.value)"
    )
    return _run([sys.executable, "-c", code], work, _env(uri)).strip().splitlines()[-1]


def _incomplete_attempt(client: MlflowClient, identity: str) -> str:
    """Leave what a connection lost mid-way leaves: a FAILED parent with a child; its run id."""
    experiment_id = store.ensure_experiment(client, _experiment(), None)
    partial = client.create_run(experiment_id, tags={records.IDENTITY_TAG: identity})
    client.create_run(experiment_id, tags={records.PARENT_RUN_TAG: partial.info.run_id})
    client.set_terminated(partial.info.run_id, RunStatus.to_string(RunStatus.FAILED))
    return partial.info.run_id


def test_new_campaign_is_scored_old_scores_kept_unrelated_stages_skipped(next_run):
    work, before, output = next_run.work, next_run.before, next_run.output
    assert "K13" not in set(before["test_campaign"])
    assert "Stage 'separate_axis' didn't change, skipping" in output
    for stage in ("ingest", "validate", "separate_spindle", "select", "evaluate", "discrepancy"):
        assert f"Running stage '{stage}'" in output
    disc = json.loads((work / "reports" / "discrepancy" / MACHINE / "discrepancy.json").read_text())
    assert "K13" in disc["campaigns"]
    after = _scores(work)
    assert "K13" in set(after["train_unit"]) and "K13" in set(after["test_campaign"])
    assert len(after) > len(before)
    # Models built without K13 (each campaign alone; the seasons other than summer) keep
    # their scores; the others now include it.
    keys = ["axis", "model", "selection", "mode", "train_unit", "test_campaign"]
    unchanged = before[(before["scheme"] == "campaign") | (before["train_unit"] == "not_summer")]
    merged = unchanged.merge(after, on=keys, suffixes=("_before", "_after"), validate="1:1")
    assert len(merged) == len(unchanged)
    for score in ("rmse_um", "resid_std_um"):
        pd.testing.assert_series_equal(
            merged[f"{score}_before"], merged[f"{score}_after"], check_names=False
        )
    assert "Running stage 'evaluate'" not in next_run.again


def test_a_stopped_server_keeps_the_outputs_and_a_later_track_logs_them_once(next_run):
    offline, work = next_run.offline, next_run.work
    assert offline.returncode != 0
    assert "Traceback" not in next_run.output
    assert "Nothing is lost" in next_run.output and "thermal track" in next_run.output
    assert "MLflow logging failed" in next_run.output  # the discrepancy report stands without it
    for name in OUTPUTS:
        assert (work / name).exists(), name
    lock = yaml.safe_load((work / "dvc.lock").read_text())["stages"]
    assert lock["evaluate"]["cmd"] == "bin/thermal evaluate"
    assert "evaluate" not in next_run.status and "track" in next_run.status

    assert "Running stage 'track'" in next_run.again
    logged, client = next_run.logged, next_run.client
    assert logged["reused"] is False and logged["run_identity"] == next_run.identity
    assert next_run.reused["reused"] is True
    assert next_run.reused["parent_run_id"] == logged["parent_run_id"]
    experiment = client.get_experiment_by_name(_experiment())
    runs = client.search_runs(
        [experiment.experiment_id],
        filter_string=f"tags.{records.IDENTITY_TAG} = '{next_run.identity}'",
    )
    parents = [r for r in runs if records.PARENT_RUN_TAG not in r.data.tags]
    assert [p.info.run_id for p in parents] == [logged["parent_run_id"]]
    assert client.get_run(next_run.partial).info.lifecycle_stage == "deleted"
    children = client.search_runs(
        [experiment.experiment_id],
        filter_string=f"tags.{records.PARENT_RUN_TAG} = '{logged['parent_run_id']}'",
    )
    assert {r.data.params["model"] for r in children} == set(NEXT_CANDIDATES)
    assert (work / OUTPUTS[0]).read_bytes() == next_run.scores


def test_malformed_campaign_is_quarantined_while_the_others_are_scored(next_run):
    work = next_run.work
    report = json.loads((work / "reports" / "validation.json").read_text())
    assert report["summary"]["quarantined"] == ["K99"]
    problems = [p for p in report["problems"] if p["campaign"] == "K99"]
    assert any(
        p["file"] == "temperature.csv" and p["row"] == 1 and p["column"] == "T3" for p in problems
    ), problems
    assert all(p["action"] for p in problems)
    scores = _scores(work)
    assert "K99" not in set(scores["test_campaign"])
    training = {c for c in SPINDLE_CAMPAIGNS if c.startswith("K")}
    assert training | {"K13"} <= set(scores["train_unit"])
    assert {path: path.read_bytes() for path in next_run.raw_bytes} == next_run.raw_bytes
    disc = json.loads((work / "reports" / "discrepancy" / MACHINE / "discrepancy.json").read_text())
    assert "K99" not in disc["campaigns"] and "K01" in disc["campaigns"]


def _check_child_tables(client, children, scores: pd.DataFrame, folder: Path) -> None:
    """Every (training unit, test campaign) score is in its child's table artifact, once."""
    logged = []
    for run in children:
        assert len(run.data.metrics) <= 100, run.info.run_name
        local = client.download_artifacts(
            run.info.run_id, "scores.json", str(folder / run.info.run_id)
        )
        content = json.loads(Path(local).read_text())
        table = pd.DataFrame(content["data"], columns=content["columns"])
        keys = dict(zip(KEYS, run.info.run_name.split("/"), strict=True))
        logged.append(table.assign(**keys))
    logged = pd.concat(logged, ignore_index=True)
    assert len(logged) == len(scores)
    pairs = [*KEYS, "train_unit", "test_campaign"]
    both = scores.merge(logged, on=pairs, suffixes=("", "_logged"), validate="one_to_one")
    assert len(both) == len(scores)
    for column in ("rmse_um", "resid_std_um", "eta"):
        np.testing.assert_allclose(both[f"{column}_logged"].astype(float), both[column])


def _check_child_headlines(work: Path, children) -> None:
    """The headline scores are the model_scores.csv columns; the standing tags rank them."""
    summary = pd.read_csv(work / "reports" / "model_scores.csv")
    child = next(r for r in children if r.info.run_name == "Z/dl/fc_grd/static")
    row = summary.query("model == 'dl'").iloc[0]
    for name in ("loso_Mn_rms_um", "loso_eta", "Mn_um", "pooled_Mn_val_rms_um"):
        assert child.data.metrics[name] == pytest.approx(row[name], abs=1e-4)
    assert {"loso_winter_rms_um", "loso_summer_eta"} <= set(child.data.metrics)
    assert child.data.params["inputs"]
    tags = {r.info.run_name: r.data.tags for r in children}
    ranked = [t for t in tags.values() if t["eligible"] == "true"]
    assert sorted(int(t["rank"]) for t in ranked) == list(range(1, len(ranked) + 1))
    assert all(t["ineligible_reason"] for t in tags.values() if t["eligible"] == "false")
    assert sum(t["champion"] == "true" for t in tags.values()) == 1


def _check_discrepancy_run(work: Path, client, experiment: str, parent) -> None:
    """Named effects met the rule held out; the discrepancy and pipeline runs name each other."""
    disc = json.loads((work / "reports" / "discrepancy" / MACHINE / "discrepancy.json").read_text())
    rule = disc["thresholds"]
    for step in disc["steps"]:
        ev = step["evidence"]
        assert ev["delta_bic"] <= rule["max_delta_bic"]
        by_z = ev["heldout_reduction"] >= rule["min_heldout_reduction"]
        by_t = ev["heldout_T_reduction"] >= rule["min_heldout_temperature_reduction"]
        assert by_z or by_t
    assert (work / "reports" / "discrepancy" / MACHINE / "heldout_fit.png").stat().st_size > 10_000
    (disc_run,) = client.search_runs([client.get_experiment_by_name(experiment).experiment_id])
    assert disc_run.data.tags["pipeline_run_id"] == parent.info.run_id
    assert parent.data.tags["discrepancy_run_id"] == disc_run.info.run_id
    assert disc_run.data.metrics["rmse_um_before"] == pytest.approx(disc["rmse_um_before"])
    assert disc_run.data.params["named_effects"] == (",".join(disc["named_effects"]) or "none")
    # the search never saw the validation campaigns; the named effects are checked on them
    val = disc["validation"]
    assert sorted(val["campaigns"]) == [c for c in SPINDLE_CAMPAIGNS if c.startswith("V")]
    assert not set(val["campaigns"]) & {c for fold in disc["folds"] for c in fold}
    metric = disc_run.data.metrics["validation_rmse_um_after"]
    assert metric == pytest.approx(val["rmse_um_after"])


def _check_champion_loads(work: Path, uri: str, scores: pd.DataFrame) -> None:
    """The registered champion predicts a logged table as the pooled fit scored it."""
    record = _record(work)
    card = json.loads(
        (work / "data" / "models" / "champion" / MACHINE / "Z" / "champion.json").read_text()
    )
    assert card["protocol"] == "loso" and card["compensate"]
    os.environ["MLFLOW_TRACKING_URI"] = uri
    try:
        import mlflow

        mlflow.set_tracking_uri(uri)
        model = mlflow.pyfunc.load_model(record["champions"]["Z"]["uri"])
    finally:
        del os.environ["MLFLOW_TRACKING_URI"]
    separated = pd.read_parquet(work / "data" / "separated" / "spindle_thermal_error.parquet")
    measured = separated.query("campaign_id == 'V01'").sort_values("elapsed_s")
    # the machine's own table: degC readings, the speed and the time, as logged
    table = measured[["campaign_id", "elapsed_s", "rpm", *card["input_spec"]["inputs"]]]
    table = table[[c for c in table.columns if not c.startswith("speed")]]
    predicted = model.predict(table.reset_index(drop=True)).to_numpy()
    rmse = float(((measured["thermal_error_um"].to_numpy() - predicted) ** 2).mean() ** 0.5)
    pooled = scores[
        (scores["model"] == card["model"])
        & (scores["selection"] == card["selection"])
        & (scores["mode"] == card["mode"])
        & (scores["train_unit"] == "all_training")
    ]
    (logged_rmse,) = pooled.loc[pooled["test_campaign"] == "V01", "rmse_um"]
    assert rmse == pytest.approx(logged_rmse, rel=1e-4)


def _check_compensation(work: Path, uri: str, client) -> None:
    """The replay proof holds, its bundle is the champion run's, the runtime loads it from there."""
    document = json.loads((work / "reports" / "compensation" / "compensation.json").read_text())
    proof = document["machines"][MACHINE]["axes"]["Z"]["proof"]
    assert proof["n_campaigns"] == len(SPINDLE_CAMPAIGNS) and proof["ratio"] <= 1.1
    assert proof["rms_after_um"] < 0.2 * proof["rms_before_um"]
    record = _record(work)
    champion = record["champions"]["Z"]
    version = client.get_model_version(champion["registered_model"], champion["version"])
    run = client.get_run(version.run_id)
    assert run.data.metrics["replay.ratio"] == pytest.approx(proof["ratio"])
    logged = {a.path for a in client.list_artifacts(version.run_id, "compensation/bundle")}
    assert "compensation/bundle/bundle.json" in logged
    card = json.loads(
        (work / "data" / "models" / "champion" / MACHINE / "Z" / "champion.json").read_text()
    )
    separated = pd.read_parquet(work / "data" / "separated" / "spindle_thermal_error.parquet")
    logger = separated.query("campaign_id == 'V02'").sort_values("elapsed_s")
    sensors = [s for s in card["input_spec"]["inputs"] if not s.startswith("speed")]
    logger[["elapsed_s", "rpm", *sensors]].to_csv(work / "logger.csv", index=False)
    out = _run(
        [
            str(BIN / "thermal"),
            "compensate",
            "--registry",
            "--source",
            "csv:logger.csv",
            "--no-follow",
            "--sink",
            "csv:offsets.csv",
        ],
        work,
        _env(uri),
    )
    assert f"{len(logger)} cycles, {len(logger)} writes, 0 refused" in out
    written = pd.read_csv(work / "offsets.csv")["offset_um"].to_numpy()
    replayed = pd.read_csv(work / "reports" / "compensation" / MACHINE / "Z" / "trace.csv")
    expected = replayed.query("campaign_id == 'V02'")["offset_um"].to_numpy()
    np.testing.assert_allclose(written, expected, atol=1e-3)


def test_every_score_reaches_a_real_mlflow_server_once_and_the_champion_loads(demo, tmp_path):
    work, uri, output = demo.work, demo.uri, demo.output
    env = _env(uri)
    # library warnings are counted (one line per stage, per candidate in the report), not
    # printed: the demo's fits emit hundreds
    warned = [line for line in output.splitlines() if "Warning" in line]
    assert len(warned) <= 20, "\n".join(warned[:40])
    client = MlflowClient(tracking_uri=uri)
    experiment = client.get_experiment_by_name(_experiment())
    runs = client.search_runs([experiment.experiment_id], max_results=1000)
    parents = [r for r in runs if "mlflow.parentRunId" not in r.data.tags]
    children = [r for r in runs if "mlflow.parentRunId" in r.data.tags]
    scores = _scores(work)
    params = yaml.safe_load((work / "params.yaml").read_text())
    assert set(scores["model"]) == set(params["evaluate"]["candidates"])
    assert set(scores["axis"]) == {"Z"}  # the demo campaigns have a Z probe only
    assert len(parents) == 1
    assert len(children) == scores.groupby(["axis", "model", "selection", "mode"]).ngroups
    assert all(r.data.tags["warnings"].split()[0].isdigit() for r in children)
    _check_child_tables(client, children, scores, tmp_path)
    _check_child_headlines(work, children)
    assert parents[0].data.tags.get("git_commit")
    assert (work / "reports" / "model_comparison.md").is_file()
    twin = scores.query("model == 'twin'")
    assert {"K01", "not_summer", "all_training"} <= set(twin["train_unit"])
    assert twin["rmse_um"].notna().all()
    _check_discrepancy_run(work, client, params["discrepancy"]["experiment"], parents[0])
    _check_champion_loads(work, uri, scores)
    _check_compensation(work, uri, client)

    _repro(work, env)
    again = client.search_runs([experiment.experiment_id], max_results=1000)
    assert len(again) == len(runs)
    discrepancy = client.get_experiment_by_name(params["discrepancy"]["experiment"])
    assert len(client.search_runs([discrepancy.experiment_id])) == 1


def test_on_a_real_dask_cluster_the_scores_are_the_local_runs(demo, tmp_path):
    work = _continue_from(demo, tmp_path / "repo")
    shutil.rmtree(work / ".thermal_cache")  # fit every candidate again, on the cluster
    with running_dask_cluster(tmp_path, n_workers=2) as address:
        env = {**_env(demo.uri), cluster.SCHEDULER_VARIABLE: address}
        output = _run([str(work / "bin" / "thermal"), "evaluate"], work, env)
        with Client(address, timeout=10) as client:
            ran = client.run_on_scheduler(
                lambda dask_scheduler: sorted(dask_scheduler.task_prefixes)
            )
            workers = client.run(os.getpid)
    assert f"parallel jobs run on the Dask cluster {address} (2 workers)" in output
    assert any("_call_captured" in prefix for prefix in ran), ran
    assert len(set(workers.values())) == 2
    rows = [*KEYS, "scheme", "train_unit", "test_campaign", "role"]
    local, distributed = (
        _scores(folder).sort_values(rows).reset_index(drop=True) for folder in (demo.work, work)
    )
    assert len(local) > 100
    # the file keeps 6 significant digits; the local run's first jobs ran in the stage's own
    # process (its BLAS threads), so a last digit may differ by summation order
    pd.testing.assert_frame_equal(distributed, local, rtol=2e-5)


def test_the_demo_logged_to_a_team_server_on_postgresql_and_s3(demo):
    if demo.team is None:
        pytest.skip(unavailable_reason())
    client = MlflowClient(tracking_uri=demo.uri)
    runs = client.search_runs(
        [e.experiment_id for e in client.search_experiments()], max_results=1000
    )
    # the runs are rows of the PostgreSQL database, the artifacts objects in the S3 store
    with psycopg.connect(demo.team.database) as connection, connection.cursor() as cursor:
        cursor.execute("SELECT run_uuid FROM runs WHERE lifecycle_stage = 'active'")
        stored = {row[0] for row in cursor.fetchall()}
        cursor.execute("SELECT name, version FROM model_versions")
        versions = cursor.fetchall()
    assert stored == {r.info.run_id for r in runs}
    record = _record(demo.work)
    champion = record["champions"]["Z"]
    assert (champion["registered_model"], int(champion["version"])) in versions
    s3 = s3_client(demo.team.s3_endpoint)
    listed = s3.list_objects_v2(Bucket=BUCKET, Prefix="mlartifacts/", MaxKeys=1000)
    names = [item["Key"] for item in listed.get("Contents", [])]
    assert any(name.endswith("/scores.json") for name in names), names[:20]
    assert any(name.endswith("/MLmodel") for name in names), names[:20]
    assert any(name.endswith("/bundle.json") for name in names), names[:20]

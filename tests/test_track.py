"""Tests of the track stage on small synthetic evaluate outputs (spec.md formats)."""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mlflow.tracking import MlflowClient

from pipeline import track
from pipeline.tracking import identity, records, store
from tests.mlflow_server import running_mlflow_server

EXPERIMENT = "thermal-test"
CAMPAIGNS = {"K01": "train", "K02": "train", "K03": "train", "V01": "validation"}
TRAIN = [c for c, split in CAMPAIGNS.items() if split == "train"]
MODELS = ("mlr", "ridge")
SELECTIONS = ("all", "top3")
SUMMARY_KEYS = ("S_um", "Mn_um", "Sd_um", "Mn_val_um", "Sd_val_um", "S_rms_um", "Mn_rms_um")
PARAMS = {
    "evaluate": {"model": "mlr", "features": "temperature_rise", "n_jobs": 2},
    "track": {
        "experiment": EXPERIMENT,
        "batch_size": 1000,
        "default_tracking_uri": "sqlite:///mlflow.db",
        "local_artifact_dir": "mlartifacts",
    },
}


def _summary(offset: float) -> dict[str, float]:
    return {key: round(offset + 0.1 * i, 4) for i, key in enumerate(SUMMARY_KEYS)}


def write_evaluate_outputs(root: Path, shift: float = 0.0) -> None:
    """Write the evaluate outputs, params.yaml and raw campaigns that ``track`` reads."""
    rows, fitted, metrics = [], {}, {}
    n = 0
    for model in MODELS:
        metrics[model] = {}
        for selection in SELECTIONS:
            by_train = {}
            for train in TRAIN:
                for test, split in CAMPAIGNS.items():
                    role = "fit" if test == train else split.replace("train", "prediction")
                    n += 1
                    rows.append({
                        "model": model, "selection": selection, "train_campaign": train,
                        "test_campaign": test, "test_split": split, "role": role,
                        "n_samples": 100 + n, "rmse_um": f"{1.5 + 0.137 * n + shift:.6g}",
                        "resid_std_um": f"{1.1 + 0.071 * n + shift:.6g}",
                    })  # fmt: skip
                by_train[train] = _summary(n)
                fitted[f"{model}/{selection}/{train}"] = {
                    "model": model,
                    "selection": selection,
                    "train_campaign": train,
                    "sensors": ["T1", "T3", "T8"],
                    "params": {"features": "temperature_rise", "alpha": 0.5, "intercept_um": 1.2},
                }
            metrics[model][selection] = {
                "overall": _summary(100 + n),
                "by_train_campaign": by_train,
            }
    (root / "reports" / "separation").mkdir(parents=True, exist_ok=True)
    (root / "metrics").mkdir(exist_ok=True)
    with (root / "reports" / "cross_season_scores.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (root / "reports" / "fitted_models.json").write_text(json.dumps(fitted, indent=2))
    (root / "metrics" / "cross_season.json").write_text(json.dumps(metrics, indent=2))
    (root / "reports" / "cross_season_matrix.csv").write_text("score,train_campaign,K01\n")
    (root / "reports" / "cross_season_matrix.png").write_bytes(b"\x89PNG\r\n\x1a\nfake")
    (root / "reports" / "validation.json").write_text('{"summary": {}, "problems": []}')
    (root / "reports" / "separation" / "axis_separation.png").write_bytes(b"\x89PNG\r\n\x1a\nx")
    (root / "params.yaml").write_text(yaml.safe_dump(PARAMS))
    for campaign in CAMPAIGNS:
        folder = root / "data" / "raw" / campaign
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "campaign.yaml").write_text(f"campaign_id: {campaign}\nsynthetic: true\n")
        (folder / "temperature.csv").write_text("elapsed_s,T1\n0,20.0\n60,20.5\n")


def read_scores(root: Path) -> list[dict[str, str]]:
    with (root / "reports" / "cross_season_scores.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def record(root: Path) -> dict:
    return json.loads((root / "reports" / "mlflow_run.json").read_text())


def all_runs(client: MlflowClient) -> list:
    experiment = client.get_experiment_by_name(EXPERIMENT)
    return client.search_runs([experiment.experiment_id], max_results=1000)


@pytest.fixture(scope="session")
def empty_store(tmp_path_factory) -> Path:
    """A migrated, empty MLflow SQLite database, copied by each test (creation takes ~2 s)."""
    path = tmp_path_factory.mktemp("store") / "mlflow.db"
    MlflowClient(tracking_uri=f"sqlite:///{path}").search_experiments()
    return path


@pytest.fixture
def workdir(tmp_path, monkeypatch, empty_store) -> Path:
    """Repo-like tmp folder with evaluate outputs; the default local store in it."""
    write_evaluate_outputs(tmp_path)
    shutil.copy(empty_store, tmp_path / "mlflow.db")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    return tmp_path


@pytest.fixture
def client(workdir) -> MlflowClient:
    return MlflowClient(tracking_uri=f"sqlite:///{workdir / 'mlflow.db'}")


def split_runs(runs: list) -> tuple[list, list]:
    parents = [r for r in runs if records.PARENT_RUN_TAG not in r.data.tags]
    children = [r for r in runs if records.PARENT_RUN_TAG in r.data.tags]
    return parents, children


def test_one_child_per_model_selection_train_campaign(workdir, client):
    assert track.main([]) == 0
    parents, children = split_runs(all_runs(client))
    fitted = json.loads((workdir / "reports" / "fitted_models.json").read_text())
    assert len(parents) == 1
    assert len(children) == len(fitted) == len(MODELS) * len(SELECTIONS) * len(TRAIN)
    assert {r.data.tags[records.PARENT_RUN_TAG] for r in children} == {parents[0].info.run_id}
    assert {r.info.run_name for r in children} == set(fitted)
    assert all(r.info.status == "FINISHED" for r in parents + children)


def test_child_metrics_equal_the_scores_csv(workdir, client):
    track.main([])
    _, children = split_runs(all_runs(client))
    by_key = {tuple(r.data.params[k] for k in records.KEY_COLUMNS): r for r in children}
    rows = read_scores(workdir)
    for row in rows:
        run = by_key[(row["model"], row["selection"], row["train_campaign"])]
        for column in ("rmse_um", "resid_std_um"):
            assert run.data.metrics[f"{column}.{row['test_campaign']}"] == float(row[column])
    tree = json.loads((workdir / "metrics" / "cross_season.json").read_text())
    for (model, selection, train), run in by_key.items():
        key = (model, selection, train)
        tests = {
            r["test_campaign"] for r in rows if tuple(r[k] for k in records.KEY_COLUMNS) == key
        }
        assert tests == set(CAMPAIGNS)
        expected = {f"{c}.{t}" for c in ("rmse_um", "resid_std_um") for t in tests}
        expected |= set(SUMMARY_KEYS)
        assert set(run.data.metrics) == expected
        for key, value in tree[model][selection]["by_train_campaign"][train].items():
            assert run.data.metrics[key] == value
        assert run.data.params["sensors"] == "T1,T3,T8"
        assert json.loads(run.data.params["params"])["alpha"] == 0.5
        assert run.data.params["params.alpha"] == "0.5"


def test_parent_has_overall_scores_tags_and_artifacts(workdir, client):
    (workdir / "dvc.lock").write_text(
        yaml.safe_dump({
            "schema": "2.0",
            "stages": {
                "ingest": {"cmd": "thermal ingest",
                           "deps": [{"path": "data/raw", "hash": "md5", "md5": "abc.dir"}],
                           "outs": [{"path": "data/ingested", "hash": "md5", "md5": "def.dir"}]},
                "evaluate": {"cmd": "thermal evaluate",
                             "outs": [{"path": "reports/cross_season_scores.csv", "md5": "123"}]},
                "track": {"cmd": "thermal track",
                          "outs": [{"path": "reports/mlflow_run.json", "md5": "456"}]},
            },
        })
    )  # fmt: skip
    track.main([])
    (parent,), _ = split_runs(all_runs(client))
    info = record(workdir)
    tags = parent.data.tags
    assert tags[records.IDENTITY_TAG] == info["run_identity"]
    assert tags["git_commit"] == "unknown"  # tmp folder is not a git repository
    assert tags["synthetic"] == "true"
    assert tags["dvc.data/raw"] == "abc.dir"
    assert tags["dvc.ingest.data/ingested"] == "def.dir"
    assert tags["dvc.evaluate.reports/cross_season_scores.csv"] == "123"
    assert "dvc.track.reports/mlflow_run.json" not in tags  # its own previous output
    tree = json.loads((workdir / "metrics" / "cross_season.json").read_text())
    for model in MODELS:
        for selection in SELECTIONS:
            for key, value in tree[model][selection]["overall"].items():
                assert parent.data.metrics[f"{model}.{selection}.{key}"] == value
    assert parent.data.params["evaluate.model"] == "mlr"
    listed = {f.path for f in client.list_artifacts(parent.info.run_id, "reports")}
    assert {"reports/cross_season_matrix.csv", "reports/cross_season_matrix.png",
            "reports/validation.json", "reports/separation"} <= listed  # fmt: skip
    assert [f.path for f in client.list_artifacts(parent.info.run_id, "metrics")] == [
        "metrics/cross_season.json"
    ]
    separation = client.list_artifacts(parent.info.run_id, "reports/separation")
    assert [f.path for f in separation] == ["reports/separation/axis_separation.png"]
    stored = workdir / "mlartifacts" / EXPERIMENT / parent.info.run_id / "artifacts"
    assert (stored / "reports" / "cross_season_matrix.png").is_file()
    assert info["child_runs"] == len(MODELS) * len(SELECTIONS) * len(TRAIN)
    assert info["metrics"] == len(parent.data.metrics) + sum(
        len(r.data.metrics) for r in split_runs(all_runs(client))[1]
    )
    assert info["tracking_uri"] == "sqlite:///mlflow.db"
    assert info["reused"] is False


def test_missing_optional_reports_and_dvc_lock_are_tolerated(workdir, client):
    (workdir / "reports" / "validation.json").unlink()
    shutil.rmtree(workdir / "reports" / "separation")
    assert track.main([]) == 0
    (parent,), _ = split_runs(all_runs(client))
    assert not any(key.startswith("dvc.") for key in parent.data.tags)
    listed = {f.path for f in client.list_artifacts(parent.info.run_id, "reports")}
    assert "reports/validation.json" not in listed


def test_second_run_on_unchanged_inputs_logs_nothing(workdir, client, caplog):
    track.main([])
    first = record(workdir)
    count = len(all_runs(client))
    caplog.set_level("INFO", logger="pipeline.track")
    track.main([])
    second = record(workdir)
    assert len(all_runs(client)) == count
    assert second["reused"] is True
    assert second["parent_run_id"] == first["parent_run_id"]
    assert second["run_identity"] == first["run_identity"]
    assert "already logged" in caplog.text


def _change_scores(root: Path) -> None:
    write_evaluate_outputs(root, shift=0.5)


def _change_params(root: Path) -> None:
    params = yaml.safe_load((root / "params.yaml").read_text())
    params["evaluate"]["n_jobs"] = 3
    (root / "params.yaml").write_text(yaml.safe_dump(params))


def _change_data(root: Path) -> None:
    (root / "data" / "raw" / "K02" / "temperature.csv").write_text("elapsed_s,T1\n0,20.0\n60,21\n")


@pytest.mark.parametrize("change", [_change_scores, _change_params, _change_data])
def test_changed_scores_params_or_data_log_a_new_parent(workdir, client, change):
    track.main([])
    first = record(workdir)
    change(workdir)
    track.main([])
    second = record(workdir)
    assert second["run_identity"] != first["run_identity"]
    assert second["reused"] is False
    parents, children = split_runs(all_runs(client))
    assert len(parents) == 2
    assert len(children) == 2 * first["child_runs"]


def test_identity_is_stable_and_sees_renamed_files(tmp_path):
    write_evaluate_outputs(tmp_path)
    files = [tmp_path / "reports" / "cross_season_scores.csv"]
    params = yaml.safe_load((tmp_path / "params.yaml").read_text())
    first = identity.compute_identity([tmp_path / "data"], params, tmp_path / "data/raw", files)
    again = identity.compute_identity(
        [tmp_path / "data"], dict(params), tmp_path / "data/raw", files
    )
    assert first == again
    (tmp_path / "data" / "raw" / "K01" / "temperature.csv").rename(
        tmp_path / "data" / "raw" / "K01" / "temperature_renamed.csv"
    )
    moved = identity.compute_identity([tmp_path / "data"], params, tmp_path / "data/raw", files)
    assert moved.parts["data"] != first.parts["data"]
    assert moved.parts["params"] == first.parts["params"]


def test_git_commit_is_tagged_when_in_a_repository(workdir, client):
    git = shutil.which("git")  # DVC needs git too: the project requires it
    assert git is not None, "git is required (dvc repro runs in a git repository)"
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@example.org",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@example.org"}  # fmt: skip
    for command in (["init", "-q"], ["add", "params.yaml"], ["commit", "-q", "-m", "x"]):
        subprocess.run([git, *command], cwd=workdir, env=env, check=True)
    head = subprocess.run([git, "rev-parse", "HEAD"], cwd=workdir, capture_output=True, text=True)
    track.main([])
    (parent,), _ = split_runs(all_runs(client))
    assert parent.data.tags["git_commit"] == head.stdout.strip()
    assert parent.data.tags["mlflow.source.git.commit"] == head.stdout.strip()


def test_metrics_are_logged_in_batches_not_one_by_one(workdir, monkeypatch):
    calls = {"log_batch": [], "log_metric": 0}
    original = MlflowClient.log_batch

    def spy(self, run_id, metrics=(), params=(), tags=(), **kwargs):
        calls["log_batch"].append(len(metrics))
        return original(self, run_id, metrics=metrics, params=params, tags=tags, **kwargs)

    def forbidden(*args, **kwargs):
        calls["log_metric"] += 1

    monkeypatch.setattr(MlflowClient, "log_batch", spy)
    monkeypatch.setattr(MlflowClient, "log_metric", forbidden)
    track.main([])
    n_runs = record(workdir)["child_runs"] + 1
    assert calls["log_metric"] == 0
    assert len(calls["log_batch"]) == n_runs  # one call per run at the default batch size
    assert sum(calls["log_batch"]) == record(workdir)["metrics"]


def test_batches_respect_mlflow_limits():
    metrics = {f"m{i}": float(i) for i in range(2500)}
    params = {f"p{i}": str(i) for i in range(150)}
    tags = {f"t{i}": str(i) for i in range(30)}
    chunks = list(store.batches(metrics, params, tags, batch_size=1000))
    for m, p, t in chunks:
        assert len(m) <= 1000 and len(p) <= 100 and len(t) <= 100
        assert len(m) + len(p) + len(t) <= 1000
    assert sum(len(m) for m, _, _ in chunks) == 2500
    assert dict(p for _, ps, _ in chunks for p in ps) == params
    assert dict(t for _, _, ts in chunks for t in ts) == tags
    small = list(store.batches(metrics, {}, {}, batch_size=300))
    assert [len(m) for m, _, _ in small] == [300] * 8 + [100]
    assert list(store.batches({}, {}, {}, batch_size=10)) == []
    with pytest.raises(ValueError, match="track.batch_size = 0"):
        list(store.batches(metrics, {}, {}, batch_size=0))


def test_batch_size_above_mlflow_limit_is_rejected_before_logging(workdir, client):
    params = yaml.safe_load((workdir / "params.yaml").read_text())
    params["track"]["batch_size"] = 5000
    (workdir / "params.yaml").write_text(yaml.safe_dump(params))
    with pytest.raises(ValueError, match=r"params.yaml: track.batch_size = 5000; MLflow accepts"):
        track.main([])
    assert client.get_experiment_by_name(EXPERIMENT) is None


def test_small_batch_size_splits_the_metrics(workdir, client, monkeypatch):
    params = yaml.safe_load((workdir / "params.yaml").read_text())
    params["track"]["batch_size"] = 7
    (workdir / "params.yaml").write_text(yaml.safe_dump(params))
    sizes = []
    original = MlflowClient.log_batch

    def spy(self, run_id, metrics=(), params=(), tags=(), **kwargs):
        sizes.append(len(metrics))
        return original(self, run_id, metrics=metrics, params=params, tags=tags, **kwargs)

    monkeypatch.setattr(MlflowClient, "log_batch", spy)
    track.main([])
    assert max(sizes) == 7
    assert sum(sizes) == record(workdir)["metrics"]
    _, children = split_runs(all_runs(client))
    assert all(len(r.data.metrics) == 2 * len(CAMPAIGNS) + len(SUMMARY_KEYS) for r in children)


def test_missing_evaluate_output_says_what_to_run(workdir):
    (workdir / "reports" / "fitted_models.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"fitted_models.json not found.*dvc repro"):
        track.main([])


def test_bad_score_cell_names_file_row_and_column(workdir):
    rows = read_scores(workdir)
    rows[3]["rmse_um"] = "n/a"  # model mlr, selection all, K01 -> V01
    with pytest.raises(ValueError, match=r"data row 4, column 'rmse_um': 'n/a' is not a number"):
        records.scores_by_child(rows)
    rows[3]["rmse_um"] = ""
    assert math.isnan(records.scores_by_child(rows)[("mlr", "all", "K01")]["rmse_um.V01"])


def _rewrite_scores(root: Path, rows: list[dict[str, str]]) -> Path:
    path = root / "reports" / "cross_season_scores.csv"
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def test_scores_are_read_exactly_and_checked_against_the_schema(workdir):
    path = workdir / "reports" / "cross_season_scores.csv"
    rows = read_scores(workdir)
    parsed = track.read_scores(path)
    assert [r["rmse_um"] for r in parsed] == [float(r["rmse_um"]) for r in rows]
    assert parsed[0]["train_campaign"] == "K01"
    rows[3]["rmse_um"] = "-1.5"
    rows[5]["role"] = "validation"
    _rewrite_scores(workdir, rows)
    with pytest.raises(ValueError) as caught:
        track.read_scores(path)
    message = str(caught.value)
    assert "data row 4, column 'rmse_um': -1.5 fails greater_than_or_equal_to(0)" in message
    assert "data rows [6]: check role_consistent failed" in message
    assert "dvc repro evaluate" in message
    rows[3]["rmse_um"] = "n/a"
    _rewrite_scores(workdir, rows)
    with pytest.raises(ValueError, match=r"column 'rmse_um'.*dvc repro evaluate"):
        track.main([])


def test_duplicate_score_row_is_an_error(workdir):
    rows = read_scores(workdir)
    with pytest.raises(ValueError, match=r"data row 2: .*test_campaign=K02 already on data row 1"):
        records.scores_by_child([rows[1], rows[1]])


def test_tracking_uri_env_var_overrides_default(workdir, monkeypatch, tmp_path_factory):
    other = tmp_path_factory.mktemp("other") / "other.db"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{other}")
    track.main([])
    assert record(workdir)["tracking_uri"] == f"sqlite:///{other}"
    assert (other.parent / "mlartifacts" / EXPERIMENT).is_dir()
    assert track.public_uri("https://user:secret@mlflow.example.org/x") == (
        "https://mlflow.example.org/x"
    )


@pytest.mark.slow
def test_track_logs_to_a_real_mlflow_server(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    write_evaluate_outputs(work)
    thermal = Path(sys.executable).with_name("thermal")
    command = [str(thermal)] if thermal.exists() else [sys.executable, "-m", "pipeline"]
    with running_mlflow_server(tmp_path) as uri:
        env = {**os.environ, "MLFLOW_TRACKING_URI": uri}
        for _ in range(2):  # the second run must reuse the parent
            done = subprocess.run(
                [*command, "track"], cwd=work, env=env, capture_output=True, text=True, timeout=300
            )
            assert done.returncode == 0, done.stderr
        client = MlflowClient(tracking_uri=uri)
        parents, children = split_runs(all_runs(client))
        assert len(parents) == 1
        assert len(children) == len(MODELS) * len(SELECTIONS) * len(TRAIN)
        assert record(work)["reused"] is True
        for row in read_scores(work):
            (run,) = [r for r in children if r.info.run_name ==
                      f"{row['model']}/{row['selection']}/{row['train_campaign']}"]  # fmt: skip
            assert run.data.metrics[f"rmse_um.{row['test_campaign']}"] == float(row["rmse_um"])
            assert run.data.metrics[f"resid_std_um.{row['test_campaign']}"] == float(
                row["resid_std_um"]
            )
        listed = {f.path for f in client.list_artifacts(parents[0].info.run_id, "reports")}
        assert "reports/cross_season_matrix.png" in listed
    assert not (work / "mlflow.db").exists()  # nothing went to the default local store


def test_unreachable_tracking_server_is_a_clear_error(workdir, monkeypatch):
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"http://127.0.0.1:{port}")
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
    with pytest.raises(
        SystemExit, match=r"cannot use the MLflow tracking store.*MLFLOW_TRACKING_URI"
    ):
        track.main([])
    assert not (workdir / "reports" / "mlflow_run.json").exists()

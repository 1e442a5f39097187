"""Tests of the track stage on small evaluate outputs built with the real pipeline functions.

The fixture fits small estimators with :func:`pipeline.protocol.cross_season.fit_and_score` on
synthetic campaigns of two displacement axes (four training campaigns in two seasons, one validation
campaign, ``training_units`` gives each campaign, each season left out and all of them),
validates the scores with ``schemas.evaluated.CrossSeasonScoresModel``, summarises them with
``pipeline.protocol.scoring`` and picks each axis' champion with ``pipeline.protocol.champion``,
then writes the files the select and evaluate stages write. So the fixture follows the code that
produces the real outputs. The estimators are test-local (sklearn, a ridge reporting
``chosen_params_``, an AR(1) with error feedback) so the track tests do not depend on the model
registry.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import joblib
import mlflow
import numpy as np
import pandas as pd
import pytest
import yaml
from mlflow.tracking import MlflowClient
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.linear_model import LinearRegression, Ridge

from pipeline.models.reference import NoCompensation
from pipeline.protocol.champion import champion_card, choose_champion
from pipeline.protocol.cross_season import Candidate, fit_and_score
from pipeline.protocol.evaluation import champion_metrics, ranked_summary, round_tree
from pipeline.protocol.scoring import candidate_summary, group_scores, metrics_tree
from pipeline.protocol.serving import predict_table
from pipeline.protocol.units import (
    INDEX_NAMES,
    POOLED_UNIT,
    CampaignSeries,
    training_units,
)
from pipeline.separation.features import InputSpec, model_inputs
from pipeline.stages import track
from pipeline.tracking import identity, records, stage_outputs, store
from schemas.evaluated import CrossSeasonScoresModel
from tests.helpers.clean_load import predict_without_repository
from tests.helpers.mlflow_server import empty_database, running_mlflow_server

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENT = "thermal-test"
REGISTERED = "thermal-error-spindle"
AXES = ("X", "Z")
MACHINE = "vmc 450"
"""The machine of the campaigns (``vmc-450`` in names)."""
NAMES = {axis: f"{REGISTERED}-vmc-450-{axis}" for axis in AXES}
URIS = {axis: f"models:/{name}@champion" for axis, name in NAMES.items()}
CAMPAIGNS = {  # campaign -> (split, season)
    "K01": ("train", "winter"),
    "K02": ("train", "winter"),
    "K03": ("train", "summer"),
    "K04": ("train", "summer"),
    "V01": ("validation", "spring"),
}
UNITS = ("K01", "K02", "K03", "K04", "not_winter", "not_summer", POOLED_UNIT)
N_SAMPLES = 24  # 3-min sampling: 69 min per campaign
SAMPLE_S = 180.0
COLD_DEGC = 20.0
SELECTED_SENSORS = {  # method -> unit -> sensors, in order of preference
    "pair": {
        **dict.fromkeys(UNITS, ["T1", "T2"]),
        "K04": ["T1", "T3"],
        POOLED_UNIT: ["T2", "T1"],
    },
    "all": dict.fromkeys(UNITS, ["T1", "T2", "T3"]),
}
AXIS_METRICS = {"residual_band_um": 3.2, "rmse_um": 1.4, "n_samples": 120}
PNG = b"\x89PNG\r\n\x1a\nfake"
PARAMS = {
    "evaluate": {
        "candidates": {"none": "none", "mlr": "pair", "ridge": "all", "ar1": "none"},
        "n_jobs": 2,
    },
    "tracking": {
        "default_tracking_uri": "sqlite:///mlflow.db",
        "local_artifact_dir": "mlartifacts",
    },
    "track": {"experiment": EXPERIMENT, "registered_model": REGISTERED},
}


class ReportingRidge(Ridge):
    """Ridge that reports what its fit used in ``chosen_params_``, as the registry's models do."""

    def fit(self, X, y, sample_weight=None):
        """Fit the ridge; ``chosen_params_`` holds the penalty and the number of inputs."""
        super().fit(X, y, sample_weight=sample_weight)
        self.chosen_params_ = {"alpha": float(self.alpha), "n_inputs": int(X.shape[1])}
        return self


class ErrorAR1(RegressorMixin, BaseEstimator):
    """AR(1) on the thermal error alone, scored one-step-ahead and in free run.

    The history restarts at 0 um in every campaign (level ``campaign_id`` of X's index).
    """

    needs_error_feedback = True

    def fit(self, X, y):
        """Least-squares a1 of y_t = a1 y_{t-1}."""
        y = np.asarray(y, dtype=float)
        lag = _previous(y, X)
        self.coef_ = float(lag @ y / (lag @ lag))
        self.chosen_params_ = {"ar_order": 1, "a1": round(self.coef_, 6)}
        return self

    def predict(self, X, y_history=None):
        """Thermal error (um): a1 times the measured (``y_history``) or predicted previous error.

        In free run the prediction stays at the pre-sample error, 0 um.
        """
        if y_history is None:
            return np.zeros(len(X))
        return self.coef_ * _previous(np.asarray(y_history, dtype=float), X)


def _previous(y: np.ndarray, X: pd.DataFrame) -> np.ndarray:
    """y_{t-1} per campaign, 0 um before each campaign's first sample."""
    campaign = X.index.get_level_values("campaign_id").to_numpy()
    previous = np.r_[0.0, y[:-1]]
    previous[np.r_[True, campaign[1:] != campaign[:-1]]] = 0.0
    return previous


CANDIDATES = (  # (model, selection, estimator)
    ("none", "none", NoCompensation()),
    ("mlr", "pair", LinearRegression()),
    ("ridge", "all", ReportingRidge(alpha=50.0)),
    ("ar1", "none", ErrorAR1()),
)
CHILDREN = {
    (axis, *key)
    for axis in AXES
    for key in (
        ("none", "none", "static"),
        ("mlr", "pair", "static"),
        ("ridge", "all", "static"),
        ("ar1", "none", "one_step"),
        ("ar1", "none", "free_run"),
    )
}
SPEC = InputSpec(("T2", "T1"), "temperature_rise", "first_sample", 1)


@dataclass(frozen=True)
class EvaluateOutputs:
    """What the select and evaluate stages produce, in memory.

    Attributes
    ----------
    scores : DataFrame
        Long score table (``CrossSeasonScoresModel``).
    fitted : dict
        ``reports/fitted_models.json``.
    selected : dict
        ``reports/selection/selected.json``.
    cards : dict
        Axis -> ``data/models/champion/<axis>/champion.json``.
    estimators : dict
        Axis -> the champion's fit on all training campaigns.
    """

    scores: pd.DataFrame
    fitted: dict
    selected: dict
    cards: dict
    estimators: dict


def synthetic_rises(number: int, rng: np.random.Generator) -> tuple[pd.DataFrame, np.ndarray]:
    """Temperature rises (K) of one campaign and its thermal error (um), 0 at the cold start."""
    elapsed = SAMPLE_S * np.arange(N_SAMPLES)
    rises = {
        "T1": (3.0 + number) * (1.0 - np.exp(-elapsed / 1800.0)),
        "T2": (2.0 + 0.5 * number) * (1.0 - np.exp(-elapsed / 5400.0))
        + 0.3 * np.sin(elapsed / 900.0),
        "T3": np.r_[0.0, rng.normal(0.0, 0.3, N_SAMPLES - 1)],
    }
    error = 2.0 * rises["T1"] - 1.5 * rises["T2"] + np.r_[0.0, rng.normal(0.0, 0.2, N_SAMPLES - 1)]
    return pd.DataFrame(rises).assign(elapsed_s=elapsed), error


def synthetic_series(axis: str) -> list[CampaignSeries]:
    """The campaigns of :data:`CAMPAIGNS` as the evaluate stage sees them on one axis.

    The X error is the Z error scaled by -0.5 (another sign and size, the same physics).
    """
    rng = np.random.default_rng(7)
    series = []
    for number, (campaign, (split, season)) in enumerate(CAMPAIGNS.items()):
        rises, error = synthetic_rises(number, rng)
        index = pd.MultiIndex.from_arrays(
            [np.full(N_SAMPLES, campaign), rises["elapsed_s"].to_numpy()], names=INDEX_NAMES
        )
        features = pd.DataFrame(rises[["T1", "T2", "T3"]].to_numpy(), index, ["T1", "T2", "T3"])
        target = error if axis == "Z" else -0.5 * error
        series.append(CampaignSeries(campaign, split, season, features, target, axis=axis))
    return series


def unit_sensors(selection: str, unit: str) -> list[str]:
    return [] if selection == "none" else list(SELECTED_SENSORS[selection][unit])


def build_outputs() -> EvaluateOutputs:
    """Fit every candidate on every training unit and describe the results as evaluate does."""
    results = {
        axis: [
            fit_and_score(
                Candidate(model, selection),
                unit,
                series,
                estimator,
                unit_sensors(selection, unit.name),
            )
            for model, selection, estimator in CANDIDATES
            for unit in training_units(series)
        ]
        for axis in AXES
        for series in [synthetic_series(axis)]
    }
    assert {r.unit.name for r in results["Z"]} == set(UNITS)
    scores = pd.concat([r.scores for by in results.values() for r in by], ignore_index=True)
    scores = CrossSeasonScoresModel.validate(scores, lazy=True)
    fitted = {
        f"{axis}/{r.candidate.model}/{r.candidate.selection}/{r.unit.name}": {
            "axis": axis,
            "model": r.candidate.model,
            "selection": r.candidate.selection,
            "train_unit": r.unit.name,
            "scheme": r.unit.scheme,
            "inputs": list(r.sensors),
            "chosen_params": dict(r.chosen_params),
        }
        for axis, by in results.items()
        for r in by
    }
    methods = {
        method: {
            unit: {"inputs": inputs, "details": {"rule": "fixture", "n_inputs": len(inputs)}}
            for unit, inputs in by_unit.items()
        }
        for method, by_unit in SELECTED_SENSORS.items()
    }
    selected = {"features": "temperature_rise", "axes": dict.fromkeys(AXES, methods)}
    summary = candidate_summary(scores)
    cards, estimators = {}, {}
    for axis in AXES:
        decision = choose_champion(summary, axis, "loso", 0.1)
        assert decision.label == "mlr/pair/static" and decision.compensate
        (pooled,) = [
            r
            for r in results[axis]
            if r.unit.name == POOLED_UNIT and r.candidate == Candidate("mlr", "pair")
        ]
        cards[axis] = {**champion_card(decision, pooled, SPEC, SAMPLE_S), "machine": MACHINE}
        estimators[axis] = pooled.estimator
    return EvaluateOutputs(scores, fitted, selected, cards, estimators)


SKIPPED = {"twin/roles": "the twin models the Z drift only"}


def write_scores(root: Path, scores: pd.DataFrame, cards: dict) -> None:
    """Write the long score table, the candidate table and the metrics tree as evaluate does."""
    (root / "reports").mkdir(parents=True, exist_ok=True)
    (root / "metrics").mkdir(parents=True, exist_ok=True)
    scores.assign(machine=MACHINE).to_csv(
        root / "reports" / "cross_season_scores.csv", index=False, float_format="%.6g"
    )
    summary = candidate_summary(scores)
    decisions = [choose_champion(summary, axis, "loso", 0.1) for axis in AXES]
    ranked_summary(summary, decisions).assign(machine=MACHINE).to_csv(
        root / "reports" / "model_scores.csv", index=False, float_format="%.4f"
    )
    group_scores(scores).assign(machine=MACHINE).to_csv(
        root / "reports" / "heldout_scores.csv", index=False, float_format="%.4f"
    )
    tree = metrics_tree(scores)
    metrics = {
        axis: {
            "candidates": tree[axis],
            "champion": champion_metrics(cards[axis]),
            "skipped": SKIPPED if axis == "X" else {},
        }
        for axis in AXES
    }
    (root / "metrics" / "cross_season.json").write_text(
        json.dumps({"machines": {MACHINE: round_tree(metrics)}}, indent=2, sort_keys=True)
    )


def write_champion(root: Path, outputs: EvaluateOutputs) -> None:
    table, _ = temperature_table()
    separated = separated_table()
    (root / "data" / "separated").mkdir(parents=True, exist_ok=True)
    separated.assign(machine=MACHINE).to_parquet(
        root / "data" / "separated" / "spindle_thermal_error.parquet"
    )
    for axis in AXES:
        folder = root / "data" / "models" / "champion" / "vmc-450" / axis
        folder.mkdir(parents=True, exist_ok=True)
        joblib.dump(outputs.estimators[axis], folder / "estimator.joblib")
        card = json.dumps(outputs.cards[axis], indent=2, sort_keys=True)
        (folder / "champion.json").write_text(card)
        table.head(5).to_csv(folder / "input_example.csv", index=False)
        heldout_of(separated[separated["axis"] == axis], outputs.estimators[axis]).to_parquet(
            folder / "heldout.parquet"
        )


def separated_table() -> pd.DataFrame:
    """The separated table the promotion gate reads: each campaign its own cold run (degC)."""
    frames = []
    for axis in AXES:
        for item in synthetic_series(axis):
            elapsed = item.features.index.get_level_values("elapsed_s").to_numpy()
            frames.append(
                pd.DataFrame(
                    {
                        "axis": axis,
                        "campaign_id": item.campaign_id,
                        "run_id": item.campaign_id,
                        "elapsed_s": elapsed,
                        "run_elapsed_s": elapsed,
                        "rpm": 0.0,
                        "split": item.split,
                        "thermal_error_um": item.target,
                        **{s: COLD_DEGC + item.features[s].to_numpy() for s in ("T1", "T2", "T3")},
                    }
                )
            )
    return pd.concat(frames, ignore_index=True)


def heldout_of(rows: pd.DataFrame, estimator) -> pd.DataFrame:
    """The champion's predictions as its registered model makes them (a challenger no better)."""
    log = rows[["campaign_id", "elapsed_s", "T1", "T2", "T3"]]
    return pd.DataFrame(
        {
            "campaign_id": rows["campaign_id"].to_numpy(),
            "elapsed_s": rows["elapsed_s"].to_numpy(),
            "measured_um": rows["thermal_error_um"].to_numpy(),
            "predicted_um": predict_table(estimator, log, SPEC),
        }
    )


def write_evaluate_outputs(root: Path, outputs: EvaluateOutputs) -> None:
    """Write the select and evaluate outputs, params.yaml and raw campaigns ``track`` reads."""
    reports = root / "reports"
    for folder in ("selection", "matrices", "comparison", "separation"):
        (reports / folder).mkdir(parents=True, exist_ok=True)
    write_scores(root, outputs.scores, outputs.cards)
    fitted = {"machines": {MACHINE: outputs.fitted}}
    (reports / "fitted_models.json").write_text(json.dumps(fitted, indent=2))
    selected = {
        "features": outputs.selected["features"],
        "machines": {MACHINE: {"axes": outputs.selected["axes"], "skipped_axes": {}}},
    }
    (reports / "selection" / "selected.json").write_text(json.dumps(selected, indent=2))
    (reports / "selection" / "pair_evidence.csv").write_text("unit,sensor,score\nK01,T1,0.9\n")
    (reports / "model_comparison.md").write_text("# Model comparison (SYNTHETIC data)\n")
    (reports / "cross_season_matrix.csv").write_text("model,selection,mode,score,train_unit\n")
    (reports / "matrices" / "vmc-450__Z__mlr__pair__static.png").write_bytes(PNG)
    (reports / "comparison" / "best_worst_validation.png").write_bytes(PNG)
    (reports / "validation.json").write_text('{"summary": {}, "problems": []}')
    (reports / "separation" / "axis_separation.png").write_bytes(PNG)
    axis_model = {"machines": {MACHINE: {"axis_model": AXIS_METRICS}}}
    (reports / "axis_model.json").write_text(json.dumps(axis_model))
    (root / "metrics" / "axis_model.json").write_text(
        json.dumps({"machines": {MACHINE: AXIS_METRICS}})
    )
    write_champion(root, outputs)
    (root / "params.yaml").write_text(yaml.safe_dump(PARAMS))
    for campaign in CAMPAIGNS:
        folder = root / "data" / "raw" / campaign
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "campaign.yaml").write_text(
            f"campaign_id: {campaign}\nmachine: {MACHINE}\nsynthetic: true\n"
        )
        (folder / "temperature.csv").write_text("elapsed_s,T1\n0,20.0\n60,20.5\n")
    (root / "data" / "ingested").mkdir(parents=True, exist_ok=True)
    ingested = pd.DataFrame({"campaign_id": list(CAMPAIGNS), "machine": MACHINE})
    ingested.to_parquet(root / "data" / "ingested" / "campaigns.parquet")


def temperature_table() -> tuple[pd.DataFrame, pd.DataFrame]:
    """Two runs as a machine logs them (degC, extra sensor, own column order) and their rises (K).

    Returns
    -------
    table : DataFrame
        Columns ``campaign_id``, ``elapsed_s``, ``T3``, ``T1``, ``T2`` (degC).
    rises : DataFrame
        The same rows' ``T1``, ``T2``, ``T3`` rises from each run's first reading (K).
    """
    rng = np.random.default_rng(11)
    frames = []
    for run, number in (("run-a", 5), ("run-b", 1)):
        rises, _ = synthetic_rises(number, rng)
        frames.append(rises.assign(campaign_id=run))
    rises = pd.concat(frames, ignore_index=True)
    table = rises[["campaign_id", "elapsed_s"]].assign(
        **{
            sensor: COLD_DEGC + 0.5 * i + rises[sensor]
            for i, sensor in enumerate(("T3", "T1", "T2"))
        }
    )
    return table, rises[["T1", "T2", "T3"]]


def read_scores(root: Path) -> list[dict[str, str]]:
    with (root / "reports" / "cross_season_scores.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def read_json(root: Path, relative: str):
    return json.loads((root / relative).read_text())


def record(root: Path) -> dict:
    """The track record of the machine, beside the store and experiment."""
    document = read_json(root, "reports/mlflow_run.json")
    assert list(document["machines"]) == [MACHINE]
    shared = {key: value for key, value in document.items() if key != "machines"}
    return {**shared, **document["machines"][MACHINE]}


def all_runs(client: MlflowClient) -> list:
    experiment = client.get_experiment_by_name(EXPERIMENT)
    return client.search_runs([experiment.experiment_id], max_results=1000)


def split_runs(runs: list) -> tuple[list, list]:
    parents = [r for r in runs if records.PARENT_RUN_TAG not in r.data.tags]
    children = [r for r in runs if records.PARENT_RUN_TAG in r.data.tags]
    return parents, children


def child_key(run) -> tuple[str, ...]:
    return tuple(run.data.params[key] for key in records.KEY_COLUMNS)


def expected_child_metrics(root: Path, key: tuple[str, ...]) -> dict[str, float]:
    """A candidate's headline scores: its model_scores.csv row and its held-out groups."""
    summary = pd.read_csv(root / "reports" / "model_scores.csv").drop(columns="machine")
    row = summary.set_index(list(records.KEY_COLUMNS)).loc[key]
    standing = {"eligible", "ineligible_reason", "rank", "champion"}
    expected = {
        name: float(value)
        for name, value in row.items()
        if name not in standing and pd.notna(value)
    }
    groups = pd.read_csv(root / "reports" / "heldout_scores.csv", keep_default_na=False)
    groups = groups.drop(columns="machine")
    mine = groups.set_index(list(records.KEY_COLUMNS)).loc[[key]]
    for _, group in mine.iterrows():
        expected[group["name"]] = float(group["rms_um"])
        expected[group["name"].removesuffix("_rms_um") + "_eta"] = float(group["eta"])
    return expected


def table_artifact(client: MlflowClient, run_id: str, path: str, tmp: Path) -> pd.DataFrame:
    """Download a table artifact (``mlflow.log_table`` JSON) as a DataFrame."""
    local = client.download_artifacts(run_id, path, str(tmp))
    content = json.loads(Path(local).read_text())
    return pd.DataFrame(content["data"], columns=content["columns"])


def versions(client: MlflowClient, axis: str = "Z") -> list[str]:
    found = client.search_model_versions(f"name = '{NAMES[axis]}'")
    return sorted(str(v.version) for v in found)


DVC_LOCK = {
    "schema": "2.0",
    "stages": {
        "ingest": {
            "cmd": "thermal ingest",
            "deps": [{"path": "data/raw", "hash": "md5", "md5": "abc.dir"}],
            "outs": [{"path": "data/ingested", "hash": "md5", "md5": "def.dir"}],
        },
        "evaluate": {
            "cmd": "thermal evaluate",
            "outs": [{"path": "reports/cross_season_scores.csv", "md5": "123"}],
        },
        "track": {
            "cmd": "thermal track",
            "outs": [{"path": "reports/mlflow_run.json", "md5": "456"}],
        },
    },
}
"""A ``dvc.lock`` beside the outputs: its hashes are tagged on the parent run."""


@pytest.fixture(autouse=True)
def restore_mlflow_tracking_uri():
    """Undo ``mlflow.set_tracking_uri`` (it also sets ``MLFLOW_TRACKING_URI`` process-wide)."""
    before = os.environ.get("MLFLOW_TRACKING_URI")
    yield
    mlflow.set_tracking_uri(before)
    if before is None:
        os.environ.pop("MLFLOW_TRACKING_URI", None)


@pytest.fixture(scope="session")
def outputs() -> EvaluateOutputs:
    """The evaluate outputs in memory, built once (the fits take well under a second)."""
    return build_outputs()


@pytest.fixture(scope="session")
def empty_store(tmp_path_factory) -> Path:
    """A migrated, empty MLflow SQLite database, copied by each test (creation takes ~2 s)."""
    path = tmp_path_factory.mktemp("store") / "mlflow.db"
    empty_database(path)
    return path


def evaluated_folder(root: Path, empty_store: Path, outputs: EvaluateOutputs) -> Path:
    """Fill ``root`` as a repository after ``evaluate``: its outputs and an empty local store."""
    write_evaluate_outputs(root, outputs)
    shutil.copy(empty_store, root / "mlflow.db")
    return root


@pytest.fixture
def workdir(tmp_path, monkeypatch, empty_store, outputs) -> Path:
    """Repo-like tmp folder with evaluate outputs; the default local store in it."""
    evaluated_folder(tmp_path, empty_store, outputs)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    return tmp_path


@pytest.fixture
def client(workdir) -> MlflowClient:
    return store_client(workdir)


def store_client(root: Path) -> MlflowClient:
    """A client of the default local store in ``root``."""
    return MlflowClient(tracking_uri=f"sqlite:///{root / 'mlflow.db'}")


@pytest.fixture(scope="module")
def tracked_once(tmp_path_factory, empty_store, outputs) -> Iterator[Path]:
    """One ``track`` run (a ``dvc.lock`` beside the outputs) for the tests that only read it.

    Tests that change the folder or the store before or after tracking use :func:`workdir`.
    """
    root = evaluated_folder(tmp_path_factory.mktemp("tracked"), empty_store, outputs)
    (root / "dvc.lock").write_text(yaml.safe_dump(DVC_LOCK))
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)
        patch.delenv("MLFLOW_TRACKING_URI", raising=False)
        assert track.main([]) == 0
    yield root


@pytest.fixture
def tracked(tracked_once, monkeypatch) -> Path:
    """The folder of :func:`tracked_once`, the working directory (artifacts are found there)."""
    monkeypatch.chdir(tracked_once)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    return tracked_once


def test_fixture_scores_follow_the_schema_and_the_protocol(outputs):
    scores = outputs.scores
    per_child = scores.groupby(list(records.KEY_COLUMNS)).size()
    assert set(per_child.index) == CHILDREN
    assert (per_child == len(UNITS) * len(CAMPAIGNS)).all()
    assert set(scores["scheme"]) == {"campaign", "loso", "pooled"}
    assert set(scores["axis"]) == set(AXES)
    for card in outputs.cards.values():
        assert card["inputs"] == ["T2", "T1"] and card["protocol"] == "loso"
        assert card["trained_on"] == ["K01", "K02", "K03", "K04"]


def test_one_child_per_candidate_model_selection_mode(tracked):
    workdir, client = tracked, store_client(tracked)
    parents, children = split_runs(all_runs(client))
    assert len(parents) == 1
    assert {child_key(r) for r in children} == CHILDREN
    assert len(children) == len(CHILDREN)
    assert {r.data.tags[records.PARENT_RUN_TAG] for r in children} == {parents[0].info.run_id}
    assert {r.info.run_name for r in children} == {"/".join(key) for key in CHILDREN}
    assert all(r.info.status == "FINISHED" for r in parents + children)
    assert all(r.data.tags["synthetic"] == "true" for r in children)
    assert record(workdir)["child_runs"] == len(CHILDREN)


def test_child_metrics_are_the_headline_scores_and_the_rest_is_in_its_tables(
    tracked, tmp_path_factory
):
    workdir, client = tracked, store_client(tracked)
    _, children = split_runs(all_runs(client))
    by_key = {child_key(r): r for r in children}
    for key, run in by_key.items():
        assert run.data.metrics == pytest.approx(expected_child_metrics(workdir, key))
        assert len(run.data.metrics) <= records.MAX_CHILD_METRICS
    metrics = by_key[("Z", "mlr", "pair", "static")].data.metrics
    assert {
        "S_um",
        "Mn_val_um",
        "loso_Mn_rms_um",
        "pooled_Mn_val_um",
        "loso_eta",
        "loso_winter_rms_um",
        "loso_summer_eta",
        "pooled_val_spring_rms_um",
    } <= set(metrics)
    assert "pooled_Mn_um" not in metrics  # no prediction role when built on all campaigns: null
    assert by_key[("Z", "none", "none", "static")].data.metrics["loso_eta"] == 0.0
    # every (training unit, test campaign) score of the CSV is in the child's table artifact
    tmp = tmp_path_factory.mktemp("artifacts")
    rows = pd.DataFrame(read_scores(workdir))
    for key, run in by_key.items():
        table = table_artifact(client, run.info.run_id, records.SCORES_TABLE, tmp / run.info.run_id)
        mine = rows.set_index(list(records.KEY_COLUMNS)).loc[[key]].reset_index(drop=True)
        assert len(table) == len(mine)
        merged = mine.merge(table, on=["train_unit", "test_campaign"], suffixes=("", "_logged"))
        assert len(merged) == len(mine)
        for column in records.SCORE_COLUMNS:
            logged = merged[f"{column}_logged"].astype(float).to_numpy()
            np.testing.assert_array_equal(merged[column].astype(float).to_numpy(), logged)
    # and each training unit's summary (metrics/cross_season.json by_train_unit)
    metrics = read_json(workdir, "metrics/cross_season.json")["machines"][MACHINE]
    tree = metrics["Z"]["candidates"]["mlr"]["pair"]
    run = by_key[("Z", "mlr", "pair", "static")]
    units = table_artifact(client, run.info.run_id, records.UNITS_TABLE, tmp / "units")
    units = units.set_index("train_unit")
    for unit, entry in tree["static"]["by_train_unit"].items():
        for name, value in entry.items():
            if value is not None:
                assert units.loc[unit, name] == pytest.approx(value)
    listed = {f.path for f in client.list_artifacts(run.info.run_id)}
    assert {
        records.SCORES_TABLE,
        records.UNITS_TABLE,
        records.GROUPS_TABLE,
        records.FITS_TABLE,
        records.HEATMAP,
    } <= listed


def test_child_tags_say_eligible_rank_champion_and_why_not(tracked):
    client = store_client(tracked)
    _, children = split_runs(all_runs(client))
    by_key = {child_key(r): r.data.tags for r in children}
    for (axis, model, selection, mode), tags in by_key.items():
        assert tags["axis"] == axis and tags["model"] == model and tags["mode"] == mode
        assert tags["ranked_by"] == "loso_Mn_rms_um"
        assert tags["champion"] == str((model, selection) == ("mlr", "pair")).lower()
        assert "mlflow.note.content" in tags
        if mode == "one_step":
            assert tags["eligible"] == "false" and "rank" not in tags
            assert "measured error" in tags["ineligible_reason"]
        else:
            assert tags["eligible"] == "true" and "ineligible_reason" not in tags
    for axis in AXES:
        ranks = sorted(int(t["rank"]) for (a, *_), t in by_key.items() if a == axis and "rank" in t)
        assert ranks == list(range(1, len(ranks) + 1))
        assert by_key[(axis, "mlr", "pair", "static")]["rank"] == "1"
    note = by_key[("Z", "mlr", "pair", "static")]["mlflow.note.content"]
    assert "Champion" in note and "winter" in note
    experiment = client.get_experiment_by_name(EXPERIMENT)
    description = experiment.tags["mlflow.note.content"]
    for name in ("loso_", "Mn_um", "Sd_um", "S_um", "eta", "pooled_", "one_step", "free_run"):
        assert name in description


def test_child_params_hold_the_registered_fit_and_the_fits_table_every_unit(
    tracked, outputs, tmp_path
):
    client = store_client(tracked)
    _, children = split_runs(all_runs(client))
    by_key = {child_key(r): r for r in children}
    for (axis, model, selection, mode), run in by_key.items():
        params = run.data.params
        fit = outputs.fitted[f"{axis}/{model}/{selection}/{POOLED_UNIT}"]
        expected = {
            "axis": axis,
            "model": model,
            "selection": selection,
            "mode": mode,
            "inputs": ",".join(fit["inputs"]) or "-",
        }
        for name, value in fit["chosen_params"].items():
            assert json.loads(params[f"chosen.{name}"]) == value
            expected[f"chosen.{name}"] = params[f"chosen.{name}"]
        assert params == expected
        fits = table_artifact(
            client, run.info.run_id, records.FITS_TABLE, tmp_path / run.info.run_id
        )
        fits = fits.set_index("train_unit")
        assert set(fits.index) == set(UNITS)
        for unit in UNITS:
            entry = outputs.fitted[f"{axis}/{model}/{selection}/{unit}"]
            assert fits.loc[unit, "inputs"] == (",".join(entry["inputs"]) or "-")
            assert json.loads(fits.loc[unit, "chosen_params"]) == entry["chosen_params"]
    # MLflow finds the tables as its own log_table leaves them (the loggedArtifacts tag)
    ids = [run.info.run_id for run in children]
    experiment = children[0].info.experiment_id
    loaded = client.load_table(
        experiment, records.FITS_TABLE, run_ids=ids, extra_columns=["run_id"]
    )
    assert set(loaded["run_id"]) == set(ids) and len(loaded) == len(ids) * len(UNITS)
    assert by_key[("Z", "mlr", "pair", "static")].data.params["inputs"] == "T2,T1"
    assert by_key[("X", "ridge", "all", "static")].data.params["chosen.alpha"] == "50.0"
    one_step = by_key[("Z", "ar1", "none", "one_step")].data.params
    assert one_step["inputs"] == "-"
    free_run = by_key[("Z", "ar1", "none", "free_run")].data.params
    assert one_step == free_run | {"mode": "one_step"}


def test_parent_has_champion_scores_selected_sensors_tags_and_artifacts(tracked, outputs):
    workdir, client = tracked, store_client(tracked)
    (parent,), children = split_runs(all_runs(client))
    info = record(workdir)
    tags = parent.data.tags
    assert tags[records.IDENTITY_TAG] == info["run_identity"]
    assert tags["git_commit"] == "unknown"  # tmp folder is not a git repository
    assert tags["synthetic"] == "true"
    assert tags["dvc.data/raw"] == "abc.dir"
    assert tags["dvc.ingest.data/ingested"] == "def.dir"
    assert tags["dvc.evaluate.reports/cross_season_scores.csv"] == "123"
    assert "dvc.track.reports/mlflow_run.json" not in tags  # its own previous output
    expected = {}
    tree = read_json(workdir, "metrics/cross_season.json")["machines"][MACHINE]
    for axis in AXES:
        champion = tree[axis]["champion"]
        assert champion["loso_Mn_rms_um"] == outputs.cards[axis]["scores"]["loso_Mn_rms_um"]
        for key, value in records.flatten(champion).items():
            if value is not None and not isinstance(value, bool):
                expected[f"{axis}.champion.{key}"] = value
        assert tags[f"ranked_by.{axis}"] == "loso_Mn_rms_um"
        assert tags[f"champion.{axis}"] == f"{axis}/mlr/pair/static"
    assert "Z.champion.none.loso_Mn_rms_um" in expected
    expected |= {f"axis_model.{key}": value for key, value in AXIS_METRICS.items()}
    assert parent.data.metrics == expected
    assert tags["skipped.X.twin/roles"] == SKIPPED["twin/roles"]
    params = parent.data.params
    for method, by_unit in SELECTED_SENSORS.items():
        for unit, sensors in by_unit.items():
            assert params[f"selected.Z.{method}.{unit}"] == ",".join(sensors)
    assert params["selected.X.pair.all_training"] == "T2,T1"
    assert params["evaluate.candidates.mlr"] == "pair"
    assert params["track.registered_model"] == REGISTERED
    listed = {f.path for f in client.list_artifacts(parent.info.run_id, "reports")}
    assert {
        "reports/model_comparison.md",
        "reports/cross_season_matrix.csv",
        "reports/cross_season_scores.csv",
        "reports/model_scores.csv",
        "reports/fitted_models.json",
        "reports/validation.json",
        "reports/matrices",
        "reports/comparison",
        "reports/selection",
        "reports/separation",
        "reports/axis_model.json",
    } <= listed
    selection = {f.path for f in client.list_artifacts(parent.info.run_id, "reports/selection")}
    assert selection == {"reports/selection/selected.json", "reports/selection/pair_evidence.csv"}
    assert {f.path for f in client.list_artifacts(parent.info.run_id, "metrics")} == {
        "metrics/cross_season.json"
    }
    stored = workdir / "mlartifacts" / EXPERIMENT / parent.info.run_id / "artifacts"
    assert (stored / "reports" / "matrices" / "vmc-450__Z__mlr__pair__static.png").is_file()
    assert info["metrics"] == len(parent.data.metrics) + sum(len(r.data.metrics) for r in children)
    assert info["tracking_uri"] == "sqlite:///mlflow.db"
    assert info["reused"] is False


def test_each_axis_champion_is_registered_from_its_child_run_and_predicts(tracked, outputs):
    workdir, client = tracked, store_client(tracked)
    info = record(workdir)
    _, children = split_runs(all_runs(client))
    for axis in AXES:
        champion = info["champions"][axis]
        assert champion["registered_model"] == NAMES[axis]
        assert (champion["version"], champion["uri"]) == ("1", URIS[axis])
        assert champion["model"] == "mlr/pair/static" and champion["compensate"] is True
        version = client.get_model_version_by_alias(NAMES[axis], "champion")
        (child,) = [r for r in children if child_key(r) == (axis, "mlr", "pair", "static")]
        assert (str(version.version), version.run_id) == ("1", child.info.run_id)
        assert version.tags["inputs"] == "T2,T1" and version.tags["needs_speed_log"] == "false"
        assert "leave-one-season-out" in version.description
        assert "`loso_Mn_rms_um`" in version.description  # the score's one name
        assert version.tags["ranked_by"] == "loso_Mn_rms_um"
        assert version.tags["trained_on"] == "K01,K02,K03,K04"
        assert "@champion" in client.get_registered_model(NAMES[axis]).description

    mlflow.set_tracking_uri(f"sqlite:///{workdir / 'mlflow.db'}")
    model = mlflow.pyfunc.load_model(URIS["Z"])
    required = [c.name for c in model.metadata.get_input_schema().inputs if c.required]
    assert required == ["T2", "T1"]
    table, rises = temperature_table()
    predicted = np.asarray(model.predict(table), dtype=float)
    card = read_json(workdir, "data/models/champion/vmc-450/Z/champion.json")
    assert card == outputs.cards["Z"]
    estimator = outputs.estimators["Z"]
    expected = estimator.predict(model_inputs(table, InputSpec.from_dict(card["input_spec"])))
    np.testing.assert_array_equal(predicted, expected)
    index = pd.MultiIndex.from_arrays([table["campaign_id"], table["elapsed_s"]], names=INDEX_NAMES)
    by_hand = estimator.predict(rises[card["inputs"]].set_axis(index))
    np.testing.assert_allclose(predicted, by_hand, rtol=0, atol=1e-9)
    first_rows = table.groupby("campaign_id").head(1).index
    np.testing.assert_allclose(predicted[first_rows], estimator.intercept_, atol=1e-9)
    with pytest.raises(mlflow.exceptions.MlflowException, match="T2"):
        model.predict(table.drop(columns="T2"))


def test_a_none_champion_is_registered_and_predicts_no_compensation(workdir, client, outputs):
    summary = candidate_summary(outputs.scores)
    decision = choose_champion(summary, "X", "loso", 0.99)  # no model removes 99 %
    assert decision.label == "none/none/static" and not decision.compensate
    series = synthetic_series("X")
    (pooled,) = [
        fit_and_score(Candidate("none", "none"), unit, series, NoCompensation(), [])
        for unit in training_units(series)
        if unit.name == POOLED_UNIT
    ]
    spec = InputSpec((), "temperature_rise", "first_sample", 1)
    folder = workdir / "data" / "models" / "champion" / "vmc-450" / "X"
    joblib.dump(pooled.estimator, folder / "estimator.joblib")
    card = {**champion_card(decision, pooled, spec, SAMPLE_S), "machine": MACHINE}
    (folder / "champion.json").write_text(json.dumps(card, indent=2, sort_keys=True))
    track.main([])
    _, children = split_runs(all_runs(client))
    version = client.get_model_version_by_alias(NAMES["X"], "champion")
    (child,) = [r for r in children if child_key(r) == ("X", "none", "none", "static")]
    assert version.run_id == child.info.run_id and version.tags["compensate"] == "false"
    assert "NO (predicts zero)" in version.description
    assert record(workdir)["champions"]["X"]["compensate"] is False
    mlflow.set_tracking_uri(f"sqlite:///{workdir / 'mlflow.db'}")
    model = mlflow.pyfunc.load_model(URIS["X"])
    table, _ = temperature_table()
    assert not np.asarray(model.predict(table), dtype=float).any()


def test_missing_champion_warns_and_still_logs_the_runs(workdir, client, caplog):
    shutil.rmtree(workdir / "data" / "models" / "champion")
    caplog.set_level("WARNING", logger="pipeline.tracking.pipeline_run")
    assert track.main([]) == 0
    assert "no champion model to register" in caplog.text
    parents, children = split_runs(all_runs(client))
    assert len(parents) == 1 and len(children) == len(CHILDREN)
    assert parents[0].info.status == "FINISHED"
    info = record(workdir)
    assert info["champions"] == {}
    assert versions(client) == []


def test_missing_optional_reports_and_dvc_lock_are_tolerated(workdir, client):
    (workdir / "reports" / "validation.json").unlink()
    shutil.rmtree(workdir / "reports" / "separation")
    assert track.main([]) == 0
    (parent,), _ = split_runs(all_runs(client))
    assert not any(key.startswith("dvc.") for key in parent.data.tags)
    listed = {f.path for f in client.list_artifacts(parent.info.run_id, "reports")}
    assert "reports/validation.json" not in listed


def test_second_run_on_unchanged_inputs_logs_and_registers_nothing(workdir, client, caplog):
    track.main([])
    first = record(workdir)
    count = len(all_runs(client))
    caplog.set_level("INFO", logger="pipeline.tracking.pipeline_run")
    track.main([])
    second = record(workdir)
    assert len(all_runs(client)) == count
    assert second["reused"] is True
    assert second["parent_run_id"] == first["parent_run_id"]
    assert second["run_identity"] == first["run_identity"]
    assert "already logged" in caplog.text
    assert versions(client) == ["1"]
    assert second["champions"] == first["champions"]
    assert second["champions"]["X"]["version"] == "1"


def _change_scores(root: Path, outputs: EvaluateOutputs) -> None:
    write_scores(
        root, outputs.scores.assign(rmse_um=outputs.scores["rmse_um"] + 0.5), outputs.cards
    )


def _change_params(root: Path, outputs: EvaluateOutputs) -> None:
    params = yaml.safe_load((root / "params.yaml").read_text())
    params["evaluate"]["n_jobs"] = 3
    (root / "params.yaml").write_text(yaml.safe_dump(params))


def _change_data(root: Path, outputs: EvaluateOutputs) -> None:
    (root / "data" / "raw" / "K02" / "temperature.csv").write_text("elapsed_s,T1\n0,20.0\n60,21\n")


@pytest.mark.parametrize("change", [_change_scores, _change_params, _change_data])
def test_changed_scores_params_or_data_log_a_new_parent_and_gate_its_champion(
    workdir, client, outputs, change
):
    track.main([])
    first = record(workdir)
    assert [d["action"] for d in first["promotion"]] == ["promote"] * len(AXES)
    change(workdir, outputs)
    import_path = list(sys.path)
    track.main([])
    # the gate loaded both versions in this process and left its import path as it was
    assert sys.path == import_path
    second = record(workdir)
    assert second["run_identity"] != first["run_identity"]
    assert second["reused"] is False
    parents, children = split_runs(all_runs(client))
    assert len(parents) == 2
    assert len(children) == 2 * len(CHILDREN)
    assert versions(client) == ["1", "2"]  # the new parent registers its champion as well...
    # ...but it predicts V01, the one campaign version 1 never saw, no better: the alias stays
    (gate,) = [d for d in second["promotion"] if d["axis"] == "Z"]
    assert gate["action"] == "keep" and gate["challenger_version"] == "2"
    assert [c["campaign_id"] for c in gate["campaigns"]] == ["V01"]
    assert "not better by the margin" in gate["reason"]
    assert second["champions"]["Z"]["version"] == "1"
    assert str(client.get_model_version_by_alias(NAMES["Z"], "challenger").version) == "2"
    assert client.get_model_version(NAMES["Z"], "2").tags["gate"] == "keep"
    report = (workdir / "reports" / "promotion" / "promotion.md").read_text()
    assert f"| {MACHINE} Z | **keep** | v1 | v2 (mlr/pair/static) | 1 |" in report


def test_returning_to_logged_inputs_leaves_the_alias_where_the_gate_put_it(workdir, client):
    track.main([])
    original = (workdir / "params.yaml").read_text()
    _change_params(workdir, None)
    track.main([])
    assert str(client.get_model_version_by_alias(NAMES["Z"], "champion").version) == "1"
    (workdir / "params.yaml").write_text(original)
    track.main([])
    back = record(workdir)
    assert back["reused"] is True and back["champions"]["Z"]["version"] == "1"
    (gate,) = [d for d in back["promotion"] if d["axis"] == "X"]
    assert gate["action"] == "keep" and "already the champion" in gate["reason"]


def test_identity_is_stable_and_sees_renamed_files(tmp_path, outputs):
    write_evaluate_outputs(tmp_path, outputs)
    scores = [("scores", (tmp_path / "reports" / "cross_season_scores.csv").read_bytes())]
    params = yaml.safe_load((tmp_path / "params.yaml").read_text())
    raw = tmp_path / "data" / "raw"
    mine = [raw / "K01", raw / "K02"]  # the machine's campaign folders
    first = identity.compute_identity([tmp_path / "metrics"], params, mine, scores)
    again = identity.compute_identity([tmp_path / "metrics"], dict(params), mine, scores)
    assert first == again
    (raw / "K03" / "temperature.csv").rename(raw / "K03" / "temperature_renamed.csv")
    other = identity.compute_identity([tmp_path / "metrics"], params, mine, scores)
    assert other == first  # another machine's campaign: not this machine's identity
    (raw / "K01" / "temperature.csv").rename(raw / "K01" / "temperature_renamed.csv")
    moved = identity.compute_identity([tmp_path / "metrics"], params, mine, scores)
    assert moved.parts["data"] != first.parts["data"]
    assert moved.parts["params"] == first.parts["params"]


def test_git_commit_is_tagged_when_in_a_repository(workdir, client):
    git = shutil.which("git")  # DVC needs git too: the project requires it
    assert git is not None, "git is required (dvc repro runs in a git repository)"
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@example.org",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@example.org",
    }
    for command in (["init", "-q"], ["add", "params.yaml"], ["commit", "-q", "-m", "x"]):
        subprocess.run([git, *command], cwd=workdir, env=env, check=True)
    head = subprocess.run([git, "rev-parse", "HEAD"], cwd=workdir, capture_output=True, text=True)
    shutil.rmtree(workdir / "data" / "models" / "champion")  # not needed here: faster
    track.main([])
    (parent,), _ = split_runs(all_runs(client))
    assert parent.data.tags["git_commit"] == head.stdout.strip()
    assert parent.data.tags["mlflow.source.git.commit"] == head.stdout.strip()


def test_metrics_are_logged_in_batches_not_one_by_one(workdir, client, monkeypatch):
    calls = {"log_batch": [], "log_metric": 0}
    original = MlflowClient.log_batch

    def spy(self, run_id, metrics=(), params=(), tags=(), **kwargs):
        # MLflow's log_model re-logs the run's metrics linked to the model (model_id set)
        own = [m for m in metrics if getattr(m, "model_id", None) is None]
        calls["log_batch"].append((run_id, len(own)))
        return original(self, run_id, metrics=metrics, params=params, tags=tags, **kwargs)

    def forbidden(*args, **kwargs):
        calls["log_metric"] += 1

    monkeypatch.setattr(MlflowClient, "log_batch", spy)
    monkeypatch.setattr(MlflowClient, "log_metric", forbidden)
    track.main([])
    run_ids = [r.info.run_id for r in all_runs(client)]
    with_metrics = [run_id for run_id, n in calls["log_batch"] if n]
    assert calls["log_metric"] == 0
    assert sorted(with_metrics) == sorted(run_ids)  # one call per run
    assert sum(n for _, n in calls["log_batch"]) == record(workdir)["metrics"]


def test_a_run_beyond_mlflow_batch_limits_is_logged_whole(client):
    metrics = {f"m{i}": float(i) for i in range(2500)}
    params = {f"p{i}": str(i) for i in range(150)}
    tags = {f"t{i}": str(i) for i in range(130)}
    run = records.RunRecord(name="big", metrics=metrics, params=params, tags=tags)
    experiment_id = client.create_experiment("limits")
    parent_id = store.log_pipeline(client, experiment_id, run, [], [])
    logged = client.get_run(parent_id).data
    assert logged.metrics == metrics
    assert logged.params == params
    assert {k: v for k, v in logged.tags.items() if k.startswith("t")} == tags


def test_missing_evaluate_output_says_what_to_run(workdir):
    (workdir / "reports" / "fitted_models.json").unlink()
    with pytest.raises(FileNotFoundError, match=r"fitted_models.json not found.*dvc repro"):
        track.main([])


def _row_number(rows: list[dict[str, str]], **match: str) -> int:
    """1-based data row of the first row whose columns equal ``match``."""
    return next(i for i, row in enumerate(rows, 1) if all(row[k] == v for k, v in match.items()))


def test_bad_score_cell_names_file_row_and_column(workdir):
    rows = read_scores(workdir)
    number = _row_number(rows, axis="Z", model="mlr", train_unit="K01", test_campaign="V01")
    rows[number - 1]["rmse_um"] = "n/a"
    with pytest.raises(
        ValueError,
        match=rf"cross_season_scores.csv, data row {number}, column 'rmse_um': 'n/a' is not a",
    ):
        records.rows_by_child(rows)
    rows[number - 1]["rmse_um"] = ""
    scores = records.rows_by_child(rows)[("Z", "mlr", "pair", "static")]
    (cell,) = [r for r in scores if (r["train_unit"], r["test_campaign"]) == ("K01", "V01")]
    assert math.isnan(cell["rmse_um"])


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
    parsed = stage_outputs.read_scores(path)
    assert [r["rmse_um"] for r in parsed] == [float(r["rmse_um"]) for r in rows]
    assert [r["train_unit"] for r in parsed] == [r["train_unit"] for r in rows]
    negative = _row_number(rows, model="ridge", train_unit="K02", test_campaign="K03")
    wrong_role = _row_number(rows, model="mlr", train_unit="not_winter", test_campaign="K01")
    rows[negative - 1]["rmse_um"] = "-1.5"
    rows[wrong_role - 1]["role"] = "validation"
    _rewrite_scores(workdir, rows)
    with pytest.raises(ValueError) as caught:
        stage_outputs.read_scores(path)
    message = str(caught.value)
    assert f"data row {negative}, column 'rmse_um': -1.5 fails greater_than_or_equal_to(0)" in (
        message
    )
    assert f"data rows [{wrong_role}]: check role_consistent failed" in message
    assert "dvc repro evaluate" in message
    rows[negative - 1]["rmse_um"] = "n/a"
    _rewrite_scores(workdir, rows)
    with pytest.raises(ValueError, match=r"column 'rmse_um'.*dvc repro evaluate"):
        track.main([])


def test_duplicate_score_row_is_an_error(workdir):
    rows = read_scores(workdir)
    with pytest.raises(
        ValueError,
        match=r"data row 2: axis=X model=none selection=none mode=static train_unit=K01 "
        r"test_campaign=K02 already on data row 1",
    ):
        records.rows_by_child([rows[1], rows[1]])
    _rewrite_scores(workdir, [*rows, rows[1]])
    with pytest.raises(ValueError, match=r"check one_score_per_pair failed"):
        track.main([])


def test_tracking_uri_env_var_overrides_default(workdir, monkeypatch, tmp_path_factory):
    other = tmp_path_factory.mktemp("other") / "other.db"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{other}")
    track.main([])
    assert record(workdir)["tracking_uri"] == f"sqlite:///{other}"
    assert (other.parent / "mlartifacts" / EXPERIMENT).is_dir()
    assert not (workdir / "mlartifacts").exists()
    assert MlflowClient(f"sqlite:///{other}").get_model_version_by_alias(NAMES["Z"], "champion")
    assert store.public_uri("https://user:secret@mlflow.example.org/x") == (
        "https://mlflow.example.org/x"
    )


def test_unreachable_tracking_server_is_a_clear_error(workdir, monkeypatch):
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"http://127.0.0.1:{port}")
    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "0")
    with pytest.raises(
        SystemExit, match=r"tracking store .* cannot be used.*Nothing is lost.*thermal track"
    ):
        track.main([])
    assert not (workdir / "reports" / "mlflow_run.json").exists()


@pytest.mark.slow
def test_track_logs_and_registers_on_a_real_mlflow_server(tmp_path, outputs, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    write_evaluate_outputs(work, outputs)
    thermal = Path(sys.executable).with_name("thermal")
    command = [str(thermal)] if thermal.exists() else [sys.executable, "-m", "pipeline"]
    with running_mlflow_server(tmp_path) as uri:
        env = {**os.environ, "MLFLOW_TRACKING_URI": uri}
        done = subprocess.run(
            [*command, "track"], cwd=work, env=env, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr
        first = record(work)
        monkeypatch.chdir(work)
        monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
        assert track.main([]) == 0  # in-process (faster): must reuse the parent
        assert record(work)["reused"] is True
        assert record(work)["parent_run_id"] == first["parent_run_id"]
        client = MlflowClient(tracking_uri=uri)
        parents, children = split_runs(all_runs(client))
        assert len(parents) == 1
        assert {child_key(r) for r in children} == CHILDREN
        for run in children:
            assert run.data.metrics == expected_child_metrics(work, child_key(run))
        listed = {f.path for f in client.list_artifacts(parents[0].info.run_id, "reports")}
        assert "reports/model_comparison.md" in listed
        assert versions(client) == ["1"] and versions(client, "X") == ["1"]
        assert first["champions"]["Z"]["uri"] == URIS["Z"]
        assert first["tracking_uri"] == uri
        mlflow.set_tracking_uri(uri)
        model = mlflow.pyfunc.load_model(URIS["X"])
        table, _ = temperature_table()
        spec = InputSpec.from_dict(outputs.cards["X"]["input_spec"])
        expected = outputs.estimators["X"].predict(model_inputs(table, spec))
        np.testing.assert_array_equal(np.asarray(model.predict(table), dtype=float), expected)
        table.to_csv(tmp_path / "table.csv", index=False)
        loaded, predicted = predict_without_repository(
            URIS["X"], tmp_path / "table.csv", tmp_path, tracking_uri=uri
        )
    # the model carries the modules its loading imports, not the whole package
    assert ROOT not in loaded.parents and loaded.parent.parent.name == "code"
    assert (loaded.parent / "tracking" / "champion_model.py").is_file()
    assert not (loaded.parent / "stages").exists()
    np.testing.assert_allclose(predicted, expected, rtol=1e-12)
    assert not (work / "mlflow.db").exists()  # nothing went to the default local store


def test_track_leaves_the_process_tracking_uri_alone(workdir):
    track.main([])
    assert "MLFLOW_TRACKING_URI" not in os.environ
    track.main([])
    assert record(workdir)["tracking_uri"] == "sqlite:///mlflow.db"


def test_registering_the_champion_does_not_fetch_every_metric(workdir, monkeypatch):
    fetched = []
    original = MlflowClient.get_metric_history

    def spy(self, run_id, key):
        fetched.append(key)
        return original(self, run_id, key)

    monkeypatch.setattr(MlflowClient, "get_metric_history", spy)
    track.main([])
    assert record(workdir)["champions"]["Z"]["version"] == "1"
    assert fetched == []


def test_incomplete_attempts_of_the_same_execution_are_deleted_live_and_others_kept(workdir):
    client = MlflowClient(tracking_uri=f"sqlite:///{workdir / 'mlflow.db'}")
    experiment_id = store.ensure_experiment(client, EXPERIMENT, None)

    def parent(identity: str, status: str | None) -> str:
        run = client.create_run(experiment_id, tags={records.IDENTITY_TAG: identity})
        if status is not None:
            client.set_terminated(run.info.run_id, status)
        return run.info.run_id

    failed, finished = parent("same", "FAILED"), parent("same", "FINISHED")
    running, other = parent("same", None), parent("other", "FAILED")
    child = client.create_run(experiment_id, tags={records.PARENT_RUN_TAG: failed}).info.run_id
    client.create_registered_model("m")
    version = client.create_model_version("m", f"runs:/{child}/model", run_id=child)

    assert store.discard_incomplete(client, experiment_id, "same") == [failed]
    stage = {
        r: client.get_run(r).info.lifecycle_stage for r in (failed, child, finished, running, other)
    }
    assert stage == {
        failed: "deleted",
        child: "deleted",
        finished: "active",
        running: "active",
        other: "active",
    }
    assert version.version not in {v.version for v in client.search_model_versions("name = 'm'")}
    # a RUNNING parent counts as abandoned once it is older than stale_after_s
    assert store.discard_incomplete(client, experiment_id, "same", stale_after_s=0.0) == [running]


def test_a_score_column_of_whole_numbers_is_read_as_floats(workdir, client, outputs):
    # `none` as the only candidate leaves eta = 0 in every row, written as "0"
    write_scores(workdir, outputs.scores.assign(eta=0.0), outputs.cards)
    assert "eta" in (workdir / "reports" / "cross_season_scores.csv").read_text()
    assert track.main([]) == 0
    assert record(workdir)["child_runs"] == len(CHILDREN)

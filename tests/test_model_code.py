"""A registered champion carries the package modules its loading imports, and only those."""

from __future__ import annotations

import json
from pathlib import Path

import joblib
import mlflow
import numpy as np

from pipeline.models.distributed_lag import DistributedLagRegressor
from pipeline.tracking.champion_model import ChampionModel
from pipeline.tracking.model_code import referenced_modules, write_model_code
from tests.helpers.clean_load import predict_without_repository
from tests.helpers.compensation_bundle import SPEC, campaign, fitted_bundle, offline_prediction

ROOT = Path(__file__).resolve().parents[1]


def _shipped(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*.py")}


def test_the_code_is_the_loader_and_the_estimators_modules_with_their_imports(tmp_path):
    estimator = fitted_bundle("dl").champion.estimator
    assert type(estimator).__module__ == "pipeline.models.distributed_lag"
    shipped = _shipped(write_model_code(estimator, tmp_path).parent)
    assert {
        "pipeline/__init__.py",
        "pipeline/tracking/__init__.py",
        "pipeline/tracking/champion_model.py",
        "pipeline/tracking/model_code.py",
        "pipeline/protocol/serving.py",
        "pipeline/separation/features.py",
        "pipeline/models/__init__.py",
        "pipeline/models/distributed_lag.py",
    } <= shipped
    assert not any(p.startswith(("pipeline/stages/", "pipeline/twin/")) for p in shipped)
    assert "pipeline/plots.py" not in shipped and "pipeline/tracking/store.py" not in shipped
    assert len(shipped) < len(list((ROOT / "pipeline").rglob("*.py"))) / 4


def test_classes_and_functions_inside_containers_are_found():
    module = "pipeline.models.distributed_lag"
    assert module in referenced_modules({"models": [DistributedLagRegressor()]})
    assert module in referenced_modules({"kind": DistributedLagRegressor})
    assert referenced_modules([np.mean]) >= {"numpy"}


def test_a_package_models_champion_loads_and_predicts_where_the_repository_is_absent(tmp_path):
    bundle = fitted_bundle("dl")
    joblib.dump(bundle.champion.estimator, tmp_path / "estimator.joblib")
    card = {"axis": "Z", "input_spec": SPEC.to_dict()}
    (tmp_path / "card.json").write_text(json.dumps(card), encoding="utf-8")
    mlflow.pyfunc.save_model(
        str(tmp_path / "model"),
        python_model=ChampionModel(),
        artifacts={
            "estimator": str(tmp_path / "estimator.joblib"),
            "card": str(tmp_path / "card.json"),
        },
        code_paths=[str(write_model_code(bundle.champion.estimator, tmp_path / "code"))],
    )
    table = campaign(9).drop(columns="thermal_error_um")
    table.to_csv(tmp_path / "table.csv", index=False)
    loaded, predicted = predict_without_repository(
        str(tmp_path / "model"), tmp_path / "table.csv", tmp_path
    )
    assert ROOT not in loaded.parents
    assert loaded.is_relative_to(tmp_path / "model" / "code")
    expected = offline_prediction(bundle, table)
    np.testing.assert_allclose(predicted, expected, rtol=1e-9, equal_nan=True)

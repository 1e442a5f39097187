"""The discrepancy run reaches a real MLflow server whole, whatever effects were named.

Every candidate effect of the twin's registry brings its own calibrated parameters, with units
such as ``um/krpm^2`` that MLflow does not allow in a key. Each effect alone and all of them
together are logged, as the stage logs them, to a real ``mlflow server`` on 127.0.0.1 and read
back: the run is FINISHED, every parameter is there with its value, its unit in a tag.
"""

from __future__ import annotations

import pytest
from mlflow.tracking import MlflowClient

from pipeline.discrepancy.model import EFFECTS, ROLE_NODES, build_model
from pipeline.settings.tracking import TrackingSettings
from pipeline.tracking.discrepancy_run import log_discrepancy_run
from tests.helpers.mlflow_server import running_mlflow_server

pytestmark = pytest.mark.slow

CASES = [(effect,) for effect in EFFECTS] + [tuple(EFFECTS)]
"""Each effect of the registry alone, then all of them named one after the other."""


def _effect_parameters(effects: tuple[str, ...]) -> list[dict]:
    """The ``steps`` of a search that named ``effects`` in order, each with the parameters (and
    units) the twin gains when the effect is added, at a value inside their bounds."""
    roles = set(ROLE_NODES) | {"ambient"}
    steps, before = [], {spec.name for spec in build_model(roles).param_specs}
    for k, effect in enumerate(effects, start=1):
        specs = build_model(roles, effects[:k]).param_specs
        added = [spec for spec in specs if spec.name not in before]
        before |= {spec.name for spec in added}
        steps.append(
            {
                "effect": effect,
                "rmse_um_after": 3.0 / k,
                "effect_parameters": {
                    spec.name: {"value": 0.5 * (spec.lower + spec.upper), "unit": spec.unit}
                    for spec in added
                },
            }
        )
    return steps


def _doc(effects: tuple[str, ...]) -> dict:
    """A ``discrepancy.json`` of a search that named ``effects``."""
    return {
        "status": "tested",
        "synthetic": True,
        "named_effects": list(effects),
        "campaigns": ["H01", "H02"],
        "rmse_um_before": 4.0,
        "rmse_um_after": 3.0 / len(effects),
        "steps": _effect_parameters(effects),
        "per_campaign": {"H01": {"before": {"z_um": 4.0}, "after": {"z_um": 1.0}}},
    }


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_mlflow_server(tmp_path_factory.mktemp("discrepancy-server")) as uri:
        yield uri


@pytest.mark.parametrize("effects", CASES, ids=["+".join(case) for case in CASES])
def test_every_effect_parameter_is_logged_with_its_unit_and_the_run_finishes(
    effects, server, monkeypatch
):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", server)
    doc = _doc(effects)
    run_id = log_discrepancy_run([], doc, TrackingSettings(), "discrepancy-keys")
    run = MlflowClient(tracking_uri=server).get_run(run_id)
    assert run.info.status == "FINISHED"
    assert run.data.params["named_effects"] == ",".join(effects)
    logged = 0
    for step in doc["steps"]:
        for name, value in step["effect_parameters"].items():
            key = f"{step['effect']}.{name}"
            assert float(run.data.params[key]) == pytest.approx(value["value"])
            assert run.data.tags[f"unit.{key}"] == value["unit"]
            logged += 1
    units = {v["unit"] for s in doc["steps"] for v in s["effect_parameters"].values()}
    if "centrifugal_growth" in effects:
        assert "um/krpm^2" in units  # the unit that once failed the run, now in a tag
    expected = sum(len(s["effect_parameters"]) for s in doc["steps"])
    assert logged == expected
    assert [m.step for m in MlflowClient(server).get_metric_history(run_id, "heldout_rmse_um")] == [
        *range(len(effects) + 1)
    ]


def test_every_registry_effect_brings_parameters_but_ambient_variation():
    """The cases above log something for every effect that has parameters of its own."""
    with_parameters = {
        step["effect"] for step in _effect_parameters(tuple(EFFECTS)) if step["effect_parameters"]
    }
    assert with_parameters == set(EFFECTS) - {"ambient_variation"}

"""The registered model prepares a machine's table exactly as the separate stage prepared the
training campaigns: same windows, same references, same speed responses."""

import json

import numpy as np
import pandas as pd
from sklearn.linear_model import LinearRegression, Ridge

from pipeline.models.registry import make_model
from pipeline.protocol.serving import linear_prediction, predict_run, predict_table
from pipeline.separation.features import InputSpec, SpeedResponses
from pipeline.separation.spindle import SeparationSettings, spindle_thermal_error

SPEED = SpeedResponses((30.0,), (1.0,))


def _logger_table(n=360, interval_s=10.0):
    """One hour of a fast logger: two sensors, the speed switched on after 10 min, a Z probe."""
    t = np.arange(n) * interval_s
    rpm = np.where(t >= 600.0, 4000.0, 0.0)
    heat = np.clip(t - 600.0, 0.0, None) / 3600.0
    return pd.DataFrame(
        {
            "campaign_id": "R1",
            "source_row": np.arange(1, n + 1),
            "elapsed_s": t,
            "rpm": rpm,
            "T1": 20.0 + 3.0 * heat,
            "T2": 21.0 + 0.5 * heat,
            "disp_Z": -8.0 * heat,
        }
    )


def test_a_fast_table_is_served_in_the_training_windows():
    table = _logger_table()
    campaigns = pd.DataFrame(
        [
            {
                "campaign_id": "R1",
                "machine": "m",
                "start": pd.Timestamp("2025-01-01T08:00"),
                "split": "train",
                "season": "winter",
                "synthetic": True,
                "start_state": None,
                "follows": None,
                "sensors_json": json.dumps({"T1": {}, "T2": {}}),
                "displacement_json": json.dumps({"Z": {}}),
            }
        ]
    )
    settings = SeparationSettings(resample_s=60.0, speed=SPEED)
    separated, _ = spindle_thermal_error(campaigns, table, settings)
    inputs = ["T1", "speed_lag_30min"]
    X = separated[["rise_T1", "speed_lag_30min"]].set_axis(inputs, axis=1)
    model = LinearRegression().fit(X, separated["thermal_error_um"])
    spec = InputSpec(tuple(inputs), "temperature_rise", "first_sample", 1, SPEED, 60.0)

    served = predict_table(model, table.drop(columns=["disp_Z", "source_row"]), spec)

    assert len(separated) == 60 and served.shape == (360,)
    trained = model.predict(X)  # on the training windows: their mean instants and inputs
    expected = np.interp(table["elapsed_s"], separated["elapsed_s"], trained)
    np.testing.assert_allclose(served, expected, atol=1e-9)
    unwindowed = InputSpec(spec.inputs, spec.features, spec.reference, 1, SPEED, None)
    assert not np.allclose(predict_table(model, table, unwindowed), served)  # the window matters


def test_rows_with_a_missing_input_get_no_prediction_the_others_do():
    table = _logger_table(n=20, interval_s=60.0).drop(columns=["disp_Z", "source_row"])
    table.loc[3, "T1"] = np.nan
    spec = InputSpec(("T1",), "temperature_rise", "first_sample", 1, None, 60.0)
    model = LinearRegression().fit(pd.DataFrame({"T1": [0.0, 1.0]}), [0.0, 2.0])
    served = predict_table(model, table, spec)
    assert np.isnan(served[3]) and np.isfinite(np.delete(served, 3)).all()
    rows = [0, 19]
    np.testing.assert_allclose(served[rows], 2.0 * (table["T1"].iloc[rows] - 20.0), atol=1e-9)


def test_the_runtime_s_array_path_predicts_what_a_table_of_several_runs_gets():
    """Two runs in one table (the general path) against each run alone as arrays (the runtime's
    path), through windows, a missing reading and a lagged model."""
    first = _logger_table()
    second = _logger_table(n=300).assign(campaign_id="R2", T1=lambda t: t["T1"] + 0.4)
    second.loc[50, "T2"] = np.nan
    table = pd.concat([first, second], ignore_index=True).drop(columns=["disp_Z", "source_row"])
    spec = InputSpec(
        ("T1", "T2", "speed_lag_30min"), "temperature_rise", "first_sample", 1, SPEED, 60.0
    )
    walk = np.cumsum(np.random.default_rng(3).normal(size=(40, 3)), axis=0)
    X = pd.DataFrame(
        walk,
        columns=list(spec.inputs),
        index=pd.MultiIndex.from_arrays(
            [["A"] * 40, np.arange(40) * 60.0], names=["campaign_id", "elapsed_s"]
        ),
    )
    model = make_model("dl").fit(X, 2.0 * X["T1"] - X["T2"] + 0.5 * X["speed_lag_30min"])

    served = predict_table(model, table, spec)

    for run in ("R1", "R2"):
        rows = table["campaign_id"] == run
        part = table[rows]
        alone = predict_run(
            model,
            part["elapsed_s"].to_numpy(),
            part[["T1", "T2"]].to_numpy(),
            part["rpm"].to_numpy(),
            spec,
        )
        np.testing.assert_allclose(alone, served[rows.to_numpy()], rtol=0, atol=1e-9)
        assert np.isfinite(alone).all()


def test_a_linear_regression_is_applied_as_its_formula_and_other_models_by_predict():
    """The runtime's shortcut for scikit-learn's linear regression gives what ``predict`` gives;
    any other estimator (a ridge here) is left to its own ``predict``."""
    rng = np.random.default_rng(5)
    X = pd.DataFrame(rng.normal(size=(50, 3)), columns=["T1", "T2", "T3"])
    y = X @ np.array([1.5, -0.7, 0.2]) + 3.0 + rng.normal(scale=0.1, size=50)
    linear = LinearRegression().fit(X, y)
    rows = rng.normal(size=(7, 3))
    shortcut = linear_prediction(linear, rows)
    expected = linear.predict(pd.DataFrame(rows, columns=X.columns))
    np.testing.assert_allclose(shortcut, expected, rtol=0, atol=1e-12)
    assert linear_prediction(Ridge().fit(X, y), rows) is None
    two_targets = LinearRegression().fit(X, np.column_stack([y, -y]))
    assert linear_prediction(two_targets, rows) is None

    second = _logger_table(n=200).assign(campaign_id="R2")
    table = pd.concat([_logger_table(), second], ignore_index=True)
    table = table.drop(columns=["disp_Z", "source_row"])
    spec = InputSpec(("T1", "T2"), "temperature_rise", "first_sample", 1, None, 60.0)
    rises = np.random.default_rng(6).normal(size=(30, 2))
    fitted = LinearRegression().fit(pd.DataFrame(rises, columns=["T1", "T2"]), rises @ [2.0, 1.0])
    served = predict_table(fitted, table, spec)  # several runs: the table path, ``predict``
    first = table[table["campaign_id"] == "R1"]
    arrays = (first["elapsed_s"].to_numpy(), first[["T1", "T2"]].to_numpy(), first["rpm"])
    by_formula = predict_run(fitted, *arrays, spec)
    np.testing.assert_allclose(by_formula, served[: len(first)], rtol=0, atol=1e-12)

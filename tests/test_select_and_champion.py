import numpy as np
import pandas as pd
import pytest
from sklearn.linear_model import LinearRegression

from pipeline.champion import rank_candidates, temperature_features
from pipeline.comparison_report import score_table
from pipeline.select import select_all, selected_record, sensor_columns, stability_table
from pipeline.training_units import campaign_series, training_units


def _table(n=40):
    rng = np.random.default_rng(3)
    frames = []
    for campaign, split, season in [
        ("K1", "train", "winter"),
        ("K2", "train", "summer"),
        ("K3", "train", "summer"),
        ("V1", "validation", "autumn"),
    ]:
        t = np.arange(n) * 180.0
        heat = 1 - np.exp(-t / 3000)
        rises = {f"rise_T{j}": g * heat + rng.normal(0, 0.05, n)
                 for j, g in zip((1, 2, 10), (5.0, 2.0, 1.0), strict=True)}  # fmt: skip
        frames.append(pd.DataFrame({
            "campaign_id": campaign, "split": split, "season": season, "elapsed_s": t, **rises,
            "thermal_error_um": 3 * rises["rise_T1"] + rng.normal(0, 0.1, n),
        }))  # fmt: skip
    return pd.concat(frames, ignore_index=True)


def test_select_runs_every_method_on_every_unit_and_counts_stability():
    table = _table()
    sensors = sensor_columns(table)
    assert sensors == ["T1", "T2", "T10"]
    series = campaign_series(table, sensors, "rise_")
    units = training_units(series)
    selections = select_all(series, units, {"all": {}, "gra_top_k": {"k": 1}})
    record = selected_record("temperature_rise", selections)
    assert set(record["methods"]["gra_top_k"]) == {u.name for u in units}
    assert record["methods"]["all"]["K1"]["sensors"] == sensors
    stability = stability_table(selections, units, sensors).set_index(["method", "sensor"])
    assert stability.loc[("all", "T10"), "times_chosen"] == 3
    chosen = stability.loc["gra_top_k", "times_chosen"]
    assert chosen.sum() == 3 and chosen.max() <= 3
    assert stability["frequency"].between(0, 1).all()


def _summary():
    return pd.DataFrame({
        "model": ["arma", "arma", "mlr", "dl"], "selection": ["none", "none", "all", "all"],
        "mode": ["one_step", "free_run", "static", "static"],
        "Mn_um": [0.5, 9.0, 2.0, 2.5], "Mn_val_um": [0.4, 8.0, 1.9, 1.7],
    })  # fmt: skip


def test_champion_ignores_one_step_scores_which_need_the_measured_error():
    ranked, column = rank_candidates(_summary())
    assert column == "Mn_val_um"
    assert list(ranked["model"]) == ["dl", "mlr", "arma"]


def test_without_validation_campaigns_the_champion_is_chosen_on_mn():
    ranked, column = rank_candidates(_summary().assign(Mn_val_um=np.nan))
    assert column == "Mn_um" and ranked.iloc[0]["model"] == "mlr"


def test_without_any_prediction_score_there_is_no_champion_and_the_error_says_why():
    with pytest.raises(ValueError, match="add a training campaign or a validation campaign"):
        rank_candidates(_summary().drop(columns=["Mn_um", "Mn_val_um"]))


def test_report_table_puts_online_only_candidates_last_and_the_champion_in_bold():
    text = score_table(_summary(), {"model": "dl", "selection": "all", "mode": "static"})
    rows = [line for line in text.splitlines()[2:]]
    assert rows[0].startswith("| **dl** |") and "one_step" in rows[-1]


def test_champion_input_is_the_rise_from_each_runs_first_row():
    card = {"model": "mlr", "selection": "all", "sensors": ["T2", "T1"],
            "features": "temperature_rise"}  # fmt: skip
    table = pd.DataFrame({"campaign_id": ["a", "a", "b", "b"], "T1": [20.0, 21.0, 18.0, 18.5],
                          "T2": [19.0, 19.5, 17.0, 19.0], "T9": 0.0})  # fmt: skip
    X = temperature_features(table, card)
    assert list(X.columns) == ["T2", "T1"]
    np.testing.assert_allclose(X.to_numpy(), [[0, 0], [0.5, 1.0], [0, 0], [2.0, 0.5]])
    model = LinearRegression().fit(X, [0.0, 1.0, 0.0, 2.0])
    assert model.predict(X).shape == (4,)
    with pytest.raises(ValueError, match=r"lacks sensor column\(s\) \['T2'\]"):
        temperature_features(table.drop(columns="T2"), card)

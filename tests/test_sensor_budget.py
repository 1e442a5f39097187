"""Fallbacks without a lost sensor and the sensor budget, on synthetic campaigns.

The thermal error is driven by sensor T1 and a speed response; T2 is a weak, partly redundant
sensor and T3 and T4 are useless (independent drifts).
"""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from pipeline.compensation.sensor_budget import (
    BUDGET_COLUMNS,
    NO_FALLBACK,
    POOLED_INPUTS,
    UNIT_SELECTION,
    budget_figure,
    fallback_fits,
    heldout_units,
    residualise,
    sensor_budget,
    unit_subsets,
)
from pipeline.protocol.units import INDEX_NAMES, CampaignSeries, training_units

SPEED = "speed_lag_90min"
SENSORS = ["T1", "T2", "T3", "T4"]
CAMPAIGNS = [
    ("K01", "train", "winter"),
    ("K02", "train", "winter"),
    ("K03", "train", "spring"),
    ("K04", "train", "spring"),
    ("K05", "train", "summer"),
    ("K06", "train", "summer"),
    ("V01", "validation", "autumn"),
]
N_SAMPLES = 80


def _campaign(number: int, campaign: str, split: str, season: str, rng) -> CampaignSeries:
    t = np.arange(N_SAMPLES) * 180.0
    tau = 2500.0 + 700.0 * number
    drive = (5.0 + number) * (1.0 - np.exp(-t / tau))
    speed = np.clip(np.sin(t / (4000.0 + 300.0 * number) + number), 0.0, None)
    speed = np.convolve(speed, np.full(10, 0.1))[:N_SAMPLES]
    columns = {
        "T1": drive + rng.normal(0.0, 0.05, N_SAMPLES),
        "T2": 0.4 * drive + np.cumsum(rng.normal(0.0, 0.3, N_SAMPLES)),
        "T3": np.cumsum(rng.normal(0.0, 0.3, N_SAMPLES)),
        "T4": np.cumsum(rng.normal(0.0, 0.3, N_SAMPLES)),
        SPEED: speed,
    }
    target = 3.0 * drive + 4.0 * speed + rng.normal(0.0, 0.2, N_SAMPLES)
    index = pd.MultiIndex.from_arrays([np.full(N_SAMPLES, campaign), t], names=INDEX_NAMES)
    return CampaignSeries(campaign, split, season, pd.DataFrame(columns, index), target)


@pytest.fixture(scope="module")
def series() -> list[CampaignSeries]:
    rng = np.random.default_rng(3)
    return [_campaign(i, *spec, rng) for i, spec in enumerate(CAMPAIGNS)]


@pytest.fixture(scope="module")
def units(series):
    return training_units(series)


def _card(inputs, model="mlr"):
    return {
        "axis": "Z",
        "model": model,
        "selection": "best_subset",
        "mode": "static",
        "inputs": list(inputs),
    }


def test_budget_with_the_driving_sensor_beats_a_useless_one_and_has_its_columns(series, units):
    useless = _card(["T3", SPEED])
    table = sensor_budget(series, units, useless, {}, "loso", max_k=3)
    assert list(table.columns) == BUDGET_COLUMNS
    assert list(table["choice"]) == ["min_rss"] * 3 + ["champion"]
    assert list(table["k"]) == [1, 2, 3, 1]
    best = table[table["choice"] == "min_rss"].set_index("k")
    champion = table[table["choice"] == "champion"].iloc[0]
    assert best.loc[1, "sensors"] == "T1"
    assert best.loc[1, "stability"] == 1.0
    assert best.loc[1, "heldout_rms_um"] < 0.5 * champion["heldout_rms_um"]
    assert (table["n_campaigns"] == 6).all()
    assert (table["heldout_rms_um"] < table["none_rms_um"]).all()
    expected = 1.0 - table["heldout_rms_um"] / table["none_rms_um"]
    np.testing.assert_allclose(table["eta"], expected)
    assert set(table["speed_inputs"]) == {SPEED}


def test_fallback_without_the_driving_sensor_scores_worse_than_the_champion(series, units):
    card = _card(["T1", "T2", SPEED])
    fallbacks = {f.lost: f for f in fallback_fits(series, units, card, {}, "loso")}
    assert set(fallbacks) == {"T1", "T2"}
    lost_driver, lost_weak = fallbacks["T1"], fallbacks["T2"]
    assert lost_driver.inputs == ("T2", SPEED)
    assert lost_driver.heldout_rms_um > 2.0 * lost_driver.champion_rms_um
    assert lost_weak.heldout_rms_um < 1.2 * lost_weak.champion_rms_um
    for fallback in fallbacks.values():
        assert fallback.n_campaigns == 6
        assert fallback.inputs_rule == POOLED_INPUTS
        assert fallback.heldout_rms_um < fallback.none_rms_um
    prediction = lost_driver.estimator.predict(series[-1].features[list(lost_driver.inputs)])
    assert prediction.shape == (N_SAMPLES,) and np.isfinite(prediction).all()


def test_fallback_uses_each_units_own_selection_when_given(series, units):
    card = _card(["T1", "T2", SPEED])
    own = {u.name: {"inputs": ["T1", "T3", SPEED]} for u in units}
    selected = {"axes": {"Z": {"best_subset": own}}}
    fallbacks = {f.lost: f for f in fallback_fits(series, units, card, {}, "loso", selected)}
    assert {f.inputs_rule for f in fallbacks.values()} == {UNIT_SELECTION}
    # T2 is in no unit's own selection: its fallback is the champion on every held-out unit.
    assert fallbacks["T2"].heldout_rms_um == pytest.approx(fallbacks["T2"].champion_rms_um)
    assert fallbacks["T2"].inputs == ("T1", SPEED)


def test_single_sensor_champion_has_no_fallback_model_and_none_has_no_fallback(series, units):
    (only,) = fallback_fits(series, units, _card(["T1"]), {}, "loso")
    assert only.estimator is None and only.inputs == () and only.note == NO_FALLBACK
    assert np.isnan(only.heldout_rms_um) and only.champion_rms_um < only.none_rms_um
    assert fallback_fits(series, units, _card([], model="none"), {}, "loso") == []
    assert fallback_fits(series, units, _card([], model="arma"), {}, "loso") == []
    assert sensor_budget(series, units, _card([], model="none"), {}, "loso").empty


def test_a_units_choice_never_depends_on_its_held_out_campaigns(series, units):
    unit = next(u for u in heldout_units(units, "loso") if u.name == "not_winter")
    pooled = next(u for u in units if u.name == "all_training")
    before = unit_subsets(series, unit, SENSORS, [SPEED], 3)
    pooled_before = unit_subsets(series, pooled, SENSORS, [SPEED], 3)
    rng = np.random.default_rng(11)
    wild = []
    for item in series:
        if item.season != "winter":
            wild.append(item)
            continue
        features = item.features.copy()
        features["T4"] = np.cumsum(rng.normal(0.0, 5.0, N_SAMPLES))
        target = 1000.0 * features["T4"].to_numpy()
        wild.append(replace(item, features=features, target=target))
    assert unit_subsets(wild, unit, SENSORS, [SPEED], 3) == before
    assert unit_subsets(wild, pooled, SENSORS, [SPEED], 3) != pooled_before
    assert before[1] == ("T1",)


def test_partialling_out_the_speed_gives_the_full_regressions_rss():
    rng = np.random.default_rng(5)
    rises, speed = rng.normal(size=(60, 3)), rng.normal(size=(60, 2))
    error = rises @ [1.0, -2.0, 0.5] + speed @ [3.0, 1.0] + 2.0 + rng.normal(size=60)
    residual_rises, residual_error = residualise(rises, error, speed)
    subset = residual_rises[:, :2]
    reduced = residual_error - subset @ np.linalg.lstsq(subset, residual_error, rcond=None)[0]
    design = np.column_stack([np.ones(60), speed, rises[:, :2]])
    full = error - design @ np.linalg.lstsq(design, error, rcond=None)[0]
    assert np.sum(reduced**2) == pytest.approx(np.sum(full**2), rel=1e-10)


def test_budget_figure_is_written(series, units, tmp_path):
    table = sensor_budget(series, units, _card(["T1", SPEED]), {}, "loso", max_k=2)
    out = tmp_path / "budget.png"
    budget_figure(table, out)
    assert out.stat().st_size > 10_000

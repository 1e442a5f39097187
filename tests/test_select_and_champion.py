import numpy as np
import pandas as pd
import pytest
from sklearn.linear_model import LinearRegression

from pipeline.protocol.candidates import run_all
from pipeline.protocol.champion import choose_champion, standing
from pipeline.protocol.cross_season import Candidate
from pipeline.protocol.scoring import coverage
from pipeline.protocol.selection_runs import (
    method_entries,
    select_axis,
    selected_record,
    stability_table,
)
from pipeline.protocol.units import series_by_axis, training_units
from pipeline.reporting.comparison import score_table
from pipeline.separation.features import InputSpec, SpeedResponses, model_inputs, speed_responses


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
        rises = {
            f"rise_T{j}": g * heat + rng.normal(0, 0.05, n)
            for j, g in zip((1, 2, 10), (5.0, 2.0, 1.0), strict=True)
        }
        frames.append(
            pd.DataFrame(
                {
                    "axis": "Z",
                    "campaign_id": campaign,
                    "split": split,
                    "season": season,
                    "elapsed_s": t,
                    **rises,
                    "speed_lag_30min": 4 * heat,
                    "thermal_error_um": 3 * rises["rise_T1"] + rng.normal(0, 0.1, n),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def test_select_runs_every_method_on_every_unit_and_counts_stability():
    series = series_by_axis(_table(), "temperature_rise")["Z"]
    inputs = list(series[0].features.columns)
    assert inputs == ["T1", "T2", "T10", "speed_lag_30min"]
    units = training_units(series)
    entries = method_entries(
        {
            "all": {"inputs": "temperatures"},
            "all_speed": {"method": "all"},
            "gra_top_k": {"k": 1},
        }
    )
    selections = {"Z": select_axis(series, units, entries)}
    record = selected_record("temperature_rise", selections)
    assert set(record["axes"]["Z"]["gra_top_k"]) == {u.name for u in units}
    assert record["axes"]["Z"]["all"]["K1"]["inputs"] == ["T1", "T2", "T10"]
    assert record["axes"]["Z"]["all_speed"]["K1"]["inputs"] == inputs
    stability = stability_table(selections["Z"], units, inputs).set_index(["method", "sensor"])
    assert stability.loc[("all", "T10"), "times_chosen"] == 3
    assert stability.loc[("all", "speed_lag_30min"), "times_chosen"] == 0
    chosen = stability.loc["gra_top_k", "times_chosen"]
    assert chosen.sum() == 3 and chosen.max() <= 3
    assert stability["frequency"].between(0, 1).all()
    with pytest.raises(ValueError, match="select.methods.all.inputs"):
        method_entries({"all": {"inputs": "everything"}})


def _summary(best_model_rms=2.0):
    rms = np.array([0.5, 9.8, best_model_rms, best_model_rms + 0.1, 10.0, 0.1])
    return pd.DataFrame(
        {
            "axis": "Z",
            "model": ["arma", "arma", "mlr", "dl", "none", "twin"],
            "selection": ["none", "none", "all", "all", "none", "roles"],
            "mode": ["one_step", "free_run", "static", "static", "static", "static"],
            "loco_Mn_rms_um": rms,
            "loco_eta": 1 - rms / 10.0,
            "loco_coverage": 1.0,
            "Mn_rms_um": [0.5, 9.0, 2.0, 2.5, 10.0, 0.1],
            "pooled_Mn_val_rms_um": [0.4, 8.0, 1.9, 1.7, 9.0, 0.1],
        }
    )


def test_champion_is_chosen_on_the_held_out_protocol_never_on_one_step_or_the_twin():
    decision = choose_champion(_summary(), "Z", "loco", 0.1)
    assert decision.label == "mlr/all/static" and decision.compensate
    assert decision.column == "loco_Mn_rms_um"
    assert list(decision.ranked["model"]) == ["mlr", "dl", "arma", "none"]
    assert decision.none_score == 10.0 and decision.best_score == 2.0
    assert "80 % less" in decision.reason and "leave-one-campaign-out" in decision.reason


def test_without_a_model_beating_none_by_the_margin_the_champion_is_none():
    decision = choose_champion(_summary(best_model_rms=9.5), "Z", "loco", 0.1)
    assert decision.label == "none/none/static" and not decision.compensate
    assert decision.best_score == 9.5
    assert "no model removes 10 %" in decision.reason
    assert choose_champion(_summary(best_model_rms=8.9), "Z", "loco", 0.1).compensate


def test_a_model_that_skips_held_out_campaigns_cannot_be_champion():
    """mlr could not predict a third of the samples none was scored on (an input missing)."""
    summary = _summary()
    summary.loc[summary["model"] == "mlr", "loco_coverage"] = 0.67
    decision = choose_champion(summary, "Z", "loco", 0.1)
    assert decision.label == "dl/all/static"
    assert "mlr" not in set(decision.ranked["model"])
    assert choose_champion(summary, "Z", "loco", 0.1, min_coverage=0.5).label == "mlr/all/static"


def test_coverage_counts_the_held_out_samples_a_candidate_predicted():
    pair = {"axis": "Z", "scheme": "loco", "role": "prediction"}
    none = pd.DataFrame(
        [
            {**pair, "train_unit": f"not_K{i}", "test_campaign": f"K{i}", "n_samples": 100}
            for i in (1, 2, 3)
        ]
    )
    partial = none.iloc[:2].assign(n_samples=[100, 50])  # K3 not predicted, K2 half
    assert coverage(partial, none) == pytest.approx(150 / 300)
    assert coverage(none, none) == 1.0


def test_without_a_held_out_scheme_the_champion_is_none_and_errors_are_clear():
    decision = choose_champion(_summary(), "Z", None, 0.1)
    assert not decision.compensate and "single training campaign" in decision.reason
    with pytest.raises(ValueError, match="add 'none: none'"):
        choose_champion(_summary().query("model != 'none'"), "Z", "loco", 0.1)
    with pytest.raises(ValueError, match="min_improvement"):
        choose_champion(_summary(), "Z", "loco", 1.5)


def test_report_table_puts_candidates_never_chosen_last_and_the_champion_in_bold():
    decision = choose_champion(_summary(), "Z", "loco", 0.1)
    rows = score_table(_summary(), decision).splitlines()[2:]
    assert rows[0].startswith("| **mlr** |")
    assert {tuple(cell.strip() for cell in row.split("|")[1:4]) for row in rows[-2:]} == {
        ("arma", "none", "one_step"),
        ("twin", "roles", "static"),
    }


def test_model_inputs_are_rises_from_each_runs_first_row_and_speed_responses():
    speed = SpeedResponses((30.0,), (1.0,))
    spec = InputSpec(("T2", "T1", "speed_lag_30min"), "temperature_rise", "first_sample", 1, speed)
    table = pd.DataFrame(
        {
            "campaign_id": ["a", "a", "b", "b"],
            "elapsed_s": [0.0, 60.0, 0.0, 60.0],
            "rpm": [3000.0, 3000.0, 0.0, 0.0],
            "T1": [20.0, 21.0, 18.0, 18.5],
            "T2": [19.0, 19.5, 17.0, 19.0],
            "T9": 0.0,
        }
    )
    X = model_inputs(table, spec)
    assert list(X.columns) == ["T2", "T1", "speed_lag_30min"]
    lag = speed_responses(np.array([0.0, 60.0]), np.array([3000.0, 3000.0]), speed).iloc[1, 0]
    np.testing.assert_allclose(
        X.to_numpy(), [[0, 0, 0], [0.5, 1.0, lag], [0, 0, 0], [2.0, 0.5, 0.0]]
    )
    assert lag == pytest.approx(3 * (1 - np.exp(-2 / 60)))
    assert InputSpec.from_dict(spec.to_dict()) == spec and spec.needs_speed
    assert LinearRegression().fit(X, [0.0, 1.0, 0.0, 2.0]).predict(X).shape == (4,)
    with pytest.raises(ValueError, match=r"lacks column\(s\) \['rpm'\]"):
        model_inputs(table.drop(columns="rpm"), spec)
    temperatures_only = InputSpec(("T1",), "temperature_rise", "mean_first_n", 2)
    rises = model_inputs(table.drop(columns=["rpm", "elapsed_s"]), temperatures_only)
    np.testing.assert_allclose(rises["T1"], [-0.5, 0.5, -0.25, 0.25])


def test_units_whose_campaigns_share_no_sensor_select_nothing_and_fit_nothing():
    table = _table()
    table.loc[table["campaign_id"] == "K1", ["rise_T2", "rise_T10", "speed_lag_30min"]] = np.nan
    table.loc[table["campaign_id"] == "K2", ["rise_T1", "speed_lag_30min"]] = np.nan
    series = series_by_axis(table, "temperature_rise")["Z"]
    units = training_units(series)
    entries = method_entries({"all": {"inputs": "temperatures"}})
    chosen = select_axis(series, units, entries)["all"]
    assert (
        chosen["all_training"].sensors == []
        and "no input" in chosen["all_training"].details["empty"]
    )
    assert chosen["K1"].sensors == ["T1"]
    selected = {"all": {u: {"inputs": sel.sensors} for u, sel in chosen.items()}}
    results = run_all(
        [Candidate("mlr", "all"), Candidate("none", "none")], units, series, selected, {}, 1
    )
    fitted = {(r.candidate.model, r.unit.name) for r in results}
    assert ("mlr", "K1") in fitted and ("mlr", "all_training") not in fitted
    assert ("none", "all_training") in fitted


def test_standing_ranks_the_eligible_and_says_why_the_others_are_not():
    summary = _summary()
    summary.loc[summary["model"] == "dl", "loco_coverage"] = 0.5
    decision = choose_champion(summary, "Z", "loco", 0.1)
    table = standing(summary, decision).set_index(["model", "mode"])
    assert table.loc[("mlr", "static"), ["eligible", "rank", "champion"]].tolist() == [
        True,
        1,
        True,
    ]
    assert table.loc[("arma", "free_run"), "rank"] == 2
    assert table.loc[("none", "static"), "rank"] == 3 and table["champion"].sum() == 1
    reasons = table.loc[~table["eligible"], "ineligible_reason"]
    assert "measured error" in reasons[("arma", "one_step")]
    assert "spindle program" in reasons[("twin", "static")]
    assert "50 % of the held-out samples" in reasons[("dl", "static")]
    assert (table.loc[~table["eligible"], "rank"] == 0).all()
    assert (table.loc[table["eligible"], "ineligible_reason"] == "").all()

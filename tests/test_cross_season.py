import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.linear_model import LinearRegression

from pipeline.protocol.cross_season import Candidate, fit_and_score, modes_of
from pipeline.protocol.units import campaign_series, held_out_schemes, stack, training_units

GAINS = np.array([3.0, -1.5])
CAMPAIGNS = [
    ("K1", "train", "winter"),
    ("K2", "train", "summer"),
    ("K3", "train", "summer"),
    ("V1", "validation", "autumn"),
]
MLR = Candidate("mlr", "all")


def _table(campaigns, seed=0, noisy=()):
    rng = np.random.default_rng(seed)
    noise = np.random.default_rng(seed + 1)  # its own stream: the other campaigns stay the same
    frames = []
    for campaign, split, season in campaigns:
        t = np.arange(50) * 180.0
        rise = np.column_stack([8 * (1 - np.exp(-t / 3000)), 4 * (1 - np.exp(-t / 9000))])
        rise += rng.normal(0, 0.05, rise.shape)
        y = rise @ GAINS
        if campaign in noisy:
            y = y + noise.normal(0, 2.0, len(y))
        frames.append(
            pd.DataFrame(
                {
                    "campaign_id": campaign,
                    "split": split,
                    "season": season,
                    "elapsed_s": t,
                    "rise_T1": rise[:, 0],
                    "rise_T2": rise[:, 1],
                    "thermal_error_um": y,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _run(table, sensors=("T1", "T2")):
    series = campaign_series(table, ["T1", "T2"], "temperature_rise")
    return [
        fit_and_score(MLR, unit, series, LinearRegression(), list(sensors))
        for unit in training_units(series)
    ]


def test_units_are_each_campaign_each_left_out_season_and_all_training():
    series = campaign_series(_table(CAMPAIGNS), ["T1", "T2"], "temperature_rise")
    units = {(u.name, u.scheme): u.campaigns for u in training_units(series)}
    assert units == {
        ("K1", "campaign"): ("K1",),
        ("K2", "campaign"): ("K2",),
        ("K3", "campaign"): ("K3",),
        ("not_winter", "loso"): ("K2", "K3"),
        ("not_summer", "loso"): ("K1",),
        ("all_training", "pooled"): ("K1", "K2", "K3"),
    }


def test_one_season_gives_leave_one_campaign_out_units():
    one_season = [(c, split, "spring") for c, split, _ in CAMPAIGNS]
    series = campaign_series(_table(one_season), ["T1", "T2"], "temperature_rise")
    units = training_units(series)
    held_out = {(u.name, u.scheme): u.campaigns for u in units if u.scheme == "loco"}
    assert held_out == {
        ("not_K1", "loco"): ("K2", "K3"),
        ("not_K2", "loco"): ("K1", "K3"),
        ("not_K3", "loco"): ("K1", "K2"),
    }
    assert held_out_schemes(units) == ["loco"]
    single = training_units(series[:1] + series[3:])
    assert held_out_schemes(single) == []
    assert [u.scheme for u in single] == ["campaign", "pooled"]


def test_score_rows_carry_the_uncompensated_error_and_eta():
    table = _table(CAMPAIGNS)
    series = campaign_series(table, ["T1", "T2"], "temperature_rise")
    unit = training_units(series)[0]
    result = fit_and_score(Candidate("none", "none"), unit, series, _Zero(), [])
    row = result.scores.set_index("test_campaign").loc["K2"]
    target = series[1].target
    assert row["uncompensated_rms_um"] == pytest.approx(np.sqrt(np.mean(target**2)))
    assert row["rmse_um"] == pytest.approx(row["uncompensated_rms_um"])
    assert row["eta"] == pytest.approx(0.0) and row["axis"] == "Z"
    exact = _run(table)[0].scores
    np.testing.assert_allclose(exact["eta"], 1.0, atol=1e-9)


def test_stacked_campaigns_are_contiguous_blocks_with_campaign_index():
    series = campaign_series(_table(CAMPAIGNS), ["T1", "T2"], "temperature_rise")
    X, y = stack(series[:2], ["T2"])
    assert list(X.index.names) == ["campaign_id", "elapsed_s"]
    assert list(X.index.get_level_values(0).unique()) == ["K1", "K2"]
    assert X.shape == (100, 1) and y.shape == (100,)


def test_mlr_recovers_planted_gains_and_roles_follow_the_unit():
    results = _run(_table(CAMPAIGNS))
    for result in results:
        np.testing.assert_allclose(result.estimator.coef_, GAINS, atol=1e-9)
        assert result.scores["resid_std_um"].max() < 1e-9
        roles = dict(zip(result.scores["test_campaign"], result.scores["role"], strict=True))
        assert roles.pop("V1") == "validation"
        for campaign, role in roles.items():
            assert role == ("fit" if campaign in result.unit.campaigns else "prediction")
    assert set(results[0].scores["mode"]) == {"static"}


def test_no_leakage_a_campaign_only_affects_units_that_contain_it():
    clean = _run(_table(CAMPAIGNS))
    noisy = _run(_table(CAMPAIGNS, noisy=("K3",)))
    for before, after in zip(clean, noisy, strict=True):
        if "K3" in before.unit.campaigns:
            assert not np.allclose(before.estimator.coef_, after.estimator.coef_)
            continue
        np.testing.assert_allclose(before.estimator.coef_, after.estimator.coef_)
        unchanged = before.scores["test_campaign"] != "K3"
        pd.testing.assert_frame_equal(before.scores[unchanged], after.scores[unchanged])
        assert after.scores.set_index("test_campaign").loc["K3", "resid_std_um"] > 1.0


def test_campaign_without_a_model_sensor_gets_no_score_row():
    table = _table(CAMPAIGNS)
    table.loc[table["campaign_id"] == "V1", "rise_T2"] = np.nan
    k1 = _run(table)[0]
    assert "V1" not in set(k1.scores["test_campaign"])
    assert np.isnan(k1.predictions[("static", "V1")]).all()


def test_no_training_campaign_is_a_clear_error():
    series = campaign_series(_table([("V1", "validation", "autumn")]), ["T1"], "temperature_rise")
    with pytest.raises(ValueError, match="mark at least one campaign split: train"):
        training_units(series)


class _Zero(RegressorMixin, BaseEstimator):
    """No compensation."""

    def fit(self, X, y):
        self.n_train_ = len(y)
        return self

    def predict(self, X):
        return np.zeros(len(X))


class _History(RegressorMixin, BaseEstimator):
    """Predicts the previous measured error (one step) or zero (free run)."""

    needs_error_feedback = True

    def fit(self, X, y):
        self.n_train_ = len(y)
        return self

    def predict(self, X, y_history=None):
        if y_history is None:
            return np.zeros(len(X))
        return np.concatenate([[0.0], np.asarray(y_history)[:-1]])


def test_error_feedback_models_are_scored_one_step_and_free_run():
    series = campaign_series(_table(CAMPAIGNS), ["T1", "T2"], "temperature_rise")
    unit = training_units(series)[0]
    assert modes_of(_History()) == ("one_step", "free_run")
    result = fit_and_score(Candidate("h", "none"), unit, series, _History(), [])
    by_mode = result.scores.groupby("mode")["rmse_um"].mean()
    assert set(by_mode.index) == {"one_step", "free_run"}
    assert by_mode["one_step"] < by_mode["free_run"]
    measured = series[1].target
    np.testing.assert_allclose(result.predictions[("one_step", "K2")][1:], measured[:-1])

import numpy as np
import pandas as pd
import pytest

from pipeline.cross_season import available_sensors, campaign_series, cross_season
from pipeline.models import make_model

GAINS = np.array([3.0, -1.5])


def _table(campaigns, seed=0, noisy=()):
    rng = np.random.default_rng(seed)
    frames = []
    for campaign, split in campaigns:
        t = np.arange(50) * 180.0
        rise = np.column_stack([8 * (1 - np.exp(-t / 3000)), 4 * (1 - np.exp(-t / 9000))])
        rise += rng.normal(0, 0.05, rise.shape)
        y = rise @ GAINS
        if campaign in noisy:
            y = y + rng.normal(0, 2.0, len(y))
        frames.append(pd.DataFrame({
            "campaign_id": campaign, "split": split, "elapsed_s": t,
            "rise_T1": rise[:, 0], "rise_T2": rise[:, 1], "thermal_error_um": y,
        }))  # fmt: skip
    return pd.concat(frames, ignore_index=True)


CAMPAIGNS = [("K1", "train"), ("K2", "train"), ("K3", "train"), ("V1", "validation")]


def _run(table):
    series = campaign_series(table, ["T1", "T2"], "rise_")
    return cross_season(series, lambda: make_model("mlr"), available_sensors, n_jobs=2)


def test_mlr_recovers_planted_gains_and_scores_near_zero():
    fitted = _run(_table(CAMPAIGNS))
    assert [f.train_campaign for f in fitted] == ["K1", "K2", "K3"]
    for item in fitted:
        np.testing.assert_allclose(item.estimator.coef_, GAINS, atol=1e-9)
        assert item.scores["resid_std_um"].max() < 1e-9
        roles = dict(zip(item.scores["test_campaign"], item.scores["role"], strict=True))
        assert roles.pop(item.train_campaign) == "fit"
        assert roles.pop("V1") == "validation"
        assert set(roles.values()) == {"prediction"}


def test_no_leakage_a_campaign_only_affects_its_own_model_and_its_scores():
    clean = _run(_table(CAMPAIGNS))
    noisy = _run(_table(CAMPAIGNS, noisy=("K3",)))
    for before, after in zip(clean[:2], noisy[:2], strict=True):
        np.testing.assert_allclose(before.estimator.coef_, after.estimator.coef_)
        unchanged = before.scores["test_campaign"] != "K3"
        pd.testing.assert_frame_equal(before.scores[unchanged], after.scores[unchanged])
        assert after.scores.set_index("test_campaign").loc["K3", "resid_std_um"] > 1.0
    assert not np.allclose(clean[2].estimator.coef_, noisy[2].estimator.coef_)


def test_campaign_without_a_model_sensor_scores_nan():
    table = _table(CAMPAIGNS)
    table.loc[table["campaign_id"] == "K2", "rise_T2"] = np.nan
    fitted = _run(table)
    k1 = fitted[0].scores.set_index("test_campaign")
    assert np.isnan(k1.loc["K2", "rmse_um"]) and k1.loc["K2", "n_samples"] == 0
    assert fitted[1].sensors == ["T1"]


def test_no_training_campaign_is_a_clear_error():
    table = _table([("V1", "validation")])
    with pytest.raises(ValueError, match="mark at least one campaign split: train"):
        _run(table)

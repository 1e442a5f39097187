"""Models on the error's own history: each checked against a case with a known answer."""

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter
from sklearn.linear_model import LinearRegression
from statsmodels.tsa.ardl import ARDL
from statsmodels.tsa.arima_process import arma_generate_sample

from pipeline.models.ar_reduced import ReducedOrderAR, knee_order, spectral_peaks
from pipeline.models.ardl import AutoregressiveDistributedLag
from pipeline.models.arma import ARMAErrorModel, difference
from pipeline.models.feedback import check_history, uses_error_feedback
from pipeline.models.identification import cutoff_lag, identify
from pipeline.models.stationarity import reverse_arrangement_test, reverse_arrangements
from pipeline.models.svr import EmbeddedSVR
from pipeline.models.ts_bp import (
    TimeSeriesBPHybrid,
    hybrid_weights,
    prediction_validity,
    relative_precision,
)
from pipeline.models.tv_ar import TimeVaryingAR

FEEDBACK_MODELS = [
    AutoregressiveDistributedLag,
    ARMAErrorModel,
    ReducedOrderAR,
    TimeVaryingAR,
    EmbeddedSVR,
    TimeSeriesBPHybrid,
]


def _frame(n, values=None, campaign=None):
    """Feature table of n rows (one sensor T1), optionally indexed as one campaign."""
    data = {"T1": np.zeros(n) if values is None else values}
    if campaign is None:
        return pd.DataFrame(data)
    index = pd.MultiIndex.from_arrays(
        [[campaign] * n, np.arange(n) * 180.0], names=["campaign_id", "elapsed_s"]
    )
    return pd.DataFrame(data, index=index)


def _warm_up(campaign, seed, n=80):
    """A warm-up campaign: temperature rise and an error following it, 0 at the cold start."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    rise = 4.0 * (1.0 - np.exp(-t / 25.0)) + rng.normal(0.0, 0.05, n)
    rise[0] = 0.0
    y = -3.0 * rise + rng.normal(0.0, 0.2, n)
    y[0] = 0.0
    return _frame(n, rise, campaign), y


# --- the flag and the shared helpers ------------------------------------------------------


def test_every_model_here_needs_error_feedback_and_static_ones_do_not():
    for model in FEEDBACK_MODELS:
        assert model.needs_error_feedback
        assert uses_error_feedback(model())
    assert not uses_error_feedback(LinearRegression())


def test_history_must_match_the_rows_and_be_finite():
    assert check_history(None, 3) is None
    with pytest.raises(ValueError, match="y_history has 2 values but X has 3 rows"):
        check_history(np.zeros(2), 3)
    with pytest.raises(ValueError, match="NaN or infinite"):
        check_history(np.array([0.0, np.nan, 1.0]), 3)


@pytest.mark.parametrize("model", FEEDBACK_MODELS, ids=lambda m: m.__name__)
def test_one_step_prediction_at_t_uses_the_measured_error_only_up_to_t_minus_1(model):
    X, y = _warm_up("A", 1)
    fitted = model().fit(X, y)
    base = fitted.predict(X, y_history=y)
    changed = y.copy()
    changed[40] += 5.0
    moved = fitted.predict(X, y_history=changed)
    np.testing.assert_allclose(moved[:41], base[:41], atol=1e-9)
    assert np.abs(moved[41:] - base[41:]).max() > 1e-6
    with pytest.raises(ValueError, match="y_history has"):
        fitted.predict(X, y_history=y[:-1])


def test_one_step_error_is_the_noise_level_and_free_run_differs():
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(1000)
    y = lfilter([1.0], [1.0, -1.2, 0.5], noise)
    X = _frame(len(y))
    model = ReducedOrderAR(initial_order=16).fit(X, y)
    one_step = model.predict(X, y_history=y)
    free_run = model.predict(X)
    assert np.std(y - one_step) == pytest.approx(1.0, abs=0.1)
    assert np.std(y - free_run) > 1.5
    # free run from rest with a zero-mean AR model stays at its mean
    assert np.abs(free_run).max() < 0.5


# --- reverse-arrangement test -----------------------------------------------------------


def test_reverse_arrangement_statistic_matches_a_hand_count():
    # pairs i < j with x_i > x_j in [3, 1, 2, 5, 4]: (3,1) (3,2) (5,4) -> 3
    assert reverse_arrangements(np.array([3.0, 1.0, 2.0, 5.0, 4.0])) == 3
    result = reverse_arrangement_test(np.array([3.0, 1.0, 2.0, 5.0, 4.0]), n_subseries=5)
    assert result.statistic == 3
    assert result.expected == pytest.approx(5.0)  # k (k - 1) / 4
    assert result.variance == pytest.approx(5 * (50 + 15 - 5) / 72)
    # sub-series means of [1, 3, 2, 2, 6, 0] with L = 2 are [2, 2, 3]: no reverse arrangement
    means_test = reverse_arrangement_test(np.array([1.0, 3.0, 2.0, 2.0, 6.0, 0.0]), 3)
    assert means_test.statistic == 0


def test_reverse_arrangement_rejects_a_trend_and_accepts_white_noise():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(200)
    trend = 0.02 * np.arange(200) + noise
    assert not reverse_arrangement_test(trend).stationary
    assert reverse_arrangement_test(trend).z < -3.0
    assert reverse_arrangement_test(noise).stationary
    with pytest.raises(ValueError, match="needs 3 <= n_subseries"):
        reverse_arrangement_test(noise[:2])


# --- identification and ARMA ------------------------------------------------------------


def test_cutoff_is_abrupt_and_a_geometric_decay_tails():
    band = 0.1
    cut = np.r_[1.0, 0.6, 0.4, np.zeros(18)]
    assert cutoff_lag(cut, band, max_order=6) == 2
    decay = 0.8 ** np.arange(21)
    assert cutoff_lag(decay, band, max_order=6) is None


def test_arma_identification_finds_a_planted_arma_2_1():
    rng = np.random.default_rng(0)
    y = arma_generate_sample([1, -1.3, 0.6], [1, 0.7], 600, distrvs=rng.standard_normal)
    assert identify([y - y.mean()], 6, 4).kind == "ARMA"
    model = ARMAErrorModel().fit(_frame(len(y)), y)
    assert model.order_ == (2, 0, 1)
    np.testing.assert_allclose(model.ar_, [1.3, -0.6], atol=0.1)
    np.testing.assert_allclose(model.ma_, [0.7], atol=0.1)
    assert model.chosen_params_["identified"] == "ARMA"


def test_arma_differences_a_warm_up_curve_and_rejects_a_bad_criterion():
    X, y = _warm_up("A", 2, n=110)
    model = ARMAErrorModel().fit(X, y)
    assert model.order_[1] >= 1
    np.testing.assert_allclose(difference(np.array([1.0, 3.0, 6.0]), 1), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="ic must be one of"):
        ARMAErrorModel(ic="hqic").fit(X, y)


# --- reduced-order AR -------------------------------------------------------------------


def test_ar_reduction_keeps_a_low_order_and_the_planted_frequency():
    f0, radius = 0.1, 0.9
    poly = np.convolve([1.0, -0.5], [1.0, -2 * radius * np.cos(2 * np.pi * f0), radius**2])
    planted = spectral_peaks(-poly[1:], 1.0)["frequency"].to_numpy()
    rng = np.random.default_rng(1)
    y = lfilter([1.0], poly, rng.standard_normal(1200))[200:]
    y = y + 0.3 * rng.standard_normal(len(y))
    model = ReducedOrderAR(initial_order=32).fit(_frame(len(y)), y)
    assert 2 <= model.chosen_params_["order"] <= 4
    assert model.chosen_params_["initial_order"] == 32
    assert len(planted) == 1
    assert np.abs(model.kept_frequencies_ - planted[0]).min() <= 0.02


def test_ar_initial_order_is_capped_by_a_short_campaign():
    X, y = _warm_up("A", 3, n=110)
    model = ReducedOrderAR().fit(X, y)
    assert model.chosen_params_["initial_order"] == 27  # 110 // 4
    with pytest.raises(ValueError, match="initial_order must be >= 1"):
        ReducedOrderAR(initial_order=0).fit(X, y)


def test_knee_is_where_the_aic_stops_falling_fast():
    aic = pd.Series([100.0, 40.0, 20.0, 18.0, 17.0, 16.5], index=range(1, 7))
    assert knee_order(aic) == 3


# --- time-varying AR --------------------------------------------------------------------


def _ar1(coefficients, rng):
    y, previous = np.empty(len(coefficients)), 0.0
    for t, a in enumerate(coefficients):
        previous = a * previous + rng.standard_normal()
        y[t] = previous
    return y


def test_recursive_least_squares_tracks_a_parameter_change():
    rng = np.random.default_rng(0)
    train = _ar1(np.full(400, 0.9), rng)
    switching = _ar1(np.r_[np.full(300, 0.9), np.full(300, 0.5)], rng)
    model = TimeVaryingAR(order=1, forgetting=0.98).fit(_frame(400), train)
    tracked = model.tracked_parameters(_frame(600), switching)["a1"]
    assert tracked.iloc[200:300].mean() == pytest.approx(0.9, abs=0.1)
    assert tracked.iloc[450:].mean() == pytest.approx(0.5, abs=0.1)
    with pytest.raises(ValueError, match="forgetting must be in"):
        TimeVaryingAR(forgetting=1.5).fit(_frame(400), train)
    with pytest.raises(ValueError, match="needs the measured error"):
        model.tracked_parameters(_frame(600), None)


# --- SVR ----------------------------------------------------------------------------------


def test_svr_embedding_is_the_pacf_cutoff_of_the_differenced_series():
    rng = np.random.default_rng(0)
    differences = lfilter([1.0], [1.0, -0.5, -0.3], rng.standard_normal(600))
    y = np.cumsum(differences)
    model = EmbeddedSVR().fit(_frame(len(y)), y)
    assert model.embedding_ == 2
    assert model.chosen_params_["cv"] == "forward-chaining blocks"
    assert set(model.cv_results_["stage"]) == {"coarse", "fine"}
    one_step = model.predict(_frame(len(y)), y_history=y)
    assert np.std(y - one_step) == pytest.approx(1.0, abs=0.15)


def test_svr_cross_validates_by_whole_campaigns():
    parts = [_warm_up(name, seed) for seed, name in enumerate("ABCD")]
    X = pd.concat([p[0] for p in parts])
    y = np.concatenate([p[1] for p in parts])
    model = EmbeddedSVR(n_folds=2).fit(X, y)
    assert model.chosen_params_["cv"] == "leave-campaigns-out"
    assert model.chosen_params_["n_folds"] == 2


def test_svr_predicts_what_scikit_learn_s_svr_predicts_one_step_and_in_free_run():
    X, y = _warm_up("A", 3)
    model = EmbeddedSVR(n_folds=2).fit(X, y)
    m = model.embedding_
    scale = model.difference_scale_

    def by_sklearn(levels: np.ndarray) -> float:
        scaled = model._standardise(levels[:m] - levels[1 : m + 1])[None, :]
        return levels[0] + model.difference_mean_ + scale * model.svr_.predict(scaled)[0]

    one_step = model.predict(X, y_history=y)
    padded = np.r_[np.zeros(m + 1), y]
    expected = [
        by_sklearn(padded[t + m : t - 1 if t else None : -1][: m + 1]) for t in range(len(y))
    ]
    np.testing.assert_allclose(one_step, expected, rtol=0, atol=1e-9)
    free = model.predict(X)
    own = np.zeros(m + 1)
    for t in range(len(y)):
        value = by_sklearn(own)
        assert free[t] == pytest.approx(value, abs=1e-9)
        own = np.r_[value, own[:-1]]


# --- ARDL -----------------------------------------------------------------------------------


def test_ardl_recovers_a_planted_ardl_1_1_and_matches_statsmodels():
    rng = np.random.default_rng(0)
    n = 400
    x = np.cumsum(rng.standard_normal(n)) * 0.3 + rng.standard_normal(n)
    y = np.zeros(n)
    for t in range(1, n):
        y[t] = 0.5 + 0.6 * y[t - 1] + 2.0 * x[t] + 1.0 * x[t - 1] + 0.3 * rng.standard_normal()
    X = _frame(n, x)
    model = AutoregressiveDistributedLag(ic="bic").fit(X, y)
    assert (model.ar_order_, model.dl_order_) == (1, 1)
    np.testing.assert_allclose(model.ar_, [0.6], atol=0.05)
    np.testing.assert_allclose(model.dl_, [[2.0, 1.0]], atol=0.1)
    reference = ARDL(y, 1, X, 1, trend="c", hold_back=4).fit().params.to_numpy()
    np.testing.assert_allclose(np.r_[model.intercept_, model.ar_, model.dl_.ravel()], reference)


def test_ardl_needs_the_fitted_sensors_and_long_enough_campaigns():
    X, y = _warm_up("A", 4)
    model = AutoregressiveDistributedLag().fit(X, y)
    with pytest.raises(ValueError, match="lacks the sensor columns"):
        model.predict(X.rename(columns={"T1": "T9"}))
    with pytest.raises(ValueError, match="too short for lags up to 4"):
        AutoregressiveDistributedLag().fit(X.iloc[:6], y[:6])


# --- TS-BP hybrid ---------------------------------------------------------------------------


def test_validity_and_weights_follow_the_paper():
    y = np.array([0.0, 10.0, 10.0, -10.0])
    y_hat = np.array([5.0, 9.0, 12.0, -30.0])
    # the cold-start sample (y = 0) is left out; A = [0.9, 0.8, 0 (clipped from -1)]
    np.testing.assert_allclose(relative_precision(y, y_hat), [0.9, 0.8, 0.0])
    precision = np.array([0.9, 0.8, 0.0])
    assert prediction_validity(precision) == pytest.approx(
        precision.mean() * (1.0 - precision.std())
    )
    assert hybrid_weights(0.6, 0.2) == pytest.approx((0.75, 0.25))
    assert hybrid_weights(0.0, 0.0) == (0.5, 0.5)
    with pytest.raises(ValueError, match="0 at every sample"):
        relative_precision(np.zeros(3), np.ones(3))


def test_hybrid_weights_favour_the_better_sub_model():
    rng = np.random.default_rng(0)
    n = 110
    # smooth error, temperature only loosely related: the error's history predicts best
    smooth = 10.0 * (1.0 - np.exp(-np.arange(n) / 20.0))
    noisy_temperature = smooth / 2.0 + rng.normal(0.0, 1.0, n)
    ts_case = TimeSeriesBPHybrid(max_epochs=500).fit(_frame(n, noisy_temperature), smooth)
    # error set by the temperature sample by sample, no memory: the BP network predicts best
    temperature = rng.uniform(1.0, 3.0, n)
    bp_case = TimeSeriesBPHybrid(max_epochs=3000).fit(_frame(n, temperature), 4.0 * temperature)
    for model in (ts_case, bp_case):
        k_ts, k_bp = model.chosen_params_["k_TS"], model.chosen_params_["k_BP"]
        assert 0.0 <= k_ts <= 1.0 and 0.0 <= k_bp <= 1.0
        assert k_ts + k_bp == pytest.approx(1.0)
    assert ts_case.k_ts_ > ts_case.k_bp_
    assert bp_case.k_bp_ > bp_case.k_ts_
    X = _frame(n, temperature)
    expected = bp_case.k_ts_ * bp_case.ts_.predict(X) + bp_case.k_bp_ * bp_case.bp_.predict(X)
    np.testing.assert_allclose(bp_case.predict(X), expected)

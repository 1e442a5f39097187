"""Known-answer tests of the series helpers, the DL / PCDL / ridge / PLS models and the BP net."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sklearn.cross_decomposition import PLSRegression
from sklearn.linear_model import Ridge
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from pipeline.models.distributed_lag import DistributedLagRegressor, lag_stop_reason
from pipeline.models.neural import BackPropagationRegressor
from pipeline.models.pcdl import PrincipalComponentDistributedLag
from pipeline.models.penalised_dl import (
    PLSDistributedLag,
    RidgeDistributedLag,
    cv_folds,
    ridge_path,
)
from pipeline.models.series import check_features, history, lagged, segments

PLANTED = {"T1": (1.0, 0.6, 0.3), "T2": (-0.8, -0.5, -0.3)}
PLANTED_INTERCEPT = 2.0


def campaign_index(campaign: str, n: int) -> pd.MultiIndex:
    return pd.MultiIndex.from_arrays(
        [[campaign] * n, np.arange(n) * 180.0], names=["campaign_id", "elapsed_s"]
    )


def smooth_inputs(rng: np.random.Generator, campaigns: list[str], n: int, m: int) -> pd.DataFrame:
    """AR(1) temperatures (phi = 0.9) per campaign, columns T1..Tm."""
    frames = []
    for campaign in campaigns:
        values = np.zeros((n, m))
        for t in range(1, n):
            values[t] = 0.9 * values[t - 1] + rng.normal(size=m)
        frames.append(
            pd.DataFrame(
                values, index=campaign_index(campaign, n), columns=[f"T{j + 1}" for j in range(m)]
            )
        )
    return pd.concat(frames)


def planted_dl(noise: float = 0.05, n: int = 300) -> tuple[pd.DataFrame, np.ndarray]:
    """Two campaigns of y = 2 + sum_j sum_{i<=2} b_{j,i} T_{j,t-i} + noise (b in PLANTED)."""
    rng = np.random.default_rng(7)
    X = smooth_inputs(rng, ["K1", "K2"], n, 2)
    coef = np.concatenate([PLANTED["T1"], PLANTED["T2"]])
    y = PLANTED_INTERCEPT + lagged(X, 2).to_numpy() @ coef + rng.normal(0.0, noise, len(X))
    return X, y


def two_campaigns() -> pd.DataFrame:
    index = campaign_index("A", 3).append(campaign_index("B", 2))
    return pd.DataFrame(
        {"T1": [1.0, 2.0, 3.0, 10.0, 20.0], "T2": [5.0, 6.0, 7.0, 8.0, 9.0]}, index=index
    )


# --- series helpers -----------------------------------------------------------------------------


def test_segments_follow_campaign_blocks_and_plain_index_is_one_series():
    X = two_campaigns()
    assert [s.tolist() for s in segments(X)] == [[0, 1, 2], [3, 4]]
    assert [s.tolist() for s in segments(X.reset_index(drop=True))] == [[0, 1, 2, 3, 4]]


def test_segments_reject_a_campaign_split_in_two_blocks():
    X = two_campaigns()
    shuffled = X.iloc[[0, 3, 1, 2, 4]]
    with pytest.raises(ValueError, match="not contiguous"):
        segments(shuffled)


def test_lagged_restarts_at_campaign_boundary_with_first_sample_padding():
    design = lagged(two_campaigns(), 2)
    assert list(design.columns) == [
        "T1_lag0",
        "T1_lag1",
        "T1_lag2",
        "T2_lag0",
        "T2_lag1",
        "T2_lag2",
    ]
    expected_t1 = [[1, 1, 1], [2, 1, 1], [3, 2, 1], [10, 10, 10], [20, 10, 10]]
    expected_t2 = [[5, 5, 5], [6, 5, 5], [7, 6, 5], [8, 8, 8], [9, 8, 8]]
    np.testing.assert_array_equal(design.iloc[:, :3].to_numpy(), expected_t1)
    np.testing.assert_array_equal(design.iloc[:, 3:].to_numpy(), expected_t2)
    assert design.index.equals(two_campaigns().index)


def test_lagged_order_zero_is_the_input_and_negative_order_is_rejected():
    X = two_campaigns()
    np.testing.assert_array_equal(lagged(X, 0).to_numpy(), X.to_numpy())
    with pytest.raises(ValueError, match="non-negative integer"):
        lagged(X, -1)


def test_history_is_zero_before_each_campaign():
    y = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    expected = [[0, 0], [1, 0], [2, 1], [0, 0], [4, 0]]
    np.testing.assert_array_equal(history(y, two_campaigns(), 2), expected)
    np.testing.assert_array_equal(history(y, segments(two_campaigns()), 2), expected)
    with pytest.raises(ValueError, match="y has 4 values"):
        history(y[:4], two_campaigns(), 1)


def test_check_features_selects_fitted_columns_and_names_missing_ones():
    X = two_campaigns()
    assert list(check_features(X, ["T2", "T1"]).columns) == ["T2", "T1"]
    with pytest.raises(ValueError, match=r"lacks the sensor columns \['T9'\]"):
        check_features(X, ["T1", "T9"])
    with pytest.raises(TypeError, match="pandas DataFrame"):
        check_features(X.to_numpy())


# --- distributed lag ----------------------------------------------------------------------------


def test_stop_rule_on_alt_textbook_example():
    # Alt's fuel-oil regressions (Gujarati ch. 17): order 2 turns x_{t-2} negative -> keep 1.
    significant = np.array([0.001])
    assert lag_stop_reason(["x"], np.array([[0.111, 0.064]]), significant, 0.05) is None
    reason = lag_stop_reason(["x"], np.array([[0.109, 0.071, -0.055]]), significant, 0.05)
    assert "x coefficient changes sign from lag 1" in reason
    reason = lag_stop_reason(["x"], np.array([[0.111, 0.064]]), np.array([0.2]), 0.05)
    assert reason == "x_lag1 insignificant (p = 0.2 > 0.05)"


def test_dl_expedient_rule_recovers_planted_lag_two():
    X, y = planted_dl()
    model = DistributedLagRegressor().fit(X, y)
    assert model.chosen_params_["lag_order"] == 2
    assert model.chosen_params_["lag_rule"].startswith("expedient: stopped at lag 3")
    expected = pd.DataFrame(PLANTED).T.to_numpy()
    np.testing.assert_allclose(model.coef_.to_numpy(), expected, atol=0.03)
    assert model.intercept_ == pytest.approx(PLANTED_INTERCEPT, abs=0.03)
    assert list(model.coef_.index) == ["T1", "T2"]


def test_dl_predictions_for_one_campaign_ignore_other_campaigns():
    X, y = planted_dl()
    model = DistributedLagRegressor(lag=2).fit(X, y)
    only_k2 = X.loc[["K2"]]
    np.testing.assert_allclose(model.predict(only_k2), model.predict(X)[len(X) // 2 :])


def test_dl_fixed_lag_with_too_few_samples_says_what_to_lower():
    X, y = planted_dl(n=3)
    with pytest.raises(ValueError, match=r"too few samples \(6\) for lag order 2 with 2 sensors"):
        DistributedLagRegressor(lag=2).fit(X, y)


# --- principal-component DL ---------------------------------------------------------------------


def design_with_eigenvalues(eigenvalues: np.ndarray, n: int = 200) -> pd.DataFrame:
    """Four columns whose sample correlation matrix is H diag(eigenvalues) H' (H Hadamard / 2)."""
    rng = np.random.default_rng(3)
    raw = rng.normal(size=(n, 4))
    orthonormal, _ = np.linalg.qr(raw - raw.mean(axis=0))
    hadamard = np.array([[1, 1, 1, 1], [1, -1, 1, -1], [1, 1, -1, -1], [1, -1, -1, 1]]) / 2.0
    values = orthonormal * np.sqrt(n - 1) * np.sqrt(eigenvalues) @ hadamard.T
    return pd.DataFrame(
        5.0 + 2.0 * values, index=campaign_index("K1", n), columns=["T1", "T2", "T3", "T4"]
    )


def principal_component_regression(
    train: np.ndarray, y: np.ndarray, n_components: int, test: np.ndarray
) -> np.ndarray:
    mean, sd = train.mean(axis=0), train.std(axis=0, ddof=1)
    z = (train - mean) / sd
    eigenvalues, vectors = np.linalg.eigh(np.corrcoef(z, rowvar=False))
    leading = vectors[:, np.argsort(eigenvalues)[::-1][:n_components]]
    scores = np.column_stack([np.ones(len(z)), z @ leading])
    solution = np.linalg.lstsq(scores, y, rcond=None)[0]
    return solution[0] + ((test - mean) / sd) @ leading @ solution[1:]


def test_pcdl_keeps_components_above_85_percent_and_maps_coefficients_back():
    eigenvalues = np.array([2.4, 0.9, 0.5, 0.2])  # cumulative 0.60, 0.825, 0.95, 1.0
    X = design_with_eigenvalues(eigenvalues)
    y = X.to_numpy() @ np.array([1.0, -2.0, 0.5, 3.0]) + np.random.default_rng(4).normal(
        size=len(X)
    )
    model = PrincipalComponentDistributedLag(lag=0).fit(X, y)
    np.testing.assert_allclose(model.explained_variance_ratio_, eigenvalues / 4.0, atol=1e-12)
    assert model.chosen_params_["n_components"] == 3
    assert model.chosen_params_["explained_variance"] == pytest.approx(0.95)
    fresh = design_with_eigenvalues(eigenvalues[::-1]) * 1.5
    for rows in (X, fresh):
        expected = principal_component_regression(X.to_numpy(), y, 3, rows.to_numpy())
        np.testing.assert_allclose(model.predict(rows), expected, atol=1e-9)
    loose = PrincipalComponentDistributedLag(lag=0, variance_threshold=0.80).fit(X, y)
    assert loose.chosen_params_["n_components"] == 2


def test_pcdl_takes_lag_order_from_the_expedient_rule():
    X, y = planted_dl()
    model = PrincipalComponentDistributedLag().fit(X, y)
    assert model.chosen_params_["lag_order"] == 2
    assert model.coef_.shape == (2, 3)


def test_pcdl_rejects_a_threshold_outside_zero_one():
    X, y = planted_dl()
    with pytest.raises(ValueError, match=r"variance_threshold must be in \(0, 1\)"):
        PrincipalComponentDistributedLag(lag=1, variance_threshold=85).fit(X, y)


# --- ridge and PLS DL ---------------------------------------------------------------------------


def test_cv_folds_hold_out_whole_campaigns_or_contiguous_time_blocks():
    X, _ = planted_dl(n=20)
    folds, scheme = cv_folds(X)
    assert scheme == "leave-one-campaign-out (2 folds)"
    assert [test.tolist() for _, test in folds] == [list(range(20)), list(range(20, 40))]
    one, scheme = cv_folds(X.loc[["K1"]])
    assert scheme == "blocked time order (5 contiguous folds, one campaign)"
    assert np.concatenate([test for _, test in one]).tolist() == list(range(20))
    assert all(np.all(np.diff(test) == 1) for _, test in one)
    with pytest.raises(ValueError, match="too few samples"):
        cv_folds(X.iloc[:3])


def test_ridge_path_matches_scikit_learn_on_standardised_design():
    X, y = planted_dl(noise=1.0, n=50)
    design = lagged(X, 2).to_numpy()
    path = ridge_path(design, y, np.array([5.0]))[0]
    reference = make_pipeline(StandardScaler(), Ridge(alpha=5.0)).fit(design, y)
    np.testing.assert_allclose(path[0] + design @ path[1:], reference.predict(design), atol=1e-9)


def test_ridge_cv_picks_small_penalty_for_exact_data_and_large_for_pure_noise():
    X, y = planted_dl(noise=0.0)
    exact = RidgeDistributedLag().fit(X, y)
    assert exact.chosen_params_ == {
        "lag_order": 2,
        "alpha": min(exact.alphas),
        "cv_scheme": "leave-one-campaign-out (2 folds)",
    }
    noise = np.random.default_rng(5).normal(size=len(X))
    assert RidgeDistributedLag().fit(X, noise).chosen_params_["alpha"] >= 1e3  # shrink to mean
    single = RidgeDistributedLag().fit(X.loc[["K1"]], y[: len(X) // 2])
    assert single.chosen_params_["cv_scheme"].startswith("blocked time order")


def test_pls_cv_uses_all_components_for_an_exact_one_sensor_model():
    X, y = planted_dl(noise=0.0)
    X1 = X[["T1"]]
    y1 = 1.0 + lagged(X1, 2).to_numpy() @ np.array(PLANTED["T1"])
    model = PLSDistributedLag().fit(X1, y1)
    assert model.chosen_params_ == {
        "lag_order": 2,
        "n_components": 3,
        "cv_scheme": "leave-one-campaign-out (2 folds)",
    }
    np.testing.assert_allclose(model.coef_.to_numpy().ravel(), PLANTED["T1"], atol=1e-6)
    assert list(model.cv_mse_.index) == [1, 2, 3]


def test_pls_coefficients_reproduce_scikit_learn_predictions():
    X, y = planted_dl(noise=0.5, n=60)
    model = PLSDistributedLag(max_components=2).fit(X, y)
    design = lagged(X, 2).to_numpy()
    reference = PLSRegression(n_components=model.chosen_params_["n_components"]).fit(design, y)
    np.testing.assert_allclose(model.predict(X), reference.predict(design).ravel(), atol=1e-8)


# --- back-propagation network -------------------------------------------------------------------


def smooth_nonlinear(n: int = 110) -> tuple[pd.DataFrame, np.ndarray]:
    t = np.linspace(0.0, 1.0, n)
    X = pd.DataFrame(
        {"T1": 8.0 * (1 - np.exp(-t / 0.3)), "T2": 5.0 * (1 - np.exp(-t / 0.6)), "T3": 3.0 * t},
        index=campaign_index("K1", n),
    )
    y = 10.0 * np.sin(0.3 * X["T1"].to_numpy()) + 0.4 * X["T2"].to_numpy() ** 2
    return X, y


def test_bp_learns_a_smooth_nonlinear_function_better_than_the_mean():
    X, y = smooth_nonlinear()
    model = BackPropagationRegressor().fit(X, y)
    mse = np.mean((model.predict(X) - y) ** 2)
    assert mse < 0.1 * np.var(y)
    assert model.chosen_params_["train_mse_scaled"] <= 0.01 or model.n_epochs_ == 6000


def test_bp_is_deterministic_given_the_seed():
    X, y = smooth_nonlinear()
    first = BackPropagationRegressor(random_state=1).fit(X, y).predict(X)
    again = BackPropagationRegressor(random_state=1).fit(X, y).predict(X)
    other = BackPropagationRegressor(random_state=2).fit(X, y).predict(X)
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)


def test_bp_rejects_a_non_positive_learning_rate():
    X, y = smooth_nonlinear()
    with pytest.raises(ValueError, match="learning_rate > 0"):
        BackPropagationRegressor(learning_rate=0.0).fit(X, y)

"""Sensitive-point selection: every method against a case with a known answer."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline.selection import (
    SELECTORS,
    Selection,
    best_subset,
    best_subset_naive,
    correlation_grouping,
    fc_grd,
    gra_top_k,
    make_selector,
    select_all,
)
from pipeline.selection.fuzzy import lambda_cut_groups, transitive_closure
from pipeline.selection.grey import grey_relational_degree

# ---------------------------------------------------------------------------- data builders


def planted_clusters(seed: int = 0, n: int = 120) -> tuple[pd.DataFrame, np.ndarray]:
    """Two clusters of sensors: T1-T3 follow a heating curve, T4-T6 a heat-and-cool curve.

    T2 and T5 are the undistorted shapes; their cluster mates carry an extra wiggle. The error
    mixes the two clean shapes, so T2 and T5 are the most related members of their clusters.
    """
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    heating = 1.0 - np.exp(-t / 0.15)
    heat_cool = np.sin(np.pi * t)
    wiggle = 0.1 * np.sin(5.0 * np.pi * t)
    clean = pd.DataFrame(
        {
            "T1": 3.0 * (heating + wiggle),
            "T2": 5.0 * heating,
            "T3": 4.0 * (heating - wiggle),
            "T4": 2.0 * (heat_cool + wiggle),
            "T5": 6.0 * heat_cool,
            "T6": 1.5 * (heat_cool - wiggle),
        }
    )
    temperatures = clean + rng.normal(0.0, 0.01, clean.shape)
    error = 4.0 * heating + 2.0 * heat_cool + rng.normal(0.0, 0.05, n)
    return temperatures, error


def random_problem(seed: int, n: int = 40, m: int = 6) -> tuple[pd.DataFrame, np.ndarray]:
    """Independent sensors and an error depending on all of them weakly, plus noise."""
    rng = np.random.default_rng(seed)
    temperatures = pd.DataFrame(rng.normal(size=(n, m)), columns=[f"T{i + 1}" for i in range(m)])
    error = temperatures.to_numpy() @ rng.normal(0.0, 0.5, m) + rng.normal(0.0, 1.0, n)
    return temperatures, error


def planted_pair(seed: int = 3, n: int = 60, m: int = 6) -> tuple[pd.DataFrame, np.ndarray]:
    """Error = 2 T2 - 3 T5 + small noise; the other sensors are unrelated."""
    rng = np.random.default_rng(seed)
    temperatures = pd.DataFrame(rng.normal(size=(n, m)), columns=[f"T{i + 1}" for i in range(m)])
    error = 2.0 * temperatures["T2"].to_numpy() - 3.0 * temperatures["T5"].to_numpy()
    return temperatures, error + rng.normal(0.0, 0.1, n)


def heating_curves(seed: int = 0, n: int = 110, m: int = 8) -> tuple[pd.DataFrame, np.ndarray]:
    """Near-collinear temperature rises (first-order heating, 3-min sampling) and an error."""
    rng = np.random.default_rng(seed)
    elapsed = np.arange(n) * 180.0
    time_constants = rng.uniform(3e3, 6e3, m)
    rises = rng.uniform(1.0, 8.0, m) * (1.0 - np.exp(-elapsed[:, None] / time_constants))
    rises = rises + rng.normal(0.0, 0.03, rises.shape)
    rises[:, -1] = rises[:, 0] + rng.normal(0.0, 1e-4, n)  # a near-duplicate sensor
    error = 3.0 * rises[:, 0] - 2.0 * rises[:, 3] + rng.normal(0.0, 0.5, n)
    return pd.DataFrame(rises, columns=[f"T{i + 1}" for i in range(m)]), error


# --------------------------------------------------------------------- grey relational degree


def test_grey_relational_degree_matches_hand_computation():
    reference = np.array([0.0, 1.0, 3.0, 4.0])
    comparison = np.array([[0.0, 0.0], [2.0, 3.0], [4.0, 3.0], [8.0, 6.0]])
    # Range-normalised: x0 = [0, .25, .75, 1], x1 = [0, .25, .5, 1], x2 = [0, .5, .5, 1].
    # |x0 - x1| = [0, 0, .25, 0], |x0 - x2| = [0, .25, .25, 0] -> d_min = 0, d_max = .25.
    # xi = (0 + .5 * .25) / (d + .5 * .25): d = 0 -> 1, d = .25 -> .125 / .375 = 1/3.
    expected = np.array([(1 + 1 + 1 / 3 + 1) / 4, (1 + 1 / 3 + 1 / 3 + 1) / 4])
    np.testing.assert_allclose(grey_relational_degree(reference, comparison), expected)


def test_grey_relational_degree_treats_a_mirrored_sensor_like_the_original():
    reference = np.array([0.0, 1.0, 3.0, 4.0])
    rising = np.array([0.0, 2.0, 4.0, 8.0])
    degrees = grey_relational_degree(reference, np.column_stack([rising, -rising]))
    assert degrees[0] == pytest.approx(degrees[1])


def test_grey_relational_degree_rejects_constant_series():
    with pytest.raises(ValueError, match="constant series"):
        grey_relational_degree(np.array([0.0, 1.0, 2.0]), np.ones((3, 1)))


# ------------------------------------------------------------------------- fuzzy clustering


def test_transitive_closure_of_hand_made_similarity_matrix():
    similarity = np.array(
        [
            [1.0, 0.9, 0.2, 0.1],
            [0.9, 1.0, 0.3, 0.5],
            [0.2, 0.3, 1.0, 0.7],
            [0.1, 0.5, 0.7, 1.0],
        ]
    )
    # Closure entry = best bottleneck over all paths: 0-1-3 gives min(.9, .5) = .5 for (0, 3);
    # 0-1-3-2 gives min(.9, .5, .7) = .5 for (0, 2); 1-3-2 gives min(.5, .7) = .5 for (1, 2).
    expected = np.array(
        [
            [1.0, 0.9, 0.5, 0.5],
            [0.9, 1.0, 0.5, 0.5],
            [0.5, 0.5, 1.0, 0.7],
            [0.5, 0.5, 0.7, 1.0],
        ]
    )
    closure = transitive_closure(similarity)
    np.testing.assert_array_equal(closure, expected)
    np.testing.assert_array_equal(lambda_cut_groups(closure, 0.9), [1, 1, 2, 3])
    np.testing.assert_array_equal(lambda_cut_groups(closure, 0.7), [1, 1, 2, 2])
    np.testing.assert_array_equal(lambda_cut_groups(closure, 0.5), [1, 1, 1, 1])


def test_transitive_closure_rejects_a_non_reflexive_matrix():
    with pytest.raises(ValueError, match="reflexive"):
        transitive_closure(np.array([[0.5, 0.2], [0.2, 1.0]]))


@pytest.mark.parametrize("n_groups", [None, 2])
def test_fc_grd_finds_planted_clusters_and_their_most_related_sensor(n_groups):
    temperatures, error = planted_clusters()
    selection = fc_grd(temperatures, error, n_groups=n_groups)
    assert selection.sensors == ["T2", "T5"]
    assert selection.details["n_groups"] == 2
    groups = selection.evidence.set_index("sensor")["group"]
    assert groups[["T1", "T2", "T3"]].nunique() == 1
    assert groups[["T4", "T5", "T6"]].nunique() == 1
    assert groups["T1"] != groups["T4"]
    if n_groups is None:
        assert selection.details["F"] > selection.details["F_crit"]
        assert selection.details["rule"].startswith("F test")


def test_fc_grd_rejects_more_groups_than_sensors():
    temperatures, error = planted_clusters()
    with pytest.raises(ValueError, match="n_groups=7 must be an integer between 1 and the 6"):
        fc_grd(temperatures, error, n_groups=7)


# ------------------------------------------------------------------------------- GRA top-k


def test_gra_top_k_keeps_the_largest_degrees_in_order():
    temperatures = pd.DataFrame(
        {"low": [0.0, 3.0, 3.0, 6.0], "high": [0.0, 2.0, 4.0, 8.0]}  # degrees 8/12 and 10/12
    )
    error = np.array([0.0, 1.0, 3.0, 4.0])
    selection = gra_top_k(temperatures, error, k=1)
    assert selection.sensors == ["high"]
    table = selection.evidence.set_index("sensor")
    assert table.loc["high", "rank"] == 1 and table.loc["low", "rank"] == 2
    assert table.loc["high", "grd"] == pytest.approx(10 / 12)
    assert table.loc["low", "grd"] == pytest.approx(8 / 12)
    assert list(table["chosen"]) == [True, False]


def test_gra_top_k_order_follows_the_degrees():
    temperatures, error = heating_curves()
    degrees = grey_relational_degree(error, temperatures.to_numpy())
    expected = list(temperatures.columns[np.argsort(-degrees, kind="stable")][:4])
    assert gra_top_k(temperatures, error).sensors == expected


def test_gra_top_k_rejects_k_larger_than_the_sensors():
    temperatures, error = planted_clusters()
    with pytest.raises(ValueError, match="k=7 must be an integer between 1 and the 6 usable"):
        gra_top_k(temperatures, error, k=7)


# -------------------------------------------------------------------- correlation grouping


def test_correlation_grouping_keeps_the_most_error_correlated_sensor_per_group():
    temperatures, error = planted_clusters()
    selection = correlation_grouping(temperatures, error, threshold=0.9)
    r_error = [abs(np.corrcoef(temperatures[c], error)[0, 1]) for c in temperatures]
    leader_1 = ["T1", "T2", "T3"][int(np.argmax(r_error[:3]))]
    leader_2 = ["T4", "T5", "T6"][int(np.argmax(r_error[3:]))]
    assert selection.sensors == [leader_1, leader_2] == ["T2", "T5"]
    groups = selection.evidence.set_index("sensor")["group"]
    assert list(groups[["T1", "T2", "T3"]]) == [1, 1, 1]
    assert list(groups[["T4", "T5", "T6"]]) == [2, 2, 2]


def test_correlation_grouping_with_a_strict_threshold_keeps_everyone():
    temperatures, error = planted_clusters()
    selection = correlation_grouping(temperatures, error, threshold=0.999)
    assert sorted(selection.sensors) == sorted(temperatures.columns)


# ---------------------------------------------------------------------------- best subset


def assert_same_answer(fast: Selection, naive: Selection) -> None:
    assert fast.sensors == naive.sensors
    for key in ("winner_aicc", "winner_adj_r2", "n_subsets_singular", "n_subsets_evaluated"):
        assert fast.details[key] == naive.details[key], key
    for key in ("aicc_min", "adj_r2_max"):
        assert fast.details[key] == pytest.approx(naive.details[key], rel=1e-8)
    columns = ["n_sensors", "sensors", "best_adj_r2", "best_aicc", "chosen"]
    pd.testing.assert_frame_equal(fast.evidence[columns], naive.evidence[columns])
    numbers = ["rss_um2", "adj_r2", "aicc"]
    np.testing.assert_allclose(
        fast.evidence[numbers].to_numpy(float), naive.evidence[numbers].to_numpy(float), rtol=1e-8
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("criterion", ["aicc", "adj_r2", "parsimonious"])
def test_best_subset_equals_brute_force_on_random_problem(seed, criterion):
    temperatures, error = random_problem(seed)
    assert_same_answer(
        best_subset(temperatures, error, criterion=criterion),
        best_subset_naive(temperatures, error, criterion=criterion),
    )


def test_best_subset_equals_brute_force_on_near_collinear_heating_curves():
    temperatures, error = heating_curves()
    correlation = np.corrcoef(temperatures.to_numpy(), rowvar=False)
    assert correlation.min() > 0.9 and correlation[0, -1] > 1 - 1e-8
    assert_same_answer(best_subset(temperatures, error), best_subset_naive(temperatures, error))


def test_best_subset_finds_the_planted_pair():
    temperatures, error = planted_pair()
    selection = best_subset(temperatures, error)
    assert sorted(selection.sensors) == ["T2", "T5"]
    assert selection.sensors == ["T5", "T2"]  # dropping T5 (coefficient -3) costs more
    assert selection.details["winner_aicc"] == "T2+T5"
    assert selection.details["search"].startswith("exhaustive: all 63 subsets")
    table = selection.evidence.set_index("n_sensors")
    assert table.loc[2, "sensors"] == "T2+T5" and table.loc[2, "best_aicc"]
    assert list(table.index) == [1, 2, 3, 4, 5, 6]


def test_best_subset_criteria_match_the_formulas_for_one_sensor():
    temperatures, error = planted_pair()
    table = best_subset(temperatures, error).evidence.set_index("n_sensors")
    x = temperatures[table.loc[1, "sensors"]].to_numpy()
    slope, intercept = np.polyfit(x, error, 1)
    rss = float(np.sum((error - slope * x - intercept) ** 2))
    tss = float(np.sum((error - error.mean()) ** 2))
    n, k = len(error), 1
    n_params = k + 2
    aicc = n * np.log(rss / n) + 2 * n_params + 2 * n_params * (n_params + 1) / (n - n_params - 1)
    assert table.loc[1, "rss_um2"] == pytest.approx(rss, rel=1e-10)
    assert table.loc[1, "adj_r2"] == pytest.approx(1 - (rss / (n - k - 1)) / (tss / (n - 1)))
    assert table.loc[1, "aicc"] == pytest.approx(aicc, rel=1e-10)


def test_best_subset_falls_back_above_max_exhaustive():
    temperatures, error = planted_pair()
    selection = best_subset(temperatures, error, max_exhaustive=4)
    assert selection.details["search"].startswith("approximate: forward selection")
    assert "m=6 > max_exhaustive=4" in selection.details["search"]
    assert sorted(selection.sensors) == ["T2", "T5"]
    exact = best_subset(temperatures, error).evidence
    pd.testing.assert_frame_equal(selection.evidence[["sensors"]], exact[["sensors"]])


def test_best_subset_excludes_singular_subsets_like_brute_force():
    temperatures, error = planted_pair()
    duplicated = temperatures.assign(T7=2.0 * temperatures["T2"] + 1.0)
    fast, naive = best_subset(duplicated, error), best_subset_naive(duplicated, error)
    assert fast.details["n_subsets_singular"] == 2**5  # every subset holding both T2 and T7
    assert_same_answer(fast, naive)


def test_best_subset_counts_subsets_without_aicc():
    temperatures, error = random_problem(0, n=7, m=6)
    selection = best_subset(temperatures, error)
    # n = 7 rows: AICc needs k <= n - 4 = 3 sensors; the C(6, 4) + C(6, 5) + C(6, 6) others
    assert selection.details["n_subsets_aicc_undefined"] == 15 + 6 + 1
    assert selection.details["n_subsets_evaluated"] == 63 - 22
    assert selection.evidence["n_sensors"].max() == 3


def test_best_subset_rejects_unknown_criterion():
    temperatures, error = planted_pair()
    with pytest.raises(ValueError, match="criterion='bic' is unknown"):
        best_subset(temperatures, error, criterion="bic")


# ------------------------------------------------------ shared input rules and the registry


@pytest.mark.parametrize("name", sorted(SELECTORS))
def test_every_selector_ignores_empty_and_constant_sensors_and_drops_incomplete_rows(name):
    temperatures, error = planted_clusters()
    temperatures = temperatures.assign(T7=np.nan, T8=0.0)
    temperatures.iloc[5, 0] = np.nan
    first = make_selector(name)(temperatures, error)
    again = make_selector(name)(temperatures, error)
    assert first.method == name
    assert first.sensors == again.sensors
    pd.testing.assert_frame_equal(first.evidence, again.evidence)
    assert "T7" not in first.sensors
    assert (first.evidence == "ignored: all NaN").any(axis=None)
    assert all(isinstance(v, int | float | str) for v in first.details.values())
    if name == "all":
        assert first.details["n_sensors_ignored"] == 1 and "T8" in first.sensors
    else:
        assert first.details["n_sensors_ignored"] == 2 and "T8" not in first.sensors
        assert (first.evidence == "ignored: constant").any(axis=None)
        assert first.details["n_rows_dropped"] == 1


def test_selectors_pool_several_campaigns():
    first, error_1 = planted_clusters(seed=1)
    second, error_2 = planted_clusters(seed=2)
    index = pd.MultiIndex.from_product(
        [["K1", "K2"], np.arange(len(first)) * 180.0], names=["campaign_id", "elapsed_s"]
    )
    pooled = pd.concat([first, second]).set_axis(index)
    selection = fc_grd(pooled, np.concatenate([error_1, error_2]), n_groups=2)
    assert selection.sensors == ["T2", "T5"]
    assert selection.details["n_rows"] == 2 * len(first)


def test_select_all_keeps_every_sensor_with_data():
    temperatures, error = planted_clusters()
    temperatures = temperatures.assign(T7=np.nan)
    temperatures.loc[0, "T7"] = 1.0
    temperatures = temperatures.assign(T8=np.nan)
    selection = select_all(temperatures, error)
    assert selection.sensors == ["T1", "T2", "T3", "T4", "T5", "T6", "T7"]


def test_make_selector_binds_params():
    temperatures, error = planted_clusters()
    assert len(make_selector("gra_top_k", k=2)(temperatures, error).sensors) == 2


def test_make_selector_rejects_unknown_names_and_params():
    with pytest.raises(KeyError, match="registered methods: .*best_subset"):
        make_selector("lasso")
    with pytest.raises(TypeError, match=r"unknown parameter\(s\) \['kk'\]"):
        make_selector("gra_top_k", kk=2)
    with pytest.raises(TypeError, match="accepts no parameters"):
        make_selector("all", k=2)


@pytest.mark.parametrize(
    ("temperatures", "error", "message"),
    [
        (pd.DataFrame(), np.array([]), "temperatures is empty"),
        (pd.DataFrame({"T1": [1.0, 2.0, 3.0]}), np.zeros(2), "error has shape"),
        (pd.DataFrame({"T1": [np.nan] * 4}), np.arange(4.0), "no sensor has any finite value"),
        (pd.DataFrame({"T1": [1.0, 2.0, 3.0, 4.0]}), np.ones(4), "error is constant"),
        (pd.DataFrame({"T1": [1.0, np.nan, np.nan, 4.0]}), np.arange(4.0), "only 2 rows"),
        (np.ones((4, 2)), np.arange(4.0), "must be a pandas DataFrame"),
    ],
)
def test_bad_input_is_rejected_with_a_clear_message(temperatures, error, message):
    exception = TypeError if isinstance(temperatures, np.ndarray) else ValueError
    with pytest.raises(exception, match=message):
        gra_top_k(temperatures, error, k=1)

import numpy as np
import pandas as pd
import pytest

from pipeline.fit_statistics import information_criteria, root_mean_square
from pipeline.protocol.scoring import (
    candidate_summary,
    compensation_ratio,
    group_score_name,
    group_scores,
    metrics_tree,
    residual_std,
    score_matrix,
    summarise,
)
from tests.helpers.score_rows import score_rows, two_campaigns_and_a_season


def test_information_criteria_match_their_definitions_and_aicc_is_undefined_without_room():
    aic, aicc, bic = information_criteria(np.array([2.0, 8.0]), 10, np.array([3, 8]))
    assert aic[0] == pytest.approx(10 * np.log(0.2) + 6)
    assert bic[0] == pytest.approx(10 * np.log(0.2) + 3 * np.log(10))
    assert aicc[0] == pytest.approx(aic[0] + 2 * 3 * 4 / 6)
    assert aicc[1] == pytest.approx(aic[1] + 2 * 8 * 9 / 1)
    assert information_criteria(1.0, 10, 9)[1] == np.inf
    assert information_criteria(0.0, 10, 2)[0] == -np.inf


def test_rms_ignores_missing_values_and_is_nan_without_any():
    assert root_mean_square([3.0, np.nan, -4.0, np.inf]) == pytest.approx(np.sqrt(12.5))
    assert np.isnan(root_mean_square([np.nan]))


def test_residual_std_is_blind_to_offset_rms_is_not():
    residual = np.array([4.0, 4.0, 4.0, 4.0])
    assert residual_std(residual) == 0.0
    assert root_mean_square(residual) == 4.0


def test_residual_std_matches_eq_8_and_ignores_nan():
    e = np.array([1.0, 2.0, 4.0, np.nan])
    expected = np.sqrt(((1 - 7 / 3) ** 2 + (2 - 7 / 3) ** 2 + (4 - 7 / 3) ** 2) / 2)
    assert residual_std(e) == pytest.approx(expected)
    assert np.isnan(residual_std(np.array([1.0])))


def test_summary_uses_other_training_campaigns_for_mn_and_validation_separately():
    scores = pd.DataFrame(
        score_rows(
            "K1",
            [
                ("K1", "train", "fit", 1.0),
                ("K2", "train", "prediction", 3.0),
                ("K3", "train", "prediction", 5.0),
                ("V1", "validation", "validation", 8.0),
            ],
        )
    )
    summary = summarise(scores)
    assert summary["S_um"] == 1.0
    assert summary["Mn_um"] == 4.0
    assert summary["Sd_um"] == pytest.approx(np.sqrt(2.0))
    assert summary["Mn_val_um"] == 8.0 and np.isnan(summary["Sd_val_um"])
    assert summary["Mn_rms_um"] == 8.0
    assert summary["eta"] == pytest.approx(1 - 8.0 / 40.0)  # 1 - mean RMS / mean uncompensated
    assert summary["eta_val"] == pytest.approx(0.8)


def test_eta_is_one_minus_rms_over_the_uncompensated_rms():
    assert compensation_ratio(1.0, 4.0) == 0.75
    assert compensation_ratio(5.0, 4.0) == -0.25
    assert np.isnan(compensation_ratio(1.0, 0.0))


def test_metrics_tree_and_matrix_layout():
    scores = two_campaigns_and_a_season()
    tree = metrics_tree(scores)["Z"]["mlr"]["all"]["static"]
    assert set(tree["by_train_unit"]) == {"K1", "K2", "not_winter"}
    assert tree["S_um"] == pytest.approx(0.75)
    assert tree["Mn_um"] == pytest.approx(2.5)
    assert tree["loso_Mn_um"] == 7.0
    assert tree["by_train_unit"]["not_winter"]["loso_Mn_um"] == 7.0
    assert tree["by_train_unit"]["K1"]["Mn_um"] == 3.0
    # one name per score: the tree's names are the summary table's columns
    summary = candidate_summary(scores).iloc[0]
    for name, value in tree.items():
        if name != "by_train_unit":
            assert summary[name] == pytest.approx(value, nan_ok=True)
    matrix = score_matrix(scores, "resid_std_um")
    assert list(matrix.columns) == ["K1", "K2", "V1"]
    assert list(matrix.index) == ["K1", "K2", "not_winter"]
    assert matrix.loc["K2", "K1"] == 2.0 and matrix.loc["K1", "V1"] == 6.0


def test_candidate_summary_has_one_row_per_candidate_with_scheme_prefixes():
    scores = two_campaigns_and_a_season()
    summary = candidate_summary(scores)
    assert len(summary) == 1
    row = summary.iloc[0]
    assert row["Mn_um"] == pytest.approx(2.5)
    assert row["loso_Mn_um"] == 7.0 and row["loso_Mn_val_um"] == 5.0
    assert row["loso_eta"] == pytest.approx(0.8) and row["axis"] == "Z"
    assert "pooled_Mn_val_um" not in summary and "loco_Mn_um" not in summary


def test_group_scores_per_held_out_season_and_validation_season():
    scores = two_campaigns_and_a_season().assign(
        test_season=lambda t: t["test_campaign"].map(
            {"K1": "winter", "K2": "summer", "V1": "spring"}
        ),
    )
    groups = group_scores(scores).set_index("name")
    # the fit that left winter out, scored on winter's campaign K1: RMS 14 um of 70 um
    assert groups.loc["loso_winter_rms_um", "rms_um"] == pytest.approx(14.0)
    assert groups.loc["loso_winter_rms_um", "eta"] == pytest.approx(1 - 14.0 / 70.0)
    assert groups.loc["loso_winter_rms_um", "n_campaigns"] == 1
    assert "pooled_val_spring_rms_um" not in groups.index  # no pooled rows in this table
    assert group_score_name("pooled", "validation", "spring", "eta") == "pooled_val_spring_eta"
    assert group_score_name("loco", "train", "K07", "rms_um") == "loco_K07_rms_um"

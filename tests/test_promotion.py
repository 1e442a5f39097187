"""The promotion gate: its rule on held-out scores, its report, the aliases it moves, rollback."""

import math

import numpy as np
import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from pipeline.protocol.promotion import (
    CampaignComparison,
    GateDecision,
    compare_campaigns,
    decide_promotion,
    render_report,
)
from pipeline.tracking.promotion import apply_decision, rollback, trained_on, version_by_alias

T = np.arange(10) * 60.0


def _frame(campaign, measured, predicted):
    return pd.DataFrame(
        {
            "campaign_id": campaign,
            "elapsed_s": T[: len(measured)],
            "measured_um": measured,
            "predicted_um": predicted,
        }
    )


def _comparison(campaign, current, challenger, none=10.0):
    return CampaignComparison(campaign, 10, current, challenger, none)


def test_both_champions_are_scored_on_the_samples_both_predict():
    measured = np.linspace(0, 9, 10)
    now = measured + 1.0
    now[:2] = np.nan  # the current champion's input is missing at the start
    new = measured + 0.5
    current = pd.concat([_frame("K5", measured, now), _frame("K6", measured, measured)])
    challenger = _frame("K5", measured, new)  # no held-out prediction of K6
    comparisons, unscored = compare_campaigns(current, challenger, ["K5", "K6", "K7"])
    (k5,) = comparisons
    assert k5.n_samples == 8
    assert k5.current_rms_um == pytest.approx(1.0)
    assert k5.challenger_rms_um == pytest.approx(0.5)
    assert k5.none_rms_um == pytest.approx(np.sqrt(np.mean(measured[2:] ** 2)))
    assert unscored == {
        "K6": "the challenger has no held-out prediction of it",
        "K7": "no sample of it reached the comparison",
    }


def test_the_first_champion_is_promoted_and_a_champion_is_not_its_own_challenger():
    first = decide_promotion("Z", [], 0.05, (None, "1"))
    assert first.promoted and "first registered champion" in first.reason
    same = decide_promotion("Z", [], 0.05, ("3", "3"))
    assert same.action == "keep" and "already the champion" in same.reason
    unseen = decide_promotion("Z", [], 0.05, ("3", "4"))
    assert unseen.action == "keep" and "nothing shows the challenger is better" in unseen.reason
    assert decide_promotion("Z", [], 0.05, ("3", None)).action == "error"


@pytest.mark.parametrize(
    ("current", "challenger", "none", "action", "why"),
    [
        (2.0, 1.0, 10.0, "promote", "promoted"),
        (2.0, 1.95, 10.0, "keep", "not better by the margin"),
        (2.0, 2.5, 10.0, "keep", "not better by the margin"),
        (12.0, 11.0, 10.0, "keep", "no better than no compensation"),
    ],
)
def test_a_challenger_must_beat_the_champion_by_the_margin_and_no_compensation(
    current, challenger, none, action, why
):
    comparisons = [_comparison("K5", current, challenger, none)]
    decision = decide_promotion("Z", comparisons, 0.05, ("1", "2"), ("mlr/all/static",) * 2)
    assert decision.action == action
    assert why in decision.reason
    assert f"{challenger:.2f} um RMS against {current:.2f} um" in decision.reason


def test_a_none_challenger_replaces_a_champion_worse_than_no_compensation():
    worse = [_comparison("K5", 12.0, 10.0, 10.0)]
    labels = ("mlr/all/static", "none/none/static")
    assert decide_promotion("Z", worse, 0.05, ("1", "2"), labels).promoted
    fine = [_comparison("K5", 3.0, 10.0, 10.0)]
    assert not decide_promotion("Z", fine, 0.05, ("1", "2"), labels).promoted
    with pytest.raises(ValueError, match="min_improvement is 1.5"):
        decide_promotion("Z", worse, 1.5, ("1", "2"), labels)


def test_the_report_and_the_record_say_what_was_decided_and_why():
    kept = decide_promotion(
        "Z",
        [_comparison("W04", 1.0, 1.2), _comparison("W05", 2.0, 2.2)],
        0.05,
        ("1", "2"),
        ("ridge/all/static", "mlr/all/static"),
        {"W06": "no sample where both champions predict"},
    )
    promoted = decide_promotion("X", [_comparison("W04", 2.0, 1.0)], 0.05, ("1", "2"))
    text = render_report([kept, promoted])
    assert "| Z | **keep** | v1 | v2 (mlr/all/static) | 2 | 1.50 | 1.70 | 10.00 |" in text
    assert "| X | **promote** | v2 |" in text
    assert "| W05 | 10 | 2.00 | 2.20 | 10.00 |" in text
    assert "- W06 not compared: no sample where both champions predict" in text
    record = kept.to_dict()
    assert record["means_um"] == {"current": 1.5, "challenger": 1.7, "none": 10.0}
    again = GateDecision.from_dict(record)
    assert again.means() == kept.means() and again.unscored == kept.unscored
    empty = GateDecision.from_dict({**record, "campaigns": []})
    assert math.isnan(empty.means()["current"])


@pytest.fixture
def registry(tmp_path):
    """A real MLflow registry (SQLite) with three versions of one model."""
    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}")
    client.create_registered_model("m-Z")
    for number in (1, 2, 3):
        version = client.create_model_version("m-Z", source=str(tmp_path / f"v{number}"))
        client.set_model_version_tag("m-Z", version.version, "trained_on", f"K0{number},K09")
    return client


def test_promotion_moves_champion_and_previous_and_a_kept_version_is_the_challenger(registry):
    apply_decision(registry, "m-Z", decide_promotion("Z", [], 0.05, (None, "1")))
    assert str(version_by_alias(registry, "m-Z", "champion").version) == "1"
    assert version_by_alias(registry, "m-Z", "previous") is None
    kept = decide_promotion("Z", [_comparison("K5", 1.0, 1.0)], 0.05, ("1", "2"))
    apply_decision(registry, "m-Z", kept)
    assert str(version_by_alias(registry, "m-Z", "champion").version) == "1"
    assert str(version_by_alias(registry, "m-Z", "challenger").version) == "2"
    assert registry.get_model_version("m-Z", "2").tags["gate"] == "keep"
    better = decide_promotion("Z", [_comparison("K5", 2.0, 1.0)], 0.05, ("1", "3"))
    apply_decision(registry, "m-Z", better)
    assert str(version_by_alias(registry, "m-Z", "champion").version) == "3"
    assert str(version_by_alias(registry, "m-Z", "previous").version) == "1"
    assert version_by_alias(registry, "m-Z", "challenger") is None
    assert trained_on(registry.get_model_version("m-Z", "3")) == {"K03", "K09"}


def test_rollback_swaps_champion_and_previous_and_needs_a_previous(registry):
    with pytest.raises(LookupError, match="no @previous version"):
        rollback(registry, "m-Z")
    registry.set_registered_model_alias("m-Z", "champion", "3")
    registry.set_registered_model_alias("m-Z", "previous", "1")
    assert rollback(registry, "m-Z") == ("3", "1")
    assert str(version_by_alias(registry, "m-Z", "champion").version) == "1"
    assert str(version_by_alias(registry, "m-Z", "previous").version) == "3"
    assert registry.get_model_version("m-Z", "3").tags["gate"] == "rolled_back"

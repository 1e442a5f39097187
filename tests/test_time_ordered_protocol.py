"""Time-ordered scores: the rolling origin, the hv-block buffer and the choice of ranking score."""

import numpy as np
import pandas as pd
import pytest
from sklearn.linear_model import LinearRegression

from pipeline.errors import ParamsError
from pipeline.protocol.cross_season import Candidate, fit_and_score
from pipeline.protocol.ranking import ranking_scheme
from pipeline.protocol.scoring import candidate_summary, group_scores
from pipeline.protocol.units import campaign_series, training_units
from pipeline.settings.base import parse_section
from pipeline.settings.protocol import ProtocolSettings

HOUR = 3600.0


def _table(campaigns, drift=()):
    """Campaigns ``(id, split, season, run_id, start)``, 4 h every 3 min, error = 2 x T1 rise.

    Campaigns in ``drift`` get 5 um more error per K: a machine that changed.
    """
    frames = []
    for campaign, split, season, run, start in campaigns:
        t = np.arange(80) * 180.0
        rise = 6 * (1 - np.exp(-t / 4000)) + (0.3 if campaign.endswith("1") else 0.0)
        gain = 7.0 if campaign in drift else 2.0
        frames.append(
            pd.DataFrame(
                {
                    "campaign_id": campaign,
                    "split": split,
                    "season": season,
                    "run_id": run,
                    "campaign_start": pd.Timestamp(start),
                    "elapsed_s": t,
                    "rise_T1": rise,
                    "thermal_error_um": gain * rise,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _record(n, split=None):
    """``n`` back-to-back 4-h campaigns of one record (run W01), all training by default."""
    start = pd.Timestamp("2025-04-07T07:00:00")
    return [
        (
            f"W0{i + 1}",
            (split or {}).get(f"W0{i + 1}", "train"),
            "spring",
            "W01",
            start + pd.Timedelta(hours=4 * i),
        )
        for i in range(n)
    ]


def _series(campaigns, **kwargs):
    return campaign_series(_table(campaigns, **kwargs), ["T1"], "temperature_rise")


def _units(series, **settings):
    return {u.name: u for u in training_units(series, ProtocolSettings(**settings))}


def test_rolling_origin_predicts_each_campaign_from_those_that_ended_before_it():
    series = _series(_record(4, {"W04": "validation"}))
    units = _units(series, forward_min_share=0.0)
    forward = {name: u for name, u in units.items() if u.scheme == "forward"}
    assert {n: (u.campaigns, u.tests) for n, u in forward.items()} == {
        "before_W02": (("W01",), ("W02",)),
        "before_W03": (("W01", "W02"), ("W03",)),
    }
    # by default a forecast's fit has at least half of the training campaigns (2 of 3)
    assert [n for n, u in _units(series).items() if u.scheme == "forward"] == ["before_W03"]
    two = _units(_series(_record(4)), forward_min_train=2, forward_min_share=0.0)
    assert [n for n, u in two.items() if u.scheme == "forward"] == ["before_W03", "before_W04"]
    eight = _units(_series([(f"W{i}", *rest[1:]) for i, rest in enumerate(_record(8))]))
    assert [n for n, u in eight.items() if u.scheme == "forward"] == [
        f"before_W{i}" for i in range(4, 8)
    ]


def test_a_campaign_overlapping_the_next_is_not_in_its_forecast_and_unknown_starts_take_no_part():
    campaigns = _record(3)
    campaigns[1] = (*campaigns[1][:4], campaigns[1][4] - pd.Timedelta(hours=1))  # starts early
    units = _units(_series(campaigns))
    assert units["before_W03"].campaigns == ("W01", "W02")
    assert "before_W02" not in units  # W01 had not ended when W02 started
    table = _table(_record(3))
    table["campaign_start"] = pd.NaT
    series = campaign_series(table, ["T1"], "temperature_rise")
    assert not [u for u in training_units(series) if u.scheme == "forward"]


def test_leave_one_out_leaves_the_neighbours_in_the_same_record_out_too():
    units = _units(_series(_record(5)))
    loco = {n: u for n, u in units.items() if u.scheme == "loco"}
    assert loco["not_W03"].campaigns == ("W01", "W05")
    assert "W02" not in loco["not_W03"].tests and "W04" not in loco["not_W03"].tests
    assert loco["not_W01"].campaigns == ("W03", "W04", "W05")
    plain = _units(_series(_record(5)), buffer_campaigns=0)
    assert plain["not_W03"].campaigns == ("W01", "W02", "W04", "W05")
    assert plain["not_W03"].tests == ()  # every campaign scored, as before


def test_a_unit_the_buffer_empties_is_dropped_and_other_runs_are_not_buffered():
    three = _units(_series(_record(3)))
    assert "not_W02" not in three and three["not_W01"].campaigns == ("W03",)
    days = [
        (f"D0{i}", "train", "spring", f"D0{i}", pd.Timestamp(f"2025-04-0{i}T08:00"))
        for i in (1, 2, 3)
    ]
    independent = _units(_series(days))
    assert independent["not_D02"].campaigns == ("D01", "D03")


def test_forward_fits_score_only_their_target_and_never_see_the_future():
    series = _series(_record(4))
    changed = _series(_record(4), drift=("W04",))
    for unit in training_units(series):
        if unit.scheme != "forward":
            continue
        before = fit_and_score(Candidate("mlr", "all"), unit, series, LinearRegression(), ["T1"])
        after = fit_and_score(Candidate("mlr", "all"), unit, changed, LinearRegression(), ["T1"])
        assert list(before.scores["test_campaign"]) == list(unit.tests)
        assert set(before.scores["role"]) == {"prediction"}
        if unit.name != "before_W04":
            pd.testing.assert_frame_equal(before.scores, after.scores)
    scores = pd.concat(
        fit_and_score(Candidate("mlr", "all"), u, changed, LinearRegression(), ["T1"]).scores
        for u in training_units(changed)
    )
    summary = candidate_summary(scores).iloc[0]
    assert summary["forward_Mn_rms_um"] > 1.0  # W04 changed: the forecast of it misses
    names = set(group_scores(scores)["name"])
    assert {"forward_W03_rms_um", "forward_W04_rms_um", "loco_W01_rms_um"} <= names
    assert "forward_W02_rms_um" not in names  # its fit would have 1 of 4 campaigns


def test_ranking_follows_the_data_at_hand():
    record = _series(_record(4))
    choice = ranking_scheme(record, training_units(record))
    assert choice.scheme == "forward" and "continuous record" in choice.reason
    assert choice.others == ("loco",)
    days = [
        (f"D0{i}", "train", "spring", f"D0{i}", pd.Timestamp(f"2025-04-0{i}T08:00"))
        for i in (1, 2, 3, 4)
    ]
    independent = _series(days)
    assert ranking_scheme(independent, training_units(independent)).scheme == "loco"
    seasons = _series([(c, s, "summer" if c > "D02" else "winter", r, t) for c, s, _, r, t in days])
    choice = ranking_scheme(seasons, training_units(seasons))
    assert choice.scheme == "loso" and choice.others == ("forward",)


def test_ranking_by_params_and_its_fallback_say_why():
    record = _series(_record(4))
    units = training_units(record)
    assert ranking_scheme(record, units, "loco").scheme == "loco"
    fallback = ranking_scheme(record, units, "loso")
    assert fallback.scheme == "forward"
    assert "do not allow" in fallback.reason
    short = _series(_record(2))
    assert ranking_scheme(short, training_units(short)).scheme == "forward"
    single = _series(_record(1))
    assert ranking_scheme(single, training_units(single)).scheme is None


@pytest.mark.parametrize(
    "section, message",
    [
        ({"rank_by": "newest"}, r"protocol.rank_by = 'newest'; input should be 'auto', 'loso'"),
        ({"buffer": 1}, r"protocol.buffer: unknown key \(did you mean 'buffer_campaigns'\?\)"),
        ({"buffer_campaigns": -1}, r"protocol.buffer_campaigns = -1; input should be greater"),
        ({"forward_min_train": 1.5}, r"protocol.forward_min_train = 1.5; input should be a valid"),
        ({"forward_min_share": 2}, r"protocol.forward_min_share = 2; input should be less"),
    ],
)
def test_protocol_params_are_checked(section, message):
    with pytest.raises(ParamsError, match=message):
        parse_section(ProtocolSettings, "protocol", section)


def test_protocol_defaults_are_those_of_an_empty_section():
    assert parse_section(ProtocolSettings, "protocol", {"rank_by": "auto"}) == ProtocolSettings()


def test_the_rolling_origin_forecasts_every_campaign_with_a_bounded_number_of_fits():
    series = _series(_record(9))
    every = {
        u.name: (u.campaigns, u.tests)
        for u in _units(series, forward_max_origins=100).values()
        if u.scheme == "forward"
    }
    assert list(every) == [f"before_W0{i}" for i in (6, 7, 8, 9)]  # each fit on at least 5 of 9
    blocks = {
        u.name: (u.campaigns, u.tests)
        for u in _units(series, forward_max_origins=3).values()
        if u.scheme == "forward"
    }
    # four forecasts in three fits: the earliest block the larger, the latest ones refitted
    assert blocks == {
        "before_W06": (every["before_W06"][0], ("W06", "W07")),
        "before_W08": every["before_W08"],
        "before_W09": every["before_W09"],
    }
    ranked = ranking_scheme(series, training_units(series, ProtocolSettings(forward_max_origins=3)))
    assert ranked.scheme == "forward" and "each of 4 campaigns" in ranked.reason


def _independent_days(n, seasons=("spring",)):
    """``n`` one-campaign records on consecutive days, seasons in turn."""
    return [
        (
            f"D{i:02d}",
            "train",
            seasons[i % len(seasons)],
            f"D{i:02d}",
            pd.Timestamp("2025-04-01T08:00") + pd.Timedelta(days=i),
        )
        for i in range(n)
    ]


def test_leave_one_campaign_out_leaves_consecutive_campaigns_out_together_above_max_folds():
    series = _series(_independent_days(12))
    loco = {n: u for n, u in _units(series, max_folds=5).items() if u.scheme == "loco"}
    assert list(loco) == [
        "not_D00_to_D02",
        "not_D03_to_D05",
        "not_D06_to_D07",
        "not_D08_to_D09",
        "not_D10_to_D11",
    ]
    assert loco["not_D03_to_D05"].campaigns == tuple(
        f"D{i:02d}" for i in range(12) if i not in (3, 4, 5)
    )
    every = {s.campaign_id for s in series}
    left_out = [c for u in loco.values() for c in every - set(u.campaigns)]
    assert sorted(left_out) == [f"D{i:02d}" for i in range(12)]  # each left out exactly once
    alone = {n for n, u in _units(series, max_folds=12).items() if u.scheme == "loco"}
    assert alone == {f"not_D{i:02d}" for i in range(12)}


def test_a_block_of_one_record_leaves_the_buffer_out_on_either_side_of_the_whole_block():
    loco = {n: u for n, u in _units(_series(_record(9)), max_folds=3).items() if u.scheme == "loco"}
    assert loco["not_W04_to_W06"].campaigns == ("W01", "W02", "W08", "W09")
    assert set(loco["not_W04_to_W06"].tests) == {"W01", "W02", "W04", "W05", "W06", "W08", "W09"}


def test_leave_one_season_out_merges_consecutive_seasons_above_max_folds():
    seasons = ("s1", "s2", "s3", "s4")
    series = _series(_independent_days(8, seasons))
    loso = {n: u for n, u in _units(series, max_folds=2).items() if u.scheme == "loso"}
    assert list(loso) == ["not_s1_to_s2", "not_s3_to_s4"]
    assert {c for c in loso["not_s1_to_s2"].campaigns} == {"D02", "D03", "D06", "D07"}
    assert len([u for u in _units(series).values() if u.scheme == "loso"]) == 4

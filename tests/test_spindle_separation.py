import json

import numpy as np
import pandas as pd
import pytest

from pipeline.errors import ParamsError
from pipeline.separation.features import SpeedResponses, reference_value, resample, speed_responses
from pipeline.separation.spindle import SeparationSettings, spindle_thermal_error
from pipeline.settings.base import parse_section
from pipeline.settings.separate import SeparateSettings
from schemas import SpindleThermalErrorModel

START = pd.Timestamp("2025-03-03T08:00:00")
ORDER = {"geometric_order": 4}  # the one required key of separate:, read by separate_axis


def _campaign(cid, start=START, axes=("Z",), follows=None, start_state=None):
    return {
        "campaign_id": cid,
        "machine": "m1",
        "start": start,
        "split": "train",
        "season": "spring",
        "synthetic": True,
        "start_state": start_state,
        "follows": follows,
        "sensors_json": json.dumps({"T1": {"role": "other"}}),
        "displacement_json": json.dumps({a: {"probe": "eddy_current"} for a in axes}),
    }


def _samples(cid, temperature, interval_s=180.0, rpm=4000.0, **displacement):
    n = len(temperature)
    frame = pd.DataFrame(
        {
            "campaign_id": cid,
            "source_row": np.arange(1, n + 1),
            "elapsed_s": interval_s * np.arange(n),
            "rpm": rpm,
            "T1": temperature,
        }
    )
    for axis, values in displacement.items():
        frame[f"disp_{axis}"] = values
    return frame


def _separate(campaigns, samples, **settings):
    return spindle_thermal_error(
        pd.DataFrame(campaigns),
        pd.concat(samples, ignore_index=True),
        SeparationSettings(**settings),
    )


def _back_to_back(k01_samples, k02_samples, **settings):
    """Separate K01 and a K02 that starts one interval after K01's fourth sample."""
    k02_start = START + pd.Timedelta(seconds=4 * 180)
    campaigns = [_campaign("K01"), _campaign("K02", start=k02_start)]
    return _separate(campaigns, [k01_samples, k02_samples], **settings)


def test_first_sample_reference():
    table, record = _separate(
        [_campaign("K01")], [_samples("K01", [20.0, 20.5, 21.0, 22.0], Z=[np.nan, 10, 12, 15])]
    )
    np.testing.assert_allclose(table["thermal_error_um"], [np.nan, 0.0, 2.0, 5.0])
    np.testing.assert_allclose(table["rise_T1"], [0.0, 0.5, 1.0, 2.0])
    assert record["campaigns"]["K01"]["reference"] == "first sample of K01 (cold start)"
    assert not table["warm_start"].any()


def test_mean_of_first_n_reference():
    table, _ = _separate(
        [_campaign("K01")],
        [_samples("K01", [20.0, 20.0, 21.0, 23.0], Z=[10, 11, 12, 20])],
        reference="mean_first_n",
        n=3,
    )
    np.testing.assert_allclose(table["thermal_error_um"], [-1.0, 0.0, 1.0, 9.0])
    assert table["rise_T1"].iloc[-1] == pytest.approx(23.0 - 61.0 / 3)


def test_every_declared_axis_gets_its_rows_unless_the_params_list_fewer():
    campaigns = [_campaign("K01", axes=("X", "Z"))]
    samples = [_samples("K01", [20, 21, 22], X=[1.0, 2.0, 4.0], Z=[5.0, 7.0, 9.0])]
    table, record = _separate(campaigns, samples)
    assert record["axes"] == ["X", "Z"]
    np.testing.assert_allclose(table.query("axis == 'X'")["thermal_error_um"], [0, 1, 3])
    np.testing.assert_allclose(table.query("axis == 'Z'")["thermal_error_um"], [0, 2, 4])
    second, record = _separate(
        [_campaign("K01", axes=("Z2", "Z"))],
        [_samples("K01", [20, 21, 22], Z=[5.0, 7.0, 9.0], Z2=[1.0, 1.5, 2.0])],
    )
    assert record["axes"] == ["Z", "Z2"]
    np.testing.assert_allclose(second.query("axis == 'Z2'")["thermal_error_um"], [0, 0.5, 1])
    only_z, _ = _separate(campaigns, samples, axes=("Z",))
    assert set(only_z["axis"]) == {"Z"}
    nothing, record = _separate(campaigns, samples, axes=("Y",))
    assert nothing.empty and record["axes"] == [] and "along the axes ['Y']" in record["note"]
    SpindleThermalErrorModel.validate(nothing)


def test_back_to_back_campaigns_form_a_run_referenced_at_its_cold_start():
    """K02 starts one interval after K01 ends: warm, counted from K01's first sample."""
    table, record = _back_to_back(
        _samples("K01", [20.0, 21.0, 22.0, 23.0], Z=[0.0, 2.0, 4.0, 6.0]),
        _samples("K02", [23.5, 23.0, 22.5], Z=[7.0, 6.0, 5.0]),
    )
    k02 = table[table["campaign_id"] == "K02"]
    np.testing.assert_allclose(k02["thermal_error_um"], [7.0, 6.0, 5.0])
    np.testing.assert_allclose(k02["rise_T1"], [3.5, 3.0, 2.5])
    np.testing.assert_allclose(k02["run_elapsed_s"], [720.0, 900.0, 1080.0])
    assert set(table["run_id"]) == {"K01"} and k02["warm_start"].all()
    assert "continues run K01" in record["campaigns"]["K02"]["reference"]
    link = record["runs"][0]["links"][0]
    assert (link["how"], link["gap_s"], link["contiguous"]) == ("detected", 180.0, True)


def test_a_re_zeroed_probe_is_stitched_across_a_contiguous_cut():
    table, record = _back_to_back(
        _samples("K01", [20.0, 21.0, 22.0, 23.0], Z=[0.0, 2.0, 4.0, 6.0]),
        _samples("K02", [24.0, 25.0, 26.0], Z=[0.0, 2.0, 4.0]),
    )
    np.testing.assert_allclose(
        table.query("campaign_id == 'K02'")["thermal_error_um"], [8.0, 10.0, 12.0]
    )
    stitch = record["runs"][0]["links"][0]["displacement"][0]
    assert stitch["offset_um"] == pytest.approx(8.0) and stitch["jump_um"] == pytest.approx(-8.0)


def test_a_real_jump_at_the_cut_is_kept():
    """The spindle starts at the cut: Z shifts at once (centrifugal), the probe was not zeroed."""
    table, record = _back_to_back(
        _samples("K01", [20.0, 20.0, 20.0, 20.0], Z=[9.0, 9.0, 9.0, 9.0]),
        _samples("K02", [20.1, 20.5, 21.0], Z=[4.0, 3.5, 3.0]),
    )
    np.testing.assert_allclose(
        table.query("campaign_id == 'K02'")["thermal_error_um"], [-5.0, -5.5, -6.0]
    )
    stitch = record["runs"][0]["links"][0]["displacement"][0]
    assert stitch["offset_um"] == 0.0 and stitch["jump_um"] == pytest.approx(-5.0)


def test_no_run_across_a_long_gap_a_temperature_jump_or_a_declared_cold_start():
    late = START + pd.Timedelta(hours=3)
    soon = START + pd.Timedelta(seconds=4 * 180)
    cases = [
        (_campaign("K02", start=late), [23.0, 23.0]),  # 2.4 h gap
        (_campaign("K02", start=soon), [30.0, 30.0]),  # temperatures jump by 7 K
        (_campaign("K02", start=soon, start_state="cold"), [23.0, 23.0]),
    ]
    for campaign, temperature in cases:
        table, record = _separate(
            [_campaign("K01"), campaign],
            [
                _samples("K01", [20, 21, 22, 23], Z=[0, 1, 2, 3]),
                _samples("K02", temperature, Z=[9.0, 10.0]),
            ],
        )
        assert set(table["run_id"]) == {"K01", "K02"}
        np.testing.assert_allclose(table.query("campaign_id == 'K02'")["thermal_error_um"], [0, 1])


def test_declared_follows_links_across_any_gap_and_declared_warm_start_is_said():
    later = START + pd.Timedelta(days=1)
    table, record = _separate(
        [
            _campaign("K01"),
            _campaign("K02", start=later, follows="K01"),
            _campaign("K03", start=later + pd.Timedelta(days=1), start_state="warm"),
        ],
        [
            _samples("K01", [20, 21, 22, 23], Z=[0, 1, 2, 3]),
            _samples("K02", [22.0, 21.5], Z=[2.5, 2.0]),
            _samples("K03", [25.0, 24.0], Z=[4, 3]),
        ],
    )
    assert record["runs"][0]["links"][0]["how"] == "declared"
    np.testing.assert_allclose(table.query("campaign_id == 'K02'")["thermal_error_um"], [2.5, 2])
    assert "declared warm start" in record["campaigns"]["K03"]["reference"]
    assert table.query("campaign_id == 'K03'")["warm_start"].all()


def test_speed_responses_carry_across_the_cut_and_start_from_rest():
    table, _ = _back_to_back(
        _samples("K01", [20, 21, 22, 23], Z=[0, 1, 2, 3], rpm=3000.0),
        _samples("K02", [23, 23, 23], Z=[3, 3, 3], rpm=0.0),
        speed=SpeedResponses((30.0,), (1.0,)),
    )
    response = table["speed_lag_30min"].to_numpy()
    decay = np.exp(-180.0 / 1800.0)
    expected = [0.0]
    for k in range(6):
        expected.append(expected[-1] * decay + (3.0 if k < 4 else 0.0) * (1 - decay))
    np.testing.assert_allclose(response, expected)
    assert response[4] > response[5] > response[6] > 0  # cooling in K02, not zero


def test_fast_sampling_is_averaged_into_windows():
    rows = _samples("K01", np.arange(12.0), interval_s=20.0, Z=np.arange(12.0) * 2)
    out = resample(rows, 60.0)
    np.testing.assert_allclose(out["T1"], [1.0, 4.0, 7.0, 10.0])
    np.testing.assert_allclose(out["elapsed_s"], [20.0, 80.0, 140.0, 200.0])
    assert list(out["source_row"]) == [1, 4, 7, 10]
    assert resample(rows, 10.0) is rows


def test_unknown_reference_and_bad_run_keys_are_clear_errors():
    with pytest.raises(ValueError, match="separate.cold_reference"):
        reference_value(np.array([1.0]), "median", 3)
    with pytest.raises(ParamsError, match=r"separate.cold_reference = 'median'; input should"):
        parse_section(SeparateSettings, "separate", {"cold_reference": "median", **ORDER})
    with pytest.raises(ParamsError, match=r"separate.runs.max_gap: unknown key \(did you mean"):
        parse_section(SeparateSettings, "separate", {"runs": {"max_gap": 10}, **ORDER})


def test_the_separate_section_becomes_the_separation_settings():
    settings = SeparationSettings.from_settings(
        parse_section(
            SeparateSettings,
            "separate",
            {"displacement_axis": "Z", "resample_s": 0, "speed_responses": {}, **ORDER},
        )
    )
    assert settings.axes == ("Z",) and settings.resample_s is None and settings.speed is None
    assert SeparationSettings.from_settings(SeparateSettings(**ORDER)) == SeparationSettings()


def test_inputs_a_run_cannot_reference_at_its_cold_start_are_left_out_or_said():
    """K02 continues K01 but has a new sensor T2, an X probe K01 lacked, and no speed."""
    k02_start = START + pd.Timedelta(seconds=4 * 180)
    k02 = _campaign("K02", start=k02_start, axes=("X", "Z"))
    k02["sensors_json"] = json.dumps({"T1": {"role": "other"}, "T2": {"role": "other"}})
    samples = _samples("K02", [23.0, 23.0, 23.0], rpm=np.nan, Z=[3, 3, 3], X=[5.0, 6.0, 7.0])
    table, record = _separate(
        [_campaign("K01"), k02],
        [_samples("K01", [20, 21, 22, 23], Z=[0, 1, 2, 3]), samples.assign(T2=30.0)],
        speed=SpeedResponses((30.0,), (1.0,)),
    )
    k02_rows = table.query("campaign_id == 'K02'")
    assert k02_rows["rise_T2"].isna().all() and k02_rows["rise_T1"].notna().all()
    assert table["speed_lag_30min"].isna().all()
    x = table.query("axis == 'X'")
    np.testing.assert_allclose(x["thermal_error_um"], [0.0, 1.0, 2.0])
    assert x["reference"].str.contains("first reading of X in K02").all() and x["warm_start"].all()
    notes = " ".join(record["runs"][0]["notes"])
    assert "T2 not read in K01" in notes and "no spindle speed in K02" in notes


def test_a_missing_speed_is_a_standing_spindle_and_a_long_break_stops_it():
    t = np.array([0.0, 60.0, 120.0, 180.0, 10_000.0, 10_060.0])
    speed = SpeedResponses((10.0,), (1.0,))
    held = speed_responses(t, np.array([3000, 3000, np.nan, np.nan, 3000, 3000.0]), speed)
    decay = np.exp(-60.0 / 600.0)
    first = 3 * (1 - decay)  # 3000 rpm for 60 s, then 0 rpm where the speed is missing
    np.testing.assert_allclose(
        held.iloc[:4, 0], [0.0, first, first * (1 + decay), first * (1 + decay) * decay]
    )
    gap = speed_responses(t, np.full(6, 3000.0), speed).iloc[:, 0].to_numpy()
    assert gap[4] < 1e-6 * gap[3]  # stopped across the 2.7-h break, not held at 3000 rpm
    assert np.isnan(speed_responses(t, np.full(6, np.nan), speed).to_numpy()).all()


def test_a_declared_follows_that_overlaps_its_predecessor_is_refused():
    overlapping = _campaign("K02", start=START + pd.Timedelta(seconds=60), follows="K01")
    table, record = _separate(
        [_campaign("K01"), overlapping],
        [_samples("K01", [20, 21, 22, 23], Z=[0, 1, 2, 3]), _samples("K02", [23, 23], Z=[3, 3])],
    )
    assert set(table["run_id"]) == {"K01", "K02"}
    notes = " ".join(n for r in record["runs"] for n in r["notes"])
    assert "starts before it ends" in notes

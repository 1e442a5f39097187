import json

import numpy as np
import pandas as pd
import pytest

from pipeline.spindle_separation import cold_value, spindle_thermal_error


def _inputs(displacement, temperature):
    campaigns = pd.DataFrame({
        "campaign_id": ["K01"], "split": ["train"], "season": ["winter"], "synthetic": [True],
        "sensors_json": [json.dumps({"T1": {"role": "headstock"}})],
    })  # fmt: skip
    samples = pd.DataFrame({
        "campaign_id": "K01", "source_row": np.arange(1, len(displacement) + 1),
        "elapsed_s": 180.0 * np.arange(len(displacement)), "rpm": 4000.0,
        "T1": temperature, "disp_Z": displacement,
    })  # fmt: skip
    return campaigns, samples


def test_first_sample_reference():
    campaigns, samples = _inputs([np.nan, 10.0, 12.0, 15.0], [20.0, 20.5, 21.0, 22.0])
    table = spindle_thermal_error(campaigns, samples, "Z", "first_sample", 3)
    np.testing.assert_allclose(table["thermal_error_um"], [np.nan, 0.0, 2.0, 5.0])
    np.testing.assert_allclose(table["rise_T1"], [0.0, 0.5, 1.0, 2.0])


def test_mean_of_first_n_reference():
    campaigns, samples = _inputs([10.0, 11.0, 12.0, 20.0], [20.0, 20.0, 21.0, 23.0])
    table = spindle_thermal_error(campaigns, samples, "Z", "mean_first_n", 3)
    np.testing.assert_allclose(table["thermal_error_um"], [-1.0, 0.0, 1.0, 9.0])
    assert table["rise_T1"].iloc[-1] == pytest.approx(23.0 - 61.0 / 3)


def test_unknown_reference_and_missing_axis_are_clear_errors():
    with pytest.raises(ValueError, match="separate.cold_reference"):
        cold_value(np.array([1.0]), "median", 3)
    campaigns, samples = _inputs([1.0, 2.0], [20.0, 21.0])
    with pytest.raises(ValueError, match="no valid spindle_drift campaign has a 'X'"):
        spindle_thermal_error(campaigns, samples, "X", "first_sample", 1)

import numpy as np
import pandas as pd
import pytest
from numpy.polynomial import Polynomial

from pipeline.separation.axis import bidirectional_mean, fit_geometric, separate_axis
from pipeline.twin import demo_plans, simulate_axis_campaign


@pytest.fixture(scope="module")
def y01():
    plan = next(p for p in demo_plans() if p.campaign_id == "Y01")
    return simulate_axis_campaign(plan, seed=2016)


def _inputs(campaign):
    laser = campaign.laser.assign(campaign_id="Y01")
    samples = campaign.temperature.assign(campaign_id="Y01")
    sensors = [c for c in campaign.temperature.columns if c != "elapsed_s"]
    campaigns = pd.DataFrame(
        {
            "campaign_id": ["Y01"],
            "split": ["train"],
            "season": ["spring"],
            "axis_name": ["Y"],
            "synthetic": [True],
            "sensors_json": [pd.Series({s: {} for s in sensors}).to_json()],
        }
    )
    return campaigns, samples, laser


def test_bidirectional_mean_removes_the_reversal(y01):
    means = bidirectional_mean(y01.laser.assign(campaign_id="Y01"))
    assert means["reversal_um"].mean() == pytest.approx(y01.truth.reversal_um, abs=0.2)
    cold = means[means["elapsed_min"] == 0]
    truth = y01.truth.geometric_um(cold["target_mm"].to_numpy())
    assert np.abs(cold["measured_um"] - truth).max() < 1.0  # probe noise only


def test_geometric_polynomial_recovered_within_periodic_error_and_noise(y01):
    means = bidirectional_mean(y01.laser.assign(campaign_id="Y01"))
    cold = means[means["elapsed_min"] == 0]
    coefficients = fit_geometric(cold["target_mm"].to_numpy(), cold["measured_um"].to_numpy(), 4)
    x = np.linspace(0, 280, 57)
    gap = Polynomial(coefficients)(x) - y01.truth.polynomial_um(x)
    assert np.abs(gap).max() < y01.truth.periodic_amplitude_um + 0.5
    assert coefficients[1] == pytest.approx(y01.truth.geometric_coeffs_um[1], abs=0.01)


def test_thermal_slopes_recovered_within_noise(y01):
    tables = separate_axis(*_inputs(y01), order=4)
    slopes = tables["slopes"].set_index("elapsed_min")["slope_um_per_mm"]
    truth = y01.truth.passes.set_index("elapsed_min")["slope_um_per_mm"]
    np.testing.assert_allclose(slopes.loc[truth.index], truth, atol=0.003)
    assert slopes.is_monotonic_increasing  # the screw warms up pass after pass
    assert {"T1", "T7"} <= set(tables["slopes"].columns)
    thermal = tables["thermal"]
    assert np.abs(thermal.loc[thermal["elapsed_min"] == 0, "thermal_um"]).max() < 1.5


def test_too_few_targets_for_the_order_is_a_clear_error():
    with pytest.raises(ValueError, match="separate.geometric_order"):
        fit_geometric(np.array([0.0, 10.0, 20.0]), np.array([0.0, 1.0, 2.0]), 4)

"""The calibrated twin takes a campaign's external heat loads (``heat_loads:``) as known input.

A heater on one part of the machine is the test that separates what the spindle's heat ties
together; the twin must put the load's power into the node of its role, exactly.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import build_model, loaded_roles
from pipeline.thermal.loads import HeatLoad
from pipeline.thermal.program import Program, Segment

ROLES = {
    "T1": "spindle_front_bearing",
    "T5": "column_front",
    "T6": "column_rear",
    "T10": "ambient",
}


def _campaign(loads: tuple[HeatLoad, ...], hours: float = 6.0, step_s: float = 120.0):
    t = np.arange(0.0, hours * 3600.0 + 1.0, step_s)
    temps = pd.DataFrame({s: np.full(t.size, 20.0) for s in ROLES})
    return MeasuredCampaign(
        campaign_id="heater",
        t_s=t,
        rpm=np.zeros(t.size),
        temperatures=temps,
        roles=dict(ROLES),
        z_um=np.zeros(t.size),
        program=Program((), key="rpm"),
        heat_loads=loads,
    )


def _load(power_w: float, from_min: float = 0.0, to_min: float | None = None) -> HeatLoad:
    return HeatLoad("column_rear", Program((Segment(from_min, to_min, power_w),), key="power_W"))


def _rise(model, campaign) -> pd.DataFrame:
    sim = model.simulate(model.initial(), campaign)
    return sim.nodes - sim.nodes.iloc[0]


def test_a_constant_load_heats_its_node_to_the_networks_steady_state():
    campaign = _campaign((_load(300.0),), hours=400.0, step_s=3600.0)
    model = build_model(set(ROLES.values()), load_roles=loaded_roles([campaign]))
    assert model.load_nodes == ("column_rear",)
    p = model.values(model.initial())
    network = model.network(p)
    heat = np.zeros(len(model.nodes))
    heat[model.node_index["column_rear"]] = 300.0
    expected = network.steady_state(heat, 20.0) - 20.0
    rise = _rise(model, campaign).iloc[-1].to_numpy()
    np.testing.assert_allclose(rise, expected, rtol=1e-3, atol=1e-6)
    assert rise[model.node_index["column_rear"]] > rise[model.node_index["column_front"]] > 0


def test_the_response_is_linear_in_the_power_and_starts_when_the_load_does():
    model = build_model(set(ROLES.values()), load_roles={"column_rear"})
    one = _rise(model, _campaign((_load(250.0, 60.0, 180.0),)))
    two = _rise(model, _campaign((_load(500.0, 60.0, 180.0),)))
    np.testing.assert_allclose(two.to_numpy(), 2.0 * one.to_numpy(), rtol=1e-9, atol=1e-12)
    t_min = np.arange(0.0, 6 * 60.0 + 1.0, 2.0)
    rear = one["column_rear"].to_numpy()
    assert np.all(np.abs(rear[t_min <= 60.0]) <= 1e-9)  # rounding only before the heater
    assert np.argmax(rear) == np.flatnonzero(t_min == 180.0)[0]  # cools once the heater is off


def test_no_load_gives_the_model_without_load_inputs_bit_for_bit():
    campaign = _campaign(())
    plain = build_model(set(ROLES.values()))
    loaded = build_model(set(ROLES.values()), load_roles={"column_rear"})
    z_plain = plain.simulate(plain.initial(), campaign).z_um
    z_loaded = loaded.simulate(loaded.initial(), campaign).z_um
    assert np.array_equal(z_plain, z_loaded)


def test_a_load_on_an_unsensed_part_gets_its_node_and_an_unknown_part_is_refused():
    model = build_model({"spindle_front_bearing", "ambient"}, load_roles={"bed"})
    assert "bed" in model.nodes and model.load_nodes == ("bed",)
    with pytest.raises(ValueError, match="not structure parts"):
        build_model(set(ROLES.values()), load_roles={"coolant"})
    plain = build_model(set(ROLES.values()))
    with pytest.raises(ValueError, match="heat load on role"):
        plain.simulate(plain.initial(), _campaign((_load(300.0),)))

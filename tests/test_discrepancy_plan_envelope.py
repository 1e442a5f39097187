"""Tests of the safety envelope of a proposed test (discrepancy/plan_envelope.py).

The adiabatic bound of a heater on a part no campaign heated: its energy over the part's
smallest plausible heat capacity (two prior scales below the typical value, not below the
bound), only for the parts not yet heated, and the envelope's floor.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.discrepancy.model import CAPACITY_SPECS
from pipeline.discrepancy.plan_envelope import (
    ENVELOPE_FLOOR_K,
    adiabatic_rise_k,
    first_heating_bound_k,
    rise_limit_k,
    smallest_capacity_j_per_k,
)
from pipeline.thermal.loads import POWER_KEY, HeatLoad
from pipeline.thermal.program import Program, Segment


def _load(role: str, *segments: tuple[float, float | None, float]) -> HeatLoad:
    program = Program(tuple(Segment(a, b, w) for a, b, w in segments), key=POWER_KEY)
    return HeatLoad(role, program, "heater")


def test_the_smallest_capacity_is_two_prior_scales_below_the_typical_value():
    motor = CAPACITY_SPECS["motor"]
    assert smallest_capacity_j_per_k("spindle_motor", 1.0) == pytest.approx(
        motor.initial * np.exp(-2.0)
    )
    # a looser prior reaches further down, but never below the spec's bound
    assert smallest_capacity_j_per_k("spindle_motor", 0.5) == pytest.approx(
        motor.initial * np.exp(-1.0)
    )
    bearing = CAPACITY_SPECS["bearing"]
    assert bearing.initial * np.exp(-2.0) < bearing.lower
    assert smallest_capacity_j_per_k("spindle_front_bearing", 1.0) == bearing.lower
    column = smallest_capacity_j_per_k("column_rear", 1.0)
    assert column == smallest_capacity_j_per_k("column_front", 1.0) > 10 * bearing.lower


def test_the_adiabatic_rise_is_the_energy_over_that_capacity():
    pulse = _load("spindle_motor", (120.0, 135.0, 25.0))
    c_min = smallest_capacity_j_per_k("spindle_motor", 1.0)
    assert adiabatic_rise_k(pulse, 1.0) == pytest.approx(25.0 * 900.0 / c_min)
    two = _load("spindle_motor", (0.0, 15.0, 25.0), (60.0, 90.0, 100.0))
    assert adiabatic_rise_k(two, 1.0) == pytest.approx((25.0 * 900.0 + 100.0 * 1800.0) / c_min)
    with pytest.raises(ValueError, match="no end"):
        adiabatic_rise_k(_load("spindle_motor", (0.0, None, 25.0)), 1.0)


def test_only_a_part_no_campaign_heated_is_held_to_it():
    motor = _load("spindle_motor", (0.0, 15.0, 100.0))
    column = _load("column_rear", (0.0, 120.0, 250.0))
    both = [motor, column]
    expected = max(adiabatic_rise_k(motor, 1.0), adiabatic_rise_k(column, 1.0))
    assert first_heating_bound_k(both, frozenset(), 1.0) == pytest.approx(expected)
    assert first_heating_bound_k(both, frozenset({"column_rear"}), 1.0) == pytest.approx(
        adiabatic_rise_k(motor, 1.0)
    )
    assert first_heating_bound_k(both, frozenset({"column_rear", "spindle_motor"}), 1.0) == 0.0
    assert first_heating_bound_k([], frozenset(), 1.0) == 0.0


def test_the_envelope_has_a_floor():
    assert rise_limit_k([]) == ENVELOPE_FLOOR_K

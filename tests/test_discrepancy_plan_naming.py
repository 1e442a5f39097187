"""Tests of whether the search would name an effect under a proposed test (plan_naming.py).

The response a plan needs against the held-out floor, checked by pooling RMS by hand, and the
rule: Z or the temperatures, the temperatures only for a sensor-only effect.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.discrepancy.plan_naming import HeldOutFloor, needed_signal, would_be_named
from pipeline.discrepancy.visibility import Visibility

FLOOR = HeldOutFloor(z_um=0.6, t_k=0.08, n_z=800, n_t=8000, reduction_z=0.2, reduction_t=0.2)


def _figures(z_um: float, t_k: float) -> Visibility:
    return Visibility(2.0, 2.0, 3.0, 3.0, 3.0, z_um, t_k, z_um, t_k, {})


def test_the_needed_response_takes_the_pooled_rms_down_by_the_search_s_reduction():
    need_z, need_t = needed_signal(FLOOR, 160, 1600)
    # pool by hand: the plan's samples miss by e and v, the others by e; naming removes v
    before = np.sqrt((800 * 0.6**2 + 160 * (0.6**2 + need_z**2)) / 960)
    assert 1.0 - 0.6 / before == pytest.approx(0.2)
    before_t = np.sqrt((8000 * 0.08**2 + 1600 * (0.08**2 + need_t**2)) / 9600)
    assert 1.0 - 0.08 / before_t == pytest.approx(0.2)
    # twice the plan's samples need less, no sample cannot do it
    assert needed_signal(FLOOR, 320, 3200)[0] < need_z
    assert needed_signal(FLOOR, 0, 0) == (float("inf"), float("inf"))


def test_z_or_the_temperatures_name_an_effect_the_temperatures_alone_a_sensor_lag():
    need_z, need_t = needed_signal(FLOOR, 160, 1600)
    z_only = _figures(1.01 * need_z, 0.5 * need_t)
    t_only = _figures(0.5 * need_z, 1.01 * need_t)
    neither = _figures(0.99 * need_z, 0.99 * need_t)
    assert would_be_named("thermal_bending", z_only, FLOOR, 160, 1600)
    assert would_be_named("thermal_bending", t_only, FLOOR, 160, 1600)
    assert not would_be_named("thermal_bending", neither, FLOOR, 160, 1600)
    assert not would_be_named("sensor_lag", z_only, FLOOR, 160, 1600)
    assert would_be_named("sensor_lag", t_only, FLOOR, 160, 1600)

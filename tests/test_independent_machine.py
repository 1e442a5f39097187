"""The independent machine of the hidden-effect trials: its physics, its effects, its contract."""

from __future__ import annotations

import ast
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest

from benchmarks import independent_machine as im
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.workflow import read_raw
from pipeline.settings.base import load_settings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.validate import ValidateSettings

START = datetime(2024, 5, 10, 8, 30)
STEPS = im.stepped_test(((0.0, 2000.0), (120.0, 6000.0)), 270.0, 60.0)
NO_SCATTER = np.ones(3)


def run(effects=(), test=STEPS, seed=1):
    """Grid, node temperatures, air and true Z of one campaign without heat scatter."""
    machine = im.draw_machine(seed)
    return im.simulate(machine, test, frozenset(effects), START, 20.0, NO_SCATTER, seed)


def node(temps, name):
    return temps[:, im.INDEX[name]]


def test_the_module_does_not_import_the_project_twin_or_its_kernel():
    tree = ast.parse(Path(im.__file__).read_text(encoding="utf-8"))
    imported = {
        alias.name for n in ast.walk(tree) if isinstance(n, ast.Import) for alias in n.names
    } | {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert not {m for m in imported if m.startswith(("pipeline.twin", "pipeline.thermal"))}


def test_a_long_constant_run_settles_on_the_network_steady_state():
    machine = im.draw_machine(3)
    test = im.Test(({"from_min": 0, "rpm": 4000.0},), (), 40 * 24 * 3600.0, 3600.0)
    _, temps, _, _ = im.simulate(machine, test, frozenset(), START, 20.0, NO_SCATTER, 3)
    h = im._air_conductance(machine, 4000.0)
    k = np.diag(machine.conductance.sum(axis=1)) - machine.conductance
    q = im._heat(machine, 4000.0, frozenset(), NO_SCATTER)
    steady = np.linalg.solve(k + np.diag(h), h * 20.0 + q)
    np.testing.assert_allclose(temps[-1], steady, atol=0.02)


def test_the_baseline_machine_rises_and_drifts_like_a_spindle_test():
    t_s, temps, _, z = run()
    rise = temps.max(axis=0) - temps[0]
    assert 3.0 < rise[im.INDEX["front_housing"]] < 20.0
    assert rise[im.INDEX["bed"]] < 0.5
    assert -80.0 < z.min() < -8.0  # the tool moves towards the table
    assert abs(z[-1]) < abs(z.min())  # and back while it cools


def test_centrifugal_growth_follows_the_speed_at_once_and_leaves_at_rest():
    t_s, _, _, base = run()
    _, _, _, grown = run(["centrifugal_growth"])
    c = im.draw_machine(1).centrifugal_um_per_krpm2
    shift = grown - base
    at = {m: np.flatnonzero(t_s == 60.0 * m)[0] for m in (110, 260, 330)}
    assert shift[at[110]] == pytest.approx(4.0 * c, rel=1e-3)
    assert shift[at[260]] == pytest.approx(36.0 * c, rel=1e-3)
    assert abs(shift[at[330]]) < 1e-3


def test_motor_heat_warms_the_motor_and_the_headstock():
    _, base, _, z_base = run()
    _, motor, _, z_motor = run(["motor_heat"])
    assert node(motor, "motor")[-40] - node(base, "motor")[-40] > 2.0
    assert (node(motor, "head_upper") >= node(base, "head_upper") - 1e-9).all()
    assert z_motor.min() < z_base.min()


def test_nonlinear_bearing_heat_is_less_below_and_more_above_the_reference_speed():
    machine = im.draw_machine(1)
    for rpm, compare in ((2000.0, np.less), (6000.0, np.greater)):
        nonlinear = im._bearing_power(machine, rpm, True)
        assert compare(nonlinear, im._bearing_power(machine, rpm, False))
    assert im._bearing_power(machine, im.N_REF, True) == pytest.approx(1.0)


def test_sensor_lag_delays_every_structure_reading():
    machine = im.draw_machine(1)
    _, temps, air, _ = run()
    direct = im.read_sensors(machine, temps, air, False, np.random.default_rng(0))
    lagged = im.read_sensors(machine, temps, air, True, np.random.default_rng(0))
    front = [name for name, *_ in im.SENSORS].index("T1")
    mid = np.flatnonzero(np.arange(temps.shape[0]) * im.GRID_S == 130 * 60.0)[0]
    assert lagged[mid, front] < direct[mid, front] - 0.3  # still catching up after the step


def test_bending_needs_a_front_rear_difference_a_front_heater_makes_it():
    heater = ({"role": "column_front", "from_min": 0, "to_min": 240, "power_W": 500.0},)
    test = im.Test(({"from_min": 0, "rpm": 0.0},), heater, 6 * 3600.0, 180.0)
    _, temps, _, straight = run([], test)
    _, _, _, bent = run(["thermal_bending"], test)
    difference = node(temps, "column_front1") - node(temps, "column_rear1")
    assert difference.max() > 1.0
    extra = bent - straight
    assert np.corrcoef(extra, difference)[0, 1] > 0.95
    assert np.abs(extra).max() > 3.0


def test_ambient_variation_moves_the_air_and_its_sensor():
    _, _, air, _ = run(["ambient_variation"])
    _, _, still, _ = run()
    assert np.ptp(still) == 0.0
    assert np.ptp(air) > 0.5


def test_written_campaigns_pass_validation_and_reach_the_workflow(tmp_path):
    im.write_hidden_campaigns(tmp_path / "raw", im.EFFECTS, seed=2, n=1)
    proposed = {
        "name": "column front heater",
        "spindle_program": [
            {"from_min": 0, "to_min": 120, "rpm": 3000},
            {"from_min": 120, "rpm": 0},
        ],
        "heat_loads": [{"role": "column_front", "from_min": 30, "to_min": 150, "power_W": 400}],
        "sample_interval_s": 120,
        "duration_h": 4,
    }
    ids = im.write_plan_campaigns(tmp_path / "raw", proposed, im.EFFECTS, seed=2, n=1)
    gap = load_settings(IngestSettings, "ingest", DEFAULT_PARAMS).max_alignment_gap_s
    limits = load_settings(ValidateSettings, "validate", DEFAULT_PARAMS).limits()
    campaigns, quarantined, synthetic = read_raw(tmp_path / "raw", gap, limits)
    assert not quarantined and synthetic
    by_id = {c.campaign_id: c for c in campaigns}
    assert set(by_id) == {"H01", *ids}
    plan = by_id[ids[0]]
    assert [load.role for load in plan.heat_loads] == ["column_front"]
    assert len(plan.z_um) == 4 * 3600 // 120 + 1

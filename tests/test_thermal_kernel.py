"""Tests of the thermal-network kernel (pipeline.thermal) and of its two parameterisations.

The generator (pipeline.twin, stepping one state with the first-order-hold matrices) and the
calibrated twin (pipeline.discrepancy.model, stepping batches in the network's modes) must give
the same temperatures and Z for the same network, heat, ambient and sensor parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
import pandas as pd
import pytest

from pipeline.discrepancy import MeasuredCampaign, build_model
from pipeline.discrepancy.model import (
    CAPACITY_GROUP,
    CONVECTION_GROUP,
    EFFECT_SPECS,
    EFFECTS,
    REFERENCE_RPM,
    ROLE_NODES,
    TwinModel,
)
from pipeline.thermal import stepping
from pipeline.thermal.discretise import foh_matrices
from pipeline.thermal.effects import BASELINE_TERMS, Term, term_names
from pipeline.thermal.effects import EFFECTS as REGISTRY
from pipeline.thermal.network import ThermalNetwork, build_system
from pipeline.thermal.program import Program, Segment
from pipeline.twin.ambient import AmbientSeries
from pipeline.twin.effects import TERMS
from pipeline.twin.params import SensorSpec
from pipeline.twin.simulate import run_network

T_S = np.arange(0.0, 300 * 60 + 1, 180.0)
# a speed step at 121 min falls between two samples (3-min sampling): on the grid of both
PROGRAM = Program((Segment(0.0, 121.0, 6000.0), Segment(121.0, 240.0, 2500.0)), key="rpm")
# flat for the first 15 min (the calibrated twin's constant ambient is their mean), then a drift
# and a daily-cycle-like wave; the first readings of every sensor are the air at the start
AIR = 20.0 + np.where(
    T_S <= 900.0, 0.0, 0.8 * (T_S - 900.0) / 3600.0 + 1.5 * np.sin((T_S - 900.0) / 9000.0)
)
ROLES = frozenset({*ROLE_NODES, "ambient"})
# no bearing sensor (the bearing heat goes into the shaft), one column half, no motor or screw
SPARSE_ROLES = frozenset({"headstock", "column_front", "bed", "ambient"})
TOL_K = 1e-10  # degC: modal batched stepping vs one-state matrix stepping (~1e-13 seen)
TOL_UM = 1e-9  # um (~1e-12 seen)


# ------------------------------------------------------------ generator vs calibrated twin


@dataclass(frozen=True)
class _GeneratorParams:
    """What the generator's engine needs of a machine: a network, sensors and the parameters."""

    network: ThermalNetwork
    sensors: tuple[SensorSpec, ...]
    p: dict[str, float]
    heat_nodes: dict[str, str]
    bearing_law: str


def _campaign(roles: frozenset[str]) -> MeasuredCampaign:
    """Every sensor reads the air at the start; the ambient sensor reads :data:`AIR`."""
    sensed = [r for r in ROLE_NODES if r in roles]
    temps = {f"T{i}": np.full(T_S.size, AIR[0]) for i in range(len(sensed))}
    roles = {f"T{i}": role for i, role in enumerate(sensed)}
    temps["TA"], roles["TA"] = AIR, "ambient"
    rpm = PROGRAM.value_at(T_S)
    z = np.zeros(T_S.size)
    return MeasuredCampaign("EQ", T_S, rpm, pd.DataFrame(temps), roles, z, program=PROGRAM)


def _theta(model: TwinModel, seed: int) -> np.ndarray:
    lo, hi = model.bounds()
    rng = np.random.default_rng(seed)
    theta = np.clip(model.initial() * rng.uniform(0.5, 2.0, lo.size), lo, hi)
    for name, value in (("bending_um_per_K", 3.0), ("centrifugal_um_per_krpm2", 0.4)):
        if name in model.names:  # their initial value is 0: give them a visible effect
            theta[model.names.index(name)] = value
    if "sensor_lag_s" in model.names:
        theta[model.names.index("sensor_lag_s")] = 600.0
    return theta


def _network(model: TwinModel, p: dict[str, float]) -> ThermalNetwork:
    """The calibrated parameters written as the generator's network (nodes, C, h, G)."""
    return ThermalNetwork(
        model.nodes,
        tuple(p[f"C_{CAPACITY_GROUP[n]}_J_per_K"] for n in model.nodes),
        tuple(p[f"h_{CONVECTION_GROUP[n]}_W_per_K"] for n in model.nodes),
        tuple((a, b, p[f"G_{kind}_W_per_K"]) for a, b, kind in model.links),
    )


def _heat(params: _GeneratorParams, rpm: np.ndarray) -> np.ndarray:
    """Bearing friction (a share into the shaft) and motor loss, W, shape (k, n_nodes)."""
    p, net = params.p, params.network
    r = np.abs(np.asarray(rpm, dtype=float)) / 1000.0
    if params.bearing_law == "nonlinear":
        ref = REFERENCE_RPM / 1000.0
        r_bearing = ref * (r / ref) ** p["bearing_exponent"]
    else:
        r_bearing = r
    q = np.zeros((r.size, len(net.nodes)))
    share = p.get("bearing_heat_to_shaft", 0.0)
    for source, node in params.heat_nodes.items():
        watts = p[f"q_{source}_W_per_krpm"] * r_bearing
        q[:, net.index(node)] += (1.0 - share) * watts
        q[:, net.index("spindle_shaft")] += share * watts
    if "q_motor_W_per_krpm" in p:
        ref = REFERENCE_RPM / 1000.0
        q[:, net.index("motor")] += p["q_motor_W_per_krpm"] * ref * (r / ref) ** p["motor_exponent"]
    return q


def _lag(params: _GeneratorParams) -> float:
    return params.p.get("sensor_lag_s", 0.0)


def _z(params: _GeneratorParams, rise: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Z of the calibrated twin's laws written out, um (rises since the start)."""
    p, nodes = params.p, params.network.nodes
    shaft, head, screw, front, rear = (
        rise[:, nodes.index(node)] if node in nodes else np.zeros(rise.shape[0])
        for node in ("spindle_shaft", "headstock", "ball_screw", "column_front", "column_rear")
    )
    columns = [rise[:, nodes.index(c)] for c in ("column_front", "column_rear") if c in nodes]
    z = (
        -p["alpha_spindle_um_per_K"] * shaft
        - p.get("alpha_headstock_um_per_K", 0.0) * head
        - p.get("alpha_ball_screw_um_per_K", 0.0) * screw
        + p.get("alpha_column_um_per_K", 0.0) * sum(columns) / max(len(columns), 1)
        + p.get("bending_um_per_K", 0.0) * (front - rear)
    )
    r2 = (np.asarray(rpm, dtype=float) / 1000.0) ** 2
    return z + p.get("centrifugal_um_per_krpm2", 0.0) * (r2 - r2[0])


def _generator_run(model: TwinModel, theta: np.ndarray, effects: frozenset[str]) -> tuple:
    p = model.values(theta)
    sensors = tuple(SensorSpec(f"S_{n}", "", "", n, "") for n in model.sensed_nodes)
    law = "nonlinear" if "nonlinear_bearing_heat" in effects else "linear"
    params = _GeneratorParams(_network(model, p), sensors, p, model.heat_nodes, law)
    ambient = "varying_ambient" if "ambient_variation" in effects else "constant_ambient"
    terms = (
        Term("bearing_and_motor_heat", "heat", "as the calibrated twin", _heat),
        TERMS[ambient],
        Term("one_lag", "sensor", "one lag for every sensor (0 = direct)", _lag),
    )
    air = AmbientSeries(tuple(T_S), tuple(AIR))
    run = run_network(params, terms, PROGRAM, air, T_S, preroll_h=0.0)
    return run, _z(params, run.nodes_degc - run.start_degc, run.drive)


@pytest.mark.parametrize(
    ("roles", "effects"),
    [
        (ROLES, frozenset()),
        (ROLES, frozenset({"ambient_variation", "sensor_lag"})),
        (ROLES, frozenset(EFFECTS)),
        (SPARSE_ROLES, frozenset({"ambient_variation", "nonlinear_bearing_heat", "sensor_lag"})),
    ],
    ids=["baseline", "ambient_and_lag", "all_effects", "sparse_roles"],
)
def test_generator_and_calibrated_twin_agree_for_the_same_parameters(roles, effects):
    model = build_model(roles, effects)
    campaign = _campaign(roles)
    theta = _theta(model, seed=len(effects))
    sim = model.simulate(theta, campaign)
    run, z = _generator_run(model, theta, effects)
    assert list(sim.nodes.columns) == list(model.nodes)
    np.testing.assert_allclose(sim.nodes.to_numpy(), run.nodes_degc, rtol=0, atol=TOL_K)
    assert list(sim.temperatures.columns) == [f"T{j}" for j in range(len(model.sensed_nodes))]
    np.testing.assert_allclose(sim.temperatures, run.sensors_degc, rtol=0, atol=TOL_K)
    np.testing.assert_allclose(sim.z_um, z, rtol=0, atol=TOL_UM)
    # a real run: the machine warms by kelvins and drifts by microns, far above the tolerance
    assert np.ptp(run.nodes_degc) > 1.0 and np.ptp(z) > 1.0
    if "sensor_lag" in effects:  # the lag is seen: readings differ from their nodes
        sensed = [model.nodes.index(n) for n in model.sensed_nodes]
        assert np.max(np.abs(run.sensors_degc - run.nodes_degc[:, sensed])) > 0.1


def test_equality_test_would_see_a_one_percent_conductance_change():
    model = build_model(ROLES, frozenset())
    theta = _theta(model, seed=0)
    sim = model.simulate(theta, _campaign(ROLES))
    i = model.names.index("G_bearing_shaft_W_per_K")
    theta[i] *= 1.01
    run, _ = _generator_run(model, theta, frozenset())
    assert np.max(np.abs(sim.nodes.to_numpy() - run.nodes_degc)) > 1e3 * TOL_K


# ---------------------------------------------------------------------- kernel unit tests


def _small_network() -> ThermalNetwork:
    return ThermalNetwork(
        ("a", "b", "c"), (2.0e3, 5.0e3, 4.0e4), (0.5, 1.0, 6.0), (("a", "b", 3.0), ("b", "c", 8.0))
    )


def _small_inputs(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heat 40 W into ``a`` for the first hour then 10 W into ``b``; air rising 1 K/h."""
    amb = 20.0 + grid / 3600.0
    q = np.zeros((grid.size - 1, 3))
    q[grid[:-1] < 3600.0, 0] = 40.0
    q[grid[:-1] >= 3600.0, 1] = 10.0
    return np.column_stack([amb[:-1], q]), np.column_stack([amb[1:], q])


def test_conductance_matrix_is_the_laplacian_plus_convection():
    net = _small_network()
    K = net.conductance_matrix()
    np.testing.assert_array_equal(K, K.T)
    np.testing.assert_allclose(K.sum(axis=1), net.convection)  # Laplacian rows sum to 0
    assert K[0, 1] == -3.0 and K[0, 2] == 0.0 and K[1, 1] == 3.0 + 8.0 + 1.0


def test_state_space_has_one_lag_state_per_sensor_and_custom_heat_inputs():
    net = _small_network()
    system = build_system(net, (2, -1), (300.0, 60.0))
    assert system.A.shape == (5, 5) and system.B.shape == (5, 4)
    np.testing.assert_allclose(system.A[3, [2, 3]], [1.0 / 300.0, -1.0 / 300.0])
    assert system.B[4, 0] == 1.0 / 60.0  # the second lagged sensor reads the air
    np.testing.assert_array_equal(system.B[:3, 1:], np.diag(1.0 / net.capacities))
    share = np.array([[0.7], [0.3], [0.0]]) / net.capacities[:, None]
    custom = build_system(net, heat_input=share)
    np.testing.assert_array_equal(custom.B[:, 1:], share)
    with pytest.raises(ValueError, match="one row per node"):
        build_system(net, heat_input=np.ones((2, 1)))


def test_foh_matches_the_analytic_response_of_one_node():
    # C dT/dt = q - h (T - T_amb): T = T_amb + q / h (1 - exp(-h t / C))
    net = ThermalNetwork(("n",), (1.0e4,), (2.0,), ())
    grid = np.linspace(0.0, 2.0e4, 41)
    u = np.column_stack([np.full(40, 20.0), np.full(40, 50.0)])
    x = stepping.integrate_foh(build_system(net), np.array([20.0]), grid, u, u)
    np.testing.assert_allclose(
        x[:, 0], 20.0 + 25.0 * (1.0 - np.exp(-2.0 * grid / 1.0e4)), atol=1e-10
    )


def _linear_inputs(
    grid: np.ndarray, u_left: np.ndarray, u_right: np.ndarray, t: float, k: int
) -> np.ndarray:
    """Inputs at ``t`` on interval ``k``, linear from ``u_left[k]`` to ``u_right[k]``."""
    w = (t - grid[k]) / (grid[k + 1] - grid[k])
    return (1.0 - w) * u_left[k] + w * u_right[k]


def test_foh_matches_solve_ivp_on_a_small_network_with_a_lagged_sensor():
    system = build_system(_small_network(), (0,), (600.0,))
    grid = stepping.time_grid(np.arange(0.0, 7200.0 + 1, 900.0), np.array([3600.0, 5000.0]))
    u_left, u_right = _small_inputs(grid)
    x0 = np.full(4, 20.0)
    exact = stepping.integrate_foh(system, x0, grid, u_left, u_right)
    inputs = partial(_linear_inputs, grid, u_left, u_right)
    ivp = stepping.integrate_ivp(system, x0, grid, inputs, method="Radau")
    np.testing.assert_allclose(exact, ivp, atol=1e-6)
    assert np.ptp(exact[:, 0]) > 1.0  # the heated node warms by more than a kelvin


def test_time_grid_adds_breakpoints_and_cuts_long_gaps():
    grid = stepping.time_grid(np.array([0.0, 1000.0, 2000.0]), np.array([-5.0, 300.0, 2500.0]))
    np.testing.assert_array_equal(grid, [0.0, 300.0, 1000.0, 2000.0])
    cut = stepping.time_grid(np.array([10.0, 1000.0]), np.zeros(0), start_s=10.0, max_step_s=400.0)
    np.testing.assert_allclose(cut, [10.0, 340.0, 670.0, 1000.0])


def test_batched_foh_matrices_equal_one_system_and_one_step_at_a_time():
    systems = [build_system(_small_network(), (1,), (tau,)) for tau in (120.0, 900.0)]
    A = np.stack([s.A for s in systems])
    B = np.stack([s.B for s in systems])
    hs = np.array([60.0, 900.0, 3600.0])
    batched = foh_matrices(A, B, hs)
    for p in range(2):
        for i, h in enumerate(hs):
            one = foh_matrices(A[p : p + 1], B[p : p + 1], np.array([h]))
            for b, o in zip(batched, one, strict=True):
                np.testing.assert_array_equal(b[p, i], o[0, 0])


def _propagate_inputs(systems: list, grids: list) -> tuple:
    """The arrays :func:`stepping.propagate` takes for P systems and campaigns on ``grids``."""
    A = np.stack([s.A for s in systems])
    B = np.stack([s.B for s in systems])
    hs = np.unique(np.concatenate([np.diff(g) for g in grids]))
    L = max(g.size for g in grids)
    ns, ni = B.shape[1:]
    H = np.zeros((len(grids), L - 1), dtype=int)
    U = np.zeros((len(systems), L - 1, len(grids), ni))
    dU = np.zeros((L - 1, len(grids), ni))
    for c, grid in enumerate(grids):
        u_left, u_right = _small_inputs(grid)
        H[c, : grid.size - 1] = np.searchsorted(hs, np.diff(grid))
        U[:, : grid.size - 1, c] = u_left
        dU[: grid.size - 1, c] = u_right - u_left
    X0 = np.full((len(grids), ns), 20.0)
    return (A, *foh_matrices(A, B, hs), U, dU, X0, H, hs)


@pytest.mark.parametrize("modal", [True, False], ids=["modal", "full_state"])
def test_batched_stepping_equals_stepping_one_by_one(modal, monkeypatch):
    if not modal:
        monkeypatch.setattr(stepping, "MAX_MODAL_CONDITION", 0.0)
    systems = [build_system(_small_network(), (0, 2), (tau, 2 * tau)) for tau in (120.0, 1800.0)]
    grids = [
        stepping.time_grid(np.arange(0.0, 7200.0 + 1, 900.0), np.array([3600.0])),
        stepping.time_grid(np.arange(0.0, 5400.0 + 1, 600.0), np.array([3700.0])),
    ]
    X = stepping.propagate(*_propagate_inputs(systems, grids))
    for p, system in enumerate(systems):
        for c, grid in enumerate(grids):
            one = stepping.integrate_foh(system, np.full(5, 20.0), grid, *_small_inputs(grid))
            np.testing.assert_allclose(X[p, : grid.size, c], one, rtol=0, atol=1e-9)
    assert not np.allclose(X[0, :, 0], X[1, :, 0])  # the two systems differ


# ------------------------------------------------------------------------- effect registry


def test_both_parameterisations_implement_the_one_registry():
    # the generator implements every term the registry names, in the registry's slot
    for effect in REGISTRY.values():
        assert TERMS[effect.term].slot == effect.slot
        if effect.replaces is not None:
            assert TERMS[effect.replaces].slot == effect.slot
    for machine, names in BASELINE_TERMS.items():
        assert all(name in TERMS for name in names), machine
    # the calibrated twin offers exactly the registry's spindle effects, each with a spec row
    assert EFFECTS == tuple(e for e in REGISTRY if "spindle" in REGISTRY[e].machines)
    assert tuple(EFFECT_SPECS) == EFFECTS
    model = build_model(ROLES, frozenset(EFFECTS))
    for spec in model.param_specs:
        assert all(isinstance(v, float) for v in (spec.lower, spec.upper, spec.initial))
        assert spec.lower <= spec.initial <= spec.upper, spec.name


def test_term_names_swap_replaced_terms_and_append_added_ones():
    spindle = term_names("spindle", {"sensor_lag", "motor_heat"})
    assert spindle == (*BASELINE_TERMS["spindle"][:3], "lagged_sensors", "motor_heat")
    axis = term_names("axis", {"motor_heat", "ambient_variation"})  # motor_heat: spindle only
    assert axis == ("axis_friction_heat", "varying_ambient", "direct_sensors")
    with pytest.raises(KeyError, match="unknown machine"):
        term_names("lathe", ())


def test_the_spindle_program_is_right_continuous_and_round_trips_the_contract():
    contract = [{"from_min": 0.0, "to_min": 120.0, "rpm": 6000.0}, {"from_min": 120.0, "rpm": 0.0}]
    program = Program.from_contract(contract)
    assert program.to_contract() == [contract[0], {"from_min": 120.0, "rpm": 0.0}]
    np.testing.assert_array_equal(program.value_at([0.0, 7199.0, 7200.0]), [6000.0, 6000.0, 0.0])
    np.testing.assert_array_equal(program.breakpoints_s(), [0.0, 7200.0])

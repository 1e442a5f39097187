"""The calibratable baseline twin, built from sensor roles alone, and its candidate effects.

The baseline is a lumped thermal network whose nodes are the structure parts the campaign's
sensors sit on (roles ``spindle_front_bearing``, ``spindle_rear_bearing``, ``spindle_motor``,
``headstock``, ``column_front``, ``column_rear``, ``bed``, ``ball_screw``) plus two nodes that
exist even without a sensor: the rotating ``spindle_shaft`` (no sensor can sit on it; its
growth is most of the Z drift) and the ``headstock`` carrying the spindle. It knows nothing of
the machine that produced the data: every physical value is a bounded parameter fitted by
:func:`pipeline.discrepancy.calibrate.calibrate`.

Baseline physics (``C dT/dt = -K T + h T_amb + q``)::

    q_front_bearing = q_fb * rpm / 1000      (into the front-bearing node, else the shaft)
    q_rear_bearing  = q_rb * rpm / 1000      (into the rear-bearing node, else the shaft;
                                              one q_bearing into the shaft without either);
                      a share s (bearing_heat_to_shaft) of it enters the shaft instead
    T_amb           = the ambient sensor's reading at the start (constant; mean of its first
                      15 min, :data:`AMBIENT_START_S`), or the mean first reading of all
                      sensors without an ambient sensor
    z = - alpha_spindle dT_shaft - alpha_headstock dT_headstock - alpha_screw dT_ball_screw
        + alpha_column (dT_column_front + dT_column_rear) / 2          (um; rises since t0)
    reading = first reading + (T_node(t) - T_node(t0))                (direct sensors)

Topology (links exist when both ends exist): bearings - shaft, bearings - headstock (shaft -
headstock when no bearing node), motor - headstock, headstock - column (front, else rear),
column front - rear, columns - bed (headstock - bed without column), ball screw - headstock
and - column. The initial node temperatures are the sensors' first readings (the sensors read
their node directly), so a campaign may start warm or out of balance with the air; an unsensed
node starts at the mean of its neighbours.

Deviation from issue 4's baseline: a sensor with role ``ball_screw`` brings in the Z ball screw
(its growth moves the head towards the table on a semi-closed-loop Z axis). Without it, the
screw's response to the air, which the data show, is left in every residual and masks the
effects being looked for (held-out Z RMS after ``ambient_variation`` 1.0 um against a 0.6 um
floor on trial data).

Parameters are shared within node groups to stay identifiable on ~10 campaigns: one heat
capacity for both bearings and one for both column halves; one convection conductance for the
spindle group (bearings and shaft) and one for both column halves; one conductance per link
kind (both bearings to the shaft, both bearings to the headstock, both columns to the bed).

Candidate effects (:data:`EFFECTS`), each adding bounded parameters (see :func:`effect_specs`):
``ambient_variation`` (the measured ambient drives the convection; no new parameter),
``centrifugal_growth``, ``nonlinear_bearing_heat``, ``sensor_lag``, ``thermal_bending``,
``motor_heat``.

Integration is exact for the piecewise-constant speed and piecewise-linear ambient
(first-order-hold matrix exponential, as :func:`pipeline.twin.network.integrate_foh`), on a
grid of the sample instants and the program's speed steps; the discretisation is computed once
per distinct step length and parameter vector, and the campaigns and parameter vectors are
stepped together in the modes of the network (:func:`_propagate`). The calibration's
finite-difference Jacobian is one such batched run (:meth:`TwinModel.run_batch`).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.linalg import expm
from threadpoolctl import threadpool_limits

from pipeline.discrepancy.data import MeasuredCampaign, speed_at

logger = logging.getLogger(__name__)

EFFECTS = (
    "ambient_variation",
    "centrifugal_growth",
    "nonlinear_bearing_heat",
    "sensor_lag",
    "thermal_bending",
    "motor_heat",
)
"""Candidate effects, exactly these names (issue 4)."""

ROLE_NODES = {
    "spindle_front_bearing": "front_bearing",
    "spindle_rear_bearing": "rear_bearing",
    "spindle_motor": "motor",
    "headstock": "headstock",
    "column_front": "column_front",
    "column_rear": "column_rear",
    "bed": "bed",
    "ball_screw": "ball_screw",
}
"""Sensor role -> network node; other roles (``ambient``, ``other``, ...) are not nodes."""

NODE_ORDER = (
    "front_bearing",
    "rear_bearing",
    "spindle_shaft",
    "motor",
    "headstock",
    "column_front",
    "column_rear",
    "bed",
    "ball_screw",
)

REQUIRED_ROLES = {
    "ambient_variation": ("ambient",),
    "centrifugal_growth": (),
    "nonlinear_bearing_heat": (),
    "sensor_lag": (),
    "thermal_bending": ("column_front", "column_rear"),
    "motor_heat": ("spindle_motor",),
}
"""Roles an effect needs in the campaigns to be testable."""

CAPACITY_GROUP = {
    "front_bearing": "bearing",
    "rear_bearing": "bearing",
    "spindle_shaft": "spindle_shaft",
    "motor": "motor",
    "headstock": "headstock",
    "column_front": "column",
    "column_rear": "column",
    "bed": "bed",
    "ball_screw": "ball_screw",
}
CONVECTION_GROUP = {
    "front_bearing": "spindle",
    "rear_bearing": "spindle",
    "spindle_shaft": "spindle",
    "motor": "motor",
    "headstock": "headstock",
    "column_front": "column",
    "column_rear": "column",
    "bed": "bed",
    "ball_screw": "ball_screw",
}
# generic magnitudes of a mid-size machining centre (mass x specific heat, h A), not fitted
CAPACITY_INITIAL = {
    "bearing": 5e3,
    "spindle_shaft": 5e3,
    "motor": 2e4,
    "headstock": 1e5,
    "column": 3e5,
    "bed": 1e6,
    "ball_screw": 5e3,
}
CONVECTION_INITIAL = {
    "spindle": 1.0,
    "motor": 2.0,
    "headstock": 5.0,
    "column": 10.0,
    "bed": 20.0,
    "ball_screw": 1.0,
}
LINK_INITIAL = {
    "bearing_shaft": 5.0,
    "bearing_headstock": 5.0,
    "shaft_headstock": 5.0,
    "motor_headstock": 2.0,
    "headstock_column": 10.0,
    "column_front_rear": 10.0,
    "column_bed": 10.0,
    "headstock_bed": 10.0,
    "screw_headstock": 2.0,
    "screw_column": 2.0,
}

AMBIENT_START_S = 900.0
"""The constant ambient of the baseline is the mean ambient reading over the first 15 min
(the reading at the start, without the sensor's white noise and quantisation), degC."""

REFERENCE_RPM = 3000.0
"""Speed at which ``nonlinear_bearing_heat`` gives the same heat as the linear law, rpm."""


@dataclass(frozen=True)
class ParamSpec:
    """One bounded parameter of the twin.

    Attributes
    ----------
    name : str
        Readable name with its unit, e.g. ``"C_headstock_J_per_K"``.
    unit : str
        Unit, e.g. ``"J/K"``.
    lower, upper : float
        Bounds (physical plausibility), ``lower < upper``.
    initial : float
        Starting value of the calibration, inside the bounds.
    effect : str or None
        Effect that brings the parameter in, None for the baseline.
    description : str
        What it is, in words.
    """

    name: str
    unit: str
    lower: float
    upper: float
    initial: float
    effect: str | None = None
    description: str = ""

    @property
    def log(self) -> bool:
        """True when the parameter is calibrated in log space (strictly positive bounds)."""
        return self.lower > 0


@dataclass(frozen=True)
class Simulation:
    """Twin output for one campaign at its sample instants.

    Attributes
    ----------
    temperatures : pandas.DataFrame of shape (n, k), degC
        Predicted reading of every sensor whose role is a node of the model.
    z_um : ndarray of shape (n,), um
        Z drift at the spindle nose since the first sample.
    nodes : pandas.DataFrame of shape (n, n_nodes), degC
        Node temperatures (including unsensed nodes).
    """

    temperatures: pd.DataFrame
    z_um: np.ndarray
    nodes: pd.DataFrame


@dataclass
class _Prepared:
    """Per-campaign quantities that do not depend on the parameters."""

    campaign: MeasuredCampaign
    grid: np.ndarray  # (L,) s
    h: np.ndarray  # (L - 1,) step lengths, s
    rpm_steps: np.ndarray  # (L - 1,) speed on each interval
    sample_idx: np.ndarray  # (n,) index of each sample instant in grid
    ambient_grid: np.ndarray  # (L,) measured ambient at the grid (degC) or NaN
    ambient0: float
    first: dict[str, float]  # sensor -> first valid reading
    role_sensors: dict[str, list[str]]  # node -> sensors of the campaign on it
    rpm_samples: np.ndarray  # (n,)
    x0: np.ndarray | None = None  # (ns,) initial state, degC, set on the first run


def missing_roles(effect: str, roles: Iterable[str]) -> list[str]:
    """Roles ``effect`` needs that are absent from ``roles``.

    Parameters
    ----------
    effect : str
        One of :data:`EFFECTS`.
    roles : iterable of str
        Sensor roles present in the campaigns.

    Returns
    -------
    list of str
        Empty when the effect can be tested.
    """
    _check_effect(effect)
    have = set(roles)
    return [r for r in REQUIRED_ROLES[effect] if r not in have]


def _check_effect(effect: str) -> None:
    if effect not in REQUIRED_ROLES:
        raise KeyError(f"unknown effect '{effect}'; candidate effects are {', '.join(EFFECTS)}")


def _spec(name, unit, lower, upper, initial, effect=None, description=""):  # noqa: ANN001, ANN202
    return ParamSpec(name, unit, float(lower), float(upper), float(initial), effect, description)


def effect_specs(effect: str, nodes: Sequence[str]) -> list[ParamSpec]:
    """Parameters an effect adds to a model with ``nodes`` (units and bounds documented here).

    - ``ambient_variation``: none (the measured ambient drives the existing convection);
    - ``centrifugal_growth``: ``centrifugal_um_per_krpm2`` in [-2, 2] um/krpm^2 (z = c
      ((rpm/1000)^2 - (rpm0/1000)^2); +-72 um at 6000 rpm at the bounds);
    - ``nonlinear_bearing_heat``: ``bearing_exponent`` in [0.5, 3] (q ~ rpm^a, equal to
      the linear law at :data:`REFERENCE_RPM`); it starts at 1, the baseline's linear law, so
      the recalibration starts from the current model's optimum (a start inside the typical
      1.3-2 lands in worse local minima);
    - ``sensor_lag``: ``sensor_lag_s`` in [60, 7200] s, one first-order time constant shared by
      every sensor; it starts at 120 s, close to the baseline's direct reading. One per role
      would follow the issue's "each sensor" more closely, but seven free lags give the twin
      extra dynamics that stand in for structure it lacks: on trial data without any lag they
      cut the held-out Z RMS by 39 % and were named (seed 1, centrifugal growth hidden);
    - ``thermal_bending``: ``bending_um_per_K`` in [-50, 50] um/K on the column front-rear
      rise difference;
    - ``motor_heat``: ``q_motor_W_per_krpm`` in [0, 200] W per 1000 rpm into the motor node.
    """
    _check_effect(effect)
    e = effect
    if effect == "ambient_variation":
        return []
    if effect == "centrifugal_growth":
        return [
            _spec(
                "centrifugal_um_per_krpm2",
                "um/krpm^2",
                -2.0,
                2.0,
                0.0,
                e,
                "instantaneous Z shift per (1000 rpm)^2",
            )
        ]
    if effect == "nonlinear_bearing_heat":
        return [
            _spec(
                "bearing_exponent",
                "1",
                0.5,
                3.0,
                1.0,
                e,
                "exponent a of bearing friction heat ~ rpm^a",
            )
        ]
    if effect == "sensor_lag":
        return [
            _spec(
                "sensor_lag_s",
                "s",
                60.0,
                7200.0,
                120.0,
                e,
                "first-order time constant of every temperature sensor",
            )
        ]
    if effect == "thermal_bending":
        if not {"column_front", "column_rear"} <= set(nodes):
            return []
        return [
            _spec(
                "bending_um_per_K",
                "um/K",
                -50.0,
                50.0,
                0.0,
                e,
                "Z per kelvin of column front-minus-rear rise (bending)",
            )
        ]
    if "motor" not in nodes:
        return []
    return [
        _spec(
            "q_motor_W_per_krpm",
            "W/krpm",
            0.0,
            200.0,
            5.0,
            e,
            "spindle-motor loss into the motor node per 1000 rpm",
        )
    ]


@dataclass
class TwinModel:
    """A calibratable twin: the baseline built from roles plus the switched-on effects.

    Attributes
    ----------
    roles : frozenset of str
        Sensor roles the model was built for.
    effects : frozenset of str
    nodes : tuple of str
        Network nodes (sensed and unsensed).
    links : tuple of (str, str, str)
        ``(node_a, node_b, conductance group)``.
    param_specs : list of ParamSpec
        Baseline parameters first, then each effect's in :data:`EFFECTS` order.
    """

    roles: frozenset[str]
    effects: frozenset[str]
    nodes: tuple[str, ...]
    links: tuple[tuple[str, str, str], ...]
    param_specs: list[ParamSpec]
    heat_nodes: dict[str, str]
    _prepared: dict[int, _Prepared] = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ parameters

    @property
    def names(self) -> list[str]:
        """Parameter names in theta order."""
        return [p.name for p in self.param_specs]

    @property
    def sensed_nodes(self) -> tuple[str, ...]:
        """Nodes that carry a sensor role of the model."""
        return tuple(n for n in self.nodes if n in ROLE_NODES.values() and _role(n) in self.roles)

    def initial(self) -> np.ndarray:
        """Return the starting parameter vector, ndarray of shape (n_params,)."""
        return np.array([p.initial for p in self.param_specs])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds, each ndarray of shape (n_params,)."""
        return (
            np.array([p.lower for p in self.param_specs]),
            np.array([p.upper for p in self.param_specs]),
        )

    def check_theta(self, theta: np.ndarray) -> np.ndarray:
        """Return ``theta`` as floats; raise ValueError if its length or bounds are wrong."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (len(self.param_specs),):
            raise ValueError(
                f"theta has shape {theta.shape} but the model has {len(self.param_specs)} "
                f"parameters ({', '.join(self.names)})"
            )
        lo, hi = self.bounds()
        bad = [
            f"{p.name}={v:g} not in [{p.lower:g}, {p.upper:g}] {p.unit}"
            for p, v in zip(self.param_specs, theta, strict=True)
            if not (p.lower <= v <= p.upper)
        ]
        if bad:
            raise ValueError("parameters out of bounds: " + "; ".join(bad))
        return theta

    def values(self, theta: np.ndarray) -> dict[str, float]:
        """Parameter name -> value."""
        return dict(zip(self.names, (float(v) for v in theta), strict=True))

    # ------------------------------------------------------------------ matrices

    def _matrices(self, p: dict[str, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (A, B, lag_nodes): dx/dt = A x + B u, u = [T_amb, f_bearing, f_motor]."""
        n = len(self.nodes)
        idx = {node: i for i, node in enumerate(self.nodes)}
        cap = np.array([p[f"C_{CAPACITY_GROUP[node]}_J_per_K"] for node in self.nodes])
        conv = np.array([p[f"h_{CONVECTION_GROUP[node]}_W_per_K"] for node in self.nodes])
        K = np.diag(conv)
        for a, b, group in self.links:
            g = p[f"G_{group}_W_per_K"]
            i, j = idx[a], idx[b]
            K[i, i] += g
            K[j, j] += g
            K[i, j] -= g
            K[j, i] -= g
        lag_nodes = (
            np.array([idx[s] for s in self.sensed_nodes], dtype=int)
            if "sensor_lag" in self.effects
            else np.zeros(0, dtype=int)
        )
        m = lag_nodes.size
        A = np.zeros((n + m, n + m))
        B = np.zeros((n + m, 3))
        cinv = 1.0 / cap
        A[:n, :n] = -cinv[:, None] * K
        B[:n, 0] = cinv * conv
        share = p.get("bearing_heat_to_shaft", 0.0)
        shaft = idx["spindle_shaft"]
        for source, node in self.heat_nodes.items():
            q = p[f"q_{source}_W_per_krpm"]
            B[idx[node], 1] += cinv[idx[node]] * q * (1.0 - share)
            B[shaft, 1] += cinv[shaft] * q * share
        if "motor" in self.nodes and "q_motor_W_per_krpm" in p:
            B[idx["motor"], 2] = cinv[idx["motor"]] * p["q_motor_W_per_krpm"]
        if m:
            tau = p["sensor_lag_s"]
            A[n + np.arange(m), n + np.arange(m)] = -1.0 / tau
            A[n + np.arange(m), lag_nodes] = 1.0 / tau
        return A, B, lag_nodes

    # ------------------------------------------------------------------ preparation

    def prepare(self, campaign: MeasuredCampaign) -> _Prepared:
        """Precompute (and cache) what does not depend on the parameters for a campaign."""
        key = id(campaign)
        cached = self._prepared.get(key)
        if cached is not None and cached.campaign is campaign:
            return cached
        t = campaign.t_s
        steps = np.array([s for s, _ in campaign.program], dtype=float)
        inner = steps[(steps > t[0]) & (steps < t[-1])]
        grid = np.unique(np.concatenate([t, inner]))
        h = np.round(np.diff(grid), 3)
        if campaign.program:
            rpm_steps = speed_at(campaign.program, grid[:-1])
        else:  # zero-order hold of the sampled speed
            rpm_steps = campaign.rpm[np.searchsorted(t, grid[:-1], side="right") - 1]
        temps = campaign.temperatures
        first = {}
        for s in temps.columns:
            values = temps[s].to_numpy(dtype=float)
            ok = np.flatnonzero(np.isfinite(values))
            if ok.size:
                first[s] = float(values[ok[0]])
        amb = [s for s in campaign.sensors_with_role("ambient") if s in first]
        ambient_grid = np.full(grid.size, np.nan)
        if amb:
            values = temps[amb[0]].to_numpy(dtype=float)
            ok = np.isfinite(values)
            ambient_grid = np.interp(grid, t[ok], values[ok])
            early = ok & (t <= t[ok][0] + AMBIENT_START_S)
            ambient0 = float(values[early].mean())
        else:
            ambient0 = float(np.mean(list(first.values())))
        role_sensors: dict[str, list[str]] = {}
        for s in temps.columns:
            node = ROLE_NODES.get(campaign.roles.get(s, ""))
            if node in self.nodes and s in first:
                role_sensors.setdefault(node, []).append(s)
        prepared = _Prepared(
            campaign=campaign,
            grid=grid,
            h=h,
            rpm_steps=np.abs(rpm_steps),
            sample_idx=np.searchsorted(grid, t),
            ambient_grid=ambient_grid,
            ambient0=ambient0,
            first=first,
            role_sensors=role_sensors,
            rpm_samples=np.abs(campaign.rpm),
        )
        self._prepared[key] = prepared
        return prepared

    # ------------------------------------------------------------------ simulation

    def _bearing_law(self, rpm: np.ndarray, p: dict[str, np.ndarray]) -> np.ndarray:
        r = rpm / 1000.0
        if "nonlinear_bearing_heat" in self.effects:
            ref = REFERENCE_RPM / 1000.0
            return ref * (r / ref) ** p["bearing_exponent"]
        return r

    def _initial_state(self, prep: _Prepared, n_states: int) -> np.ndarray:
        assigned: dict[str, float] = {}
        for node, sensors in prep.role_sensors.items():
            assigned[node] = sum(prep.first[s] for s in sensors) / len(sensors)
        for node in self.nodes:
            if node in assigned:
                continue
            near = [assigned[b if a == node else a] for a, b, _ in self.links
                    if node in (a, b) and (b if a == node else a) in assigned]  # fmt: skip
            assigned[node] = sum(near) / len(near) if near else prep.ambient0
        values = [assigned[node] for node in self.nodes]
        if "sensor_lag" in self.effects:
            values += [assigned[node] for node in self.sensed_nodes]
        return np.array(values[:n_states])

    def run(self, theta: np.ndarray, campaigns: Sequence[MeasuredCampaign]) -> list[dict]:
        """Simulate several campaigns together; raw arrays (used by the calibration).

        Each sensed node starts at its sensors' first reading.

        Returns
        -------
        list of dict
            Per campaign: ``readings`` (n, n_nodes) degC of the state each node's sensors read
            (lagged with ``sensor_lag``), ``nodes`` (n, n_nodes) degC, ``z_um`` (n,) um.
        """
        theta = self.check_theta(theta)
        return [
            {key: value[0] for key, value in raw.items()}
            for raw in self.run_batch(theta[None, :], campaigns)
        ]

    def run_batch(self, thetas: np.ndarray, campaigns: Sequence[MeasuredCampaign]) -> list[dict]:
        """Simulate several campaigns for several parameter vectors in one vectorised pass.

        The calibration's finite-difference Jacobian needs one simulation per parameter; doing
        them together costs a few single simulations (one batched matrix exponential, one time
        loop over the stacked states) instead of one Python time loop each.

        Parameters
        ----------
        thetas : ndarray of shape (P, n_params)
            Parameter vectors, each within the bounds (not checked here).
        campaigns : sequence of MeasuredCampaign

        Returns
        -------
        list of dict
            Per campaign: ``readings`` and ``nodes`` (P, n, n_nodes) degC, ``z_um`` (P, n) um.
        """
        thetas = np.atleast_2d(np.asarray(thetas, dtype=float))
        n_p = thetas.shape[0]
        ps = [self.values(th) for th in thetas]
        p = {name: thetas[:, i, None] for i, name in enumerate(self.names)}  # (P, 1) each
        preps = [self.prepare(c) for c in campaigns]
        mats = [self._matrices(q) for q in ps]
        A = np.stack([m[0] for m in mats])
        B = np.stack([m[1] for m in mats])
        lag_nodes = mats[0][2]
        n = len(self.nodes)
        ns, ni = B.shape[1:]
        hs = np.unique(np.concatenate([pr.h for pr in preps]))
        phi, g0, g1 = _foh_batch(A, B, hs)  # (P, n_h, ns, ns), (P, n_h, ns, ni) x 2
        n_c = len(preps)
        L = max(pr.grid.size for pr in preps)
        H = np.zeros((n_c, L - 1), dtype=int)
        U = np.zeros((n_p, L - 1, n_c, ni))
        dU = np.zeros((L - 1, n_c, ni))
        X0 = np.empty((n_c, ns))
        motor = "q_motor_W_per_krpm" in p
        for c, pr in enumerate(preps):
            k = pr.h.size
            H[c, :k] = np.searchsorted(hs, pr.h)
            amb = (
                pr.ambient_grid
                if "ambient_variation" in self.effects and np.all(np.isfinite(pr.ambient_grid))
                else np.full(pr.grid.size, pr.ambient0)
            )
            U[:, :k, c, 0] = amb[:-1]
            U[:, :k, c, 1] = self._bearing_law(pr.rpm_steps[None, :], p)
            if motor:
                U[:, :k, c, 2] = pr.rpm_steps / 1000.0
            dU[:k, c, 0] = np.diff(amb)
            if pr.x0 is None:
                pr.x0 = self._initial_state(pr, ns)
            X0[c] = pr.x0
        X = _propagate(A, phi, g0, g1, U, dU, X0, H, hs)  # (P, L, n_c, ns)
        out = []
        idx = {node: i for i, node in enumerate(self.nodes)}
        columns = [idx[x] for x in ("column_front", "column_rear") if x in idx]
        for c, pr in enumerate(preps):
            xs = X[:, pr.sample_idx, c]
            nodes = xs[:, :, :n]
            readings = nodes.copy()
            readings[:, :, lag_nodes] = xs[:, :, n : n + lag_nodes.size]
            rise = nodes - X0[c, :n]
            z = -p["alpha_spindle_um_per_K"] * rise[:, :, idx["spindle_shaft"]]
            if "alpha_headstock_um_per_K" in p:
                z = z - p["alpha_headstock_um_per_K"] * rise[:, :, idx["headstock"]]
            if "alpha_ball_screw_um_per_K" in p:
                z = z - p["alpha_ball_screw_um_per_K"] * rise[:, :, idx["ball_screw"]]
            if columns:
                z = z + p["alpha_column_um_per_K"] * rise[:, :, columns].mean(axis=2)
            if "bending_um_per_K" in p:
                z = z + p["bending_um_per_K"] * (
                    rise[:, :, idx["column_front"]] - rise[:, :, idx["column_rear"]]
                )
            if "centrifugal_um_per_krpm2" in p:
                r2 = (pr.rpm_samples / 1000.0) ** 2
                z = z + p["centrifugal_um_per_krpm2"] * (r2 - r2[0])
            out.append({"readings": readings, "nodes": nodes, "z_um": z})
        return out

    def sensor_predictions(self, campaign: MeasuredCampaign, raw: dict) -> pd.DataFrame:
        """Predicted readings per sensor of ``campaign`` from a :meth:`run` result, degC."""
        prep = self.prepare(campaign)
        idx = {node: i for i, node in enumerate(self.nodes)}
        cols = {}
        for node, sensors in prep.role_sensors.items():
            series = raw["readings"][:, idx[node]]
            for s in sensors:
                cols[s] = prep.first[s] + (series - series[0])
        order = [s for s in campaign.temperatures.columns if s in cols]
        return pd.DataFrame({s: cols[s] for s in order}, index=range(campaign.t_s.size))

    def simulate_many(
        self, theta: np.ndarray, campaigns: Sequence[MeasuredCampaign]
    ) -> list[Simulation]:
        """Simulate several campaigns with the same parameters (one discretisation)."""
        with threadpool_limits(limits=1):  # BLAS threads only slow down these small matrices
            raws = self.run(theta, campaigns)
        return [
            Simulation(
                temperatures=self.sensor_predictions(c, r),
                z_um=r["z_um"],
                nodes=pd.DataFrame(r["nodes"], columns=list(self.nodes)),
            )
            for c, r in zip(campaigns, raws, strict=True)
        ]

    def simulate(self, theta: np.ndarray, campaign: MeasuredCampaign) -> Simulation:
        """Simulate one campaign.

        Parameters
        ----------
        theta : ndarray of shape (n_params,)
            Parameter values in :attr:`param_specs` order, within their bounds.
        campaign : MeasuredCampaign

        Returns
        -------
        Simulation
        """
        return self.simulate_many(theta, [campaign])[0]


def _role(node: str) -> str:
    return {v: k for k, v in ROLE_NODES.items()}.get(node, node)


MAX_MODAL_CONDITION = 1e6
"""Largest condition number of the eigenvector matrix for which :func:`_propagate` steps in
modal coordinates; above it (near-coincident time constants) it steps the full state."""


def _propagate(
    A: np.ndarray,
    phi: np.ndarray,
    g0: np.ndarray,
    g1: np.ndarray,
    U: np.ndarray,
    dU: np.ndarray,
    X0: np.ndarray,
    H: np.ndarray,
    hs: np.ndarray,
) -> np.ndarray:
    """Step ``x[k+1] = phi[h_k] x[k] + g0[h_k] u[k] + g1[h_k] du[k]`` for all P and campaigns.

    ``A`` is similar to a symmetric matrix on the nodes (``-C^-1 K``) with the sensor-lag states
    below it, so it has real eigenvalues and, unless a lag equals a node time constant, a
    well-conditioned eigenbasis ``A = V diag(mu) V^-1``. Then ``phi[h] = V diag(exp(mu h))
    V^-1`` and the recurrence decouples into one scalar recurrence per mode, stepped as an
    element-wise product (no small matrix product per step). Where the eigenbasis is
    ill-conditioned or complex, the full state is stepped with ``phi``.

    Parameters
    ----------
    A : ndarray of shape (P, ns, ns), 1/s
    phi : ndarray of shape (P, n_h, ns, ns)
        Transition matrices for the step lengths ``hs``.
    g0, g1 : ndarray of shape (P, n_h, ns, ni)
        Input matrices of the first-order hold for the step lengths ``hs``.
    U : ndarray of shape (P, L - 1, n_c, ni)
        Inputs at the start of each step.
    dU : ndarray of shape (L - 1, n_c, ni)
        Change of the inputs over each step.
    X0 : ndarray of shape (n_c, ns), degC
    H : ndarray of shape (n_c, L - 1), int
        Index in ``hs`` of each step's length.
    hs : ndarray of shape (n_h,), s

    Returns
    -------
    ndarray of shape (P, L, n_c, ns), degC
    """
    n_p, n_steps, n_c, ni = U.shape
    ns = A.shape[1]
    mu, V = np.linalg.eig(A)
    modal = bool(np.all(np.abs(mu.imag) <= 1e-12 * np.abs(mu).max())) and bool(
        np.all(np.linalg.cond(V) < MAX_MODAL_CONDITION)
    )
    V = V.real
    basis_t = np.swapaxes(np.linalg.inv(V), 1, 2) if modal else np.eye(ns)[None]
    # each step's input contribution in the stepping basis
    m0 = np.swapaxes(g0, 2, 3) @ basis_t[:, None]  # (P, n_h, ni, ns)
    m1 = np.swapaxes(g1, 2, 3) @ basis_t[:, None]
    if hs.size == 1:
        w = U.reshape(n_p, -1, ni) @ m0[:, 0] + dU.reshape(-1, ni) @ m1[:, 0]
        w = w.reshape(n_p, n_steps, n_c, ns)
    else:
        w = np.empty((n_p, n_steps, n_c, ns))
        for i in range(hs.size):
            k_idx, c_idx = np.nonzero(H.T == i)
            w[:, k_idx, c_idx] = U[:, k_idx, c_idx] @ m0[:, i] + dU[k_idx, c_idx] @ m1[:, i]
    Y = np.empty((n_p, n_steps + 1, n_c, ns))
    Y[:, 0] = X0 @ basis_t
    if modal:
        decay = np.exp(mu.real[:, None, :] * hs[None, :, None])  # (P, n_h, ns)
        for k in range(n_steps):
            d = decay[:, :1] if hs.size == 1 else decay[:, H[:, k]]
            Y[:, k + 1] = d * Y[:, k] + w[:, k]
        X = (Y.reshape(n_p, -1, ns) @ np.swapaxes(V, 1, 2)).reshape(Y.shape)
        X[:, 0] = X0  # exactly, not through the round trip of the basis change
        return X
    phi_t = np.swapaxes(phi, 2, 3)
    for k in range(n_steps):
        Y[:, k + 1] = np.einsum("pcj,pcji->pci", Y[:, k], phi_t[:, H[:, k]]) + w[:, k]
    return Y


def _foh_batch(
    A: np.ndarray, B: np.ndarray, hs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact discretisation over each step length for inputs linear within the step (FOH).

    Parameters
    ----------
    A : ndarray of shape (P, ns, ns), 1/s
    B : ndarray of shape (P, ns, ni)
    hs : ndarray of shape (n_h,), s

    Returns
    -------
    phi, g0, g1 : ndarray of shape (P, n_h, ns, ns), (P, n_h, ns, ni), (P, n_h, ns, ni)
        ``x[k+1] = phi x[k] + g0 u[k] + g1 (u[k+1] - u[k])``.
    """
    n_p, ns, ni = B.shape
    M = np.zeros((n_p, hs.size, ns + 2 * ni, ns + 2 * ni))
    M[:, :, :ns, :ns] = A[:, None] * hs[None, :, None, None]
    M[:, :, :ns, ns : ns + ni] = B[:, None] * hs[None, :, None, None]
    M[:, :, ns : ns + ni, ns + ni :] = np.eye(ni)
    E = expm(M)
    return E[..., :ns, :ns], E[..., :ns, ns : ns + ni], E[..., :ns, ns + ni :]


def _network(roles: set[str]) -> tuple[tuple[str, ...], tuple[tuple[str, str, str], ...]]:
    sensed = {ROLE_NODES[r] for r in roles if r in ROLE_NODES}
    present = sensed | {"spindle_shaft", "headstock"}
    nodes = tuple(n for n in NODE_ORDER if n in present)
    links: list[tuple[str, str, str]] = []
    bearings = [b for b in ("front_bearing", "rear_bearing") if b in present]
    for b in bearings:
        links.append((b, "spindle_shaft", "bearing_shaft"))
        links.append((b, "headstock", "bearing_headstock"))
    if not bearings:
        links.append(("spindle_shaft", "headstock", "shaft_headstock"))
    if "motor" in present:
        links.append(("motor", "headstock", "motor_headstock"))
    columns = [c for c in ("column_front", "column_rear") if c in present]
    if columns:
        links.append(("headstock", columns[0], "headstock_column"))
    if len(columns) == 2:
        links.append(("column_front", "column_rear", "column_front_rear"))
    if "bed" in present:
        for c in columns:
            links.append((c, "bed", "column_bed"))
        if not columns:
            links.append(("headstock", "bed", "headstock_bed"))
    if "ball_screw" in present:
        links.append(("ball_screw", "headstock", "screw_headstock"))
        if columns:
            links.append(("ball_screw", columns[0], "screw_column"))
    return nodes, tuple(links)


def baseline_specs(
    nodes: Sequence[str], links: Sequence[tuple[str, str, str]], sensed_roles: Sequence[str]
) -> tuple[list[ParamSpec], dict[str, str]]:
    """Baseline parameters (bounds documented in the module and the specs) and heat nodes."""
    specs: list[ParamSpec] = []
    for group in dict.fromkeys(CAPACITY_GROUP[n] for n in nodes):
        upper = 1e7 if group in ("column", "bed") else 1e6
        lower = 1e4 if group in ("column", "bed") else 1e3
        specs.append(
            _spec(
                f"C_{group}_J_per_K",
                "J/K",
                lower,
                upper,
                CAPACITY_INITIAL[group],
                description=f"heat capacity of each {group} node",
            )
        )
    for group in dict.fromkeys(CONVECTION_GROUP[n] for n in nodes):
        specs.append(
            _spec(
                f"h_{group}_W_per_K",
                "W/K",
                0.1,
                200.0,
                CONVECTION_INITIAL[group],
                description=f"convection to the air of each {group} node",
            )
        )
    for group in dict.fromkeys(g for _, _, g in links):
        specs.append(
            _spec(
                f"G_{group}_W_per_K",
                "W/K",
                0.1,
                500.0,
                LINK_INITIAL[group],
                description=f"conductance {group.replace('_', ' - ', 1)}",
            )
        )
    heat_nodes: dict[str, str] = {}
    if "front_bearing" in nodes or "rear_bearing" in nodes:
        for b in ("front_bearing", "rear_bearing"):
            heat_nodes[b] = b if b in nodes else "spindle_shaft"
        specs.append(
            _spec(
                "bearing_heat_to_shaft",
                "1",
                0.0,
                0.9,
                0.3,
                description="share of the bearing friction heat entering the shaft through "
                "the inner rings (the rest heats the bearing housings)",
            )
        )
    else:
        heat_nodes["bearing"] = "spindle_shaft"
    for source, node in heat_nodes.items():
        specs.append(
            _spec(
                f"q_{source}_W_per_krpm",
                "W/krpm",
                0.0,
                200.0,
                5.0,
                description=f"{source} friction heat into {node} per 1000 rpm",
            )
        )
    specs.append(
        _spec(
            "alpha_spindle_um_per_K",
            "um/K",
            0.01,
            30.0,
            3.0,
            description="spindle growth towards the table per K of shaft rise",
        )
    )
    if "headstock" in sensed_roles:
        specs.append(
            _spec(
                "alpha_headstock_um_per_K",
                "um/K",
                0.01,
                30.0,
                3.0,
                description="headstock growth towards the table per K",
            )
        )
    if "ball_screw" in nodes:
        specs.append(
            _spec(
                "alpha_ball_screw_um_per_K",
                "um/K",
                0.01,
                30.0,
                3.0,
                description="Z ball-screw growth moving the head towards the table per K "
                "(semi-closed-loop Z axis)",
            )
        )
    if "column_front" in nodes or "column_rear" in nodes:
        specs.append(
            _spec(
                "alpha_column_um_per_K",
                "um/K",
                0.01,
                30.0,
                5.0,
                description="column growth lifting the head per K (mean rise)",
            )
        )
    return specs, heat_nodes


def build_model(roles: Iterable[str], effects: Iterable[str] = frozenset()) -> TwinModel:
    """Build the calibratable twin for the sensor roles present and the effects switched on.

    Parameters
    ----------
    roles : iterable of str
        Sensor roles of the campaigns (any subset; ``ambient``, ``other`` etc. are not nodes).
    effects : iterable of str
        Names from :data:`EFFECTS`.

    Returns
    -------
    TwinModel

    Raises
    ------
    ValueError
        If no role is a structure node, or an effect needs a role that is absent.
    KeyError
        For an unknown effect name.
    """
    if isinstance(effects, str):
        raise TypeError(f"effects must be a collection of names; write frozenset({{'{effects}'}})")
    roles = frozenset(roles)
    effects = frozenset(effects)
    for e in sorted(effects):
        _check_effect(e)
        lacking = missing_roles(e, roles)
        if lacking:
            raise ValueError(
                f"effect '{e}' needs sensor role(s) {lacking}, absent from the campaigns; "
                "it cannot be tested on these data (leave it out)"
            )
    sensed = [r for r in ROLE_NODES if r in roles]
    if not sensed:
        raise ValueError(
            f"no sensor has a structure role (roles present: {sorted(roles)}); give at least "
            f"one sensor one of {', '.join(ROLE_NODES)} in campaign.yaml"
        )
    nodes, links = _network(set(roles))
    specs, heat_nodes = baseline_specs(nodes, links, sensed)
    for e in EFFECTS:
        if e in effects:
            specs += effect_specs(e, nodes)
    logger.debug(
        "twin model: nodes %s, effects %s, %d parameters", nodes, sorted(effects), len(specs)
    )
    return TwinModel(roles, effects, nodes, links, specs, heat_nodes)

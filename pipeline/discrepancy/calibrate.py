"""Bounded least-squares calibration of a :class:`~pipeline.discrepancy.model.TwinModel`.

Residuals over all campaigns: each temperature sensor's (K) divided by its noise floor, and the
Z drift's (um) divided by the probe's noise floor, both estimated from the data (robust
standard deviation of second differences, which removes slow drifts). The Z residual of each
campaign is taken about its mean (the zero of ``z_um`` is the noisy first reading; the constant
is a nuisance parameter per campaign, counted in ``n_params``). Strictly positive parameters
are fitted in log space; ``scipy.optimize.least_squares`` (``trf``, bounded).

AICc and BIC use the Gaussian likelihood with the residual scale estimated:
``n ln(SSE/n) + 2k + 2k(k+1)/(n-k-1)`` and ``n ln(SSE/n) + k ln n``, SSE of the weighted
residuals, n observations, k parameters.

With ``prior_log_sd`` the fit is the maximum a posteriori point under independent Gaussian
priors centred on the specs' ``initial`` values (:func:`prior_scales`): one residual row per
parameter, ``(x - x_initial) / scale`` in the fitted space. Where the campaigns pin a
combination of parameters down, the data rows decide; where they leave one loose (a node's heat
capacity and its conductances scaled together when nothing heats the node directly), the prior
rows hold it at its typical value instead of wherever the optimiser stopped. The SSE, AICc and
BIC count the data rows only.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.optimize import OptimizeResult, least_squares
from threadpoolctl import threadpool_limits

from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import Simulation, TwinModel
from pipeline.fit_statistics import information_criteria, root_mean_square

logger = logging.getLogger(__name__)

MIN_SIGMA_K = 0.005
"""Lowest temperature noise floor used, K (a perfectly quiet or quantised sensor)."""
MIN_SIGMA_UM = 0.02
"""Lowest displacement noise floor used, um."""


@dataclass(frozen=True)
class NoiseFloor:
    """Noise floors used to weight the residuals.

    Attributes
    ----------
    temperature_K : dict of str to float
        Sensor name -> standard deviation of its reading noise, K.
    z_um : float
        Standard deviation of the probe noise, um.
    """

    temperature_K: dict[str, float]  # noqa: N815 (unit K)
    z_um: float


@dataclass
class Calibration:
    """Result of :func:`calibrate`.

    Attributes
    ----------
    effects : frozenset of str
        Effects of the calibrated model.
    theta : ndarray of shape (n_theta,)
        Calibrated parameters in ``model.param_specs`` order.
    params : dict of str to (float, str)
        Name -> (value, unit).
    residuals : dict of str to dict
        Campaign id -> ``{"z_um": ndarray (n,), "temperatures_K": DataFrame (n, sensors)}``,
        measured minus calibrated twin (Z about its per-campaign mean).
    sse : float
        Sum of squared weighted residuals.
    n_obs : int
        Number of finite observations used.
    n_params : int
        Parameters fitted: ``theta`` plus one Z zero per campaign.
    aicc, bic : float
    rmse_z_um : float
        RMS of the Z residual over all campaigns, um.
    rmse_T_K : float
        RMS of all temperature residuals, K.
    converged : bool
        ``least_squares`` reported success.
    noise : NoiseFloor
    at_bounds : list of str
        Parameters ending within 0.1 % (of the range, in the fitted space) of a bound.
    message : str
    nfev : int
    seconds : float
    """

    effects: frozenset[str]
    theta: np.ndarray
    params: dict[str, tuple[float, str]]
    residuals: dict[str, dict]
    sse: float
    n_obs: int
    n_params: int
    aicc: float
    bic: float
    rmse_z_um: float
    rmse_T_K: float  # noqa: N815 (spec name, unit K)
    converged: bool
    noise: NoiseFloor
    at_bounds: list[str] = field(default_factory=list)
    message: str = ""
    nfev: int = 0
    seconds: float = 0.0


def noise_sd(values: np.ndarray) -> float:
    """Noise standard deviation of a slowly varying signal, in its unit; NaN if too short.

    ``sqrt(mean(d2^2) / 6)`` of the second differences ``d2``, after removing differences
    beyond 4 of those deviations twice (speed steps, quantisation jumps).
    """
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 5:
        return float("nan")
    d2 = np.diff(x, 2)
    kept = d2
    for _ in range(3):
        sd = float(np.sqrt(np.mean(kept**2)))
        if sd == 0.0:
            break
        kept = d2[np.abs(d2) <= 4.0 * sd]
    return float(np.sqrt(np.mean(kept**2) / 6.0)) if kept.size else 0.0


def estimate_noise(campaigns: Sequence[MeasuredCampaign]) -> NoiseFloor:
    """Noise floors from the data: median over campaigns of each sensor's and of Z's."""
    per_sensor: dict[str, list[float]] = {}
    z = []
    for c in campaigns:
        z.append(noise_sd(c.z_um))
        for s in c.temperatures.columns:
            per_sensor.setdefault(s, []).append(noise_sd(c.temperatures[s].to_numpy()))
    temp = {
        s: max(float(np.nanmedian(v)), MIN_SIGMA_K) if np.any(np.isfinite(v)) else MIN_SIGMA_K
        for s, v in per_sensor.items()
    }
    z_sd = float(np.nanmedian(z)) if np.any(np.isfinite(z)) else MIN_SIGMA_UM
    return NoiseFloor(temperature_K=temp, z_um=max(z_sd, MIN_SIGMA_UM))


@dataclass
class _Target:
    campaign: MeasuredCampaign
    sensors: list[str]
    node_index: np.ndarray  # (k,) node each sensor reads
    first: np.ndarray  # (k,)
    measured: np.ndarray  # (n, k)
    mask_t: np.ndarray  # (n, k) finite
    w_t: np.ndarray  # (k,) 1 / sigma * weight
    z: np.ndarray
    mask_z: np.ndarray
    w_z: float


def _targets(
    model: TwinModel, campaigns: Sequence[MeasuredCampaign], noise: NoiseFloor, weights: Mapping
) -> list[_Target]:
    idx = {node: i for i, node in enumerate(model.nodes)}
    out = []
    for c in campaigns:
        prep = model.prepare(c)
        pairs = [(s, node) for node, ss in prep.role_sensors.items() for s in ss]
        sensors = [s for s, _ in pairs]
        measured = c.temperatures[sensors].to_numpy(dtype=float).reshape(c.t_s.size, len(pairs))
        sig = np.array([noise.temperature_K.get(s, MIN_SIGMA_K) for s in sensors])
        out.append(
            _Target(
                campaign=c,
                sensors=sensors,
                node_index=np.array([idx[n] for _, n in pairs], dtype=int),
                first=np.array([prep.first[s] for s in sensors]),
                measured=measured,
                mask_t=np.isfinite(measured),
                w_t=float(weights.get("temperature", 1.0)) / sig,
                z=c.z_um,
                mask_z=np.isfinite(c.z_um),
                w_z=float(weights.get("z", 1.0)) / noise.z_um,
            )
        )
    return out


def _raw_residuals(model: TwinModel, thetas: np.ndarray, targets: list[_Target]) -> list[tuple]:
    """Return per campaign the T residual (P, n, k) and the Z residual about its mean (P, n).

    Residuals are measured minus model, for each of the P parameter vectors ``thetas``
    (P, n_params).
    """
    raws = model.run_batch(thetas, [t.campaign for t in targets])
    out = []
    for t, raw in zip(targets, raws, strict=True):
        read = raw["readings"][:, :, t.node_index]
        pred = t.first + (read - read[:, :1])
        rT = np.where(t.mask_t, t.measured - pred, 0.0)
        rz = np.where(t.mask_z, t.z - raw["z_um"], 0.0)
        if t.mask_z.any():
            rz = np.where(t.mask_z, rz - rz[:, t.mask_z].mean(axis=1, keepdims=True), 0.0)
        out.append((rT, rz))
    return out


def _weighted(model: TwinModel, thetas: np.ndarray, targets: list[_Target]) -> np.ndarray:
    """Weighted residual vectors, ndarray of shape (P, n_residuals)."""
    parts = []
    for t, (rT, rz) in zip(targets, _raw_residuals(model, thetas, targets), strict=True):
        parts.append((rT * t.w_t).reshape(rT.shape[0], -1))
        parts.append(rz * t.w_z)
    return np.concatenate(parts, axis=1)


@dataclass(frozen=True)
class ResidualRows:
    """Where each entry of a weighted residual vector (:func:`weighted_residuals`) comes from.

    Attributes
    ----------
    sigma : ndarray of shape (n_residuals,)
        Noise floor of the entry (its weight is ``1 / sigma``): K for a temperature, um for Z.
    is_z : ndarray of bool, shape (n_residuals,)
        True for a Z entry, False for a temperature reading.
    observed : ndarray of bool, shape (n_residuals,)
        The entry was measured (finite); an unmeasured entry is 0 in every residual vector.
    """

    sigma: np.ndarray
    is_z: np.ndarray
    observed: np.ndarray


def _rows(targets: list[_Target]) -> ResidualRows:
    """Return the :class:`ResidualRows` of :func:`_weighted`'s vectors, in the same order."""
    sigma, is_z, observed = [], [], []
    for t in targets:
        n = t.measured.shape[0]
        sigma += [np.tile(1.0 / t.w_t, n), np.full(n, 1.0 / t.w_z)]
        is_z += [np.zeros(t.mask_t.size, dtype=bool), np.ones(n, dtype=bool)]
        observed += [t.mask_t.ravel(), t.mask_z]
    return ResidualRows(np.concatenate(sigma), np.concatenate(is_z), np.concatenate(observed))


def weighted_residuals(
    model: TwinModel,
    thetas: np.ndarray,
    campaigns: Sequence[MeasuredCampaign],
    noise: NoiseFloor,
) -> tuple[np.ndarray, ResidualRows]:
    """Return the calibration's noise-weighted residuals for several parameter vectors.

    The vectors :func:`calibrate` minimises (unit weights): per campaign, every temperature
    residual (K) over its sensor's noise floor, then the Z residual about its mean (um) over
    the probe's; measured minus twin, 0 where nothing was measured. All parameter vectors are
    simulated in one batched run.

    Parameters
    ----------
    model : TwinModel
    thetas : ndarray of shape (P, n_params)
        Parameter vectors in ``model.param_specs`` order, within the bounds.
    campaigns : sequence of MeasuredCampaign
    noise : NoiseFloor

    Returns
    -------
    residuals : ndarray of shape (P, n_residuals)
        Dimensionless (units of the noise floor).
    rows : ResidualRows
    """
    targets = _targets(model, campaigns, noise, {})
    with threadpool_limits(limits=1):  # BLAS threads only slow down these small matrices
        residuals = _weighted(model, np.atleast_2d(thetas), targets)
    return residuals, _rows(targets)


def _forward_difference_steps(x: np.ndarray, x_hi: np.ndarray) -> np.ndarray:
    """Return the steps of the forward-difference Jacobian, one per parameter.

    As ``least_squares``' own '2-point' scheme: ``sqrt(eps) max(1, |x|)``, taken backwards
    where the forward step would leave the bounds.
    """
    h = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(x))
    h = np.where(x + h > x_hi, -h, h)
    return (x + h) - x


def _to_x(theta: np.ndarray, logs: np.ndarray) -> np.ndarray:
    return np.where(logs, np.log(np.where(logs, theta, 1.0)), theta)


def _to_theta(x: np.ndarray, logs: np.ndarray) -> np.ndarray:
    return np.where(logs, np.exp(np.where(logs, x, 0.0)), x)


@dataclass(frozen=True)
class _Space:
    """The space the optimiser moves in: log of the positive parameters, the others as they are.

    Attributes
    ----------
    logs : ndarray of bool, shape (n_theta,)
        Parameters fitted in log space.
    lo, hi : ndarray of shape (n_theta,)
        Bounds of the parameters, in their units.
    x_lo, x_hi : ndarray of shape (n_theta,)
        The same bounds in the fitted space (log of the unit, or the unit).
    margin : ndarray of shape (n_theta,)
        How far inside the bounds the starts are kept, in the fitted space.
    """

    logs: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    x_lo: np.ndarray
    x_hi: np.ndarray
    margin: np.ndarray

    def theta(self, x: np.ndarray) -> np.ndarray:
        """Return the parameters (their units, clipped into the bounds) of fitted points ``x``."""
        return np.clip(_to_theta(x, self.logs), self.lo, self.hi)

    def inside(self, x: np.ndarray) -> np.ndarray:
        """Return fitted points ``x`` clipped to ``margin`` inside the bounds."""
        return np.clip(x, self.x_lo + self.margin, self.x_hi - self.margin)


def _space(model: TwinModel) -> _Space:
    """Return the fitted space of ``model``'s parameters."""
    logs = np.array([p.log for p in model.param_specs])
    lo, hi = model.bounds()
    x_lo, x_hi = _to_x(lo, logs), _to_x(hi, logs)
    return _Space(logs=logs, lo=lo, hi=hi, x_lo=x_lo, x_hi=x_hi, margin=1e-6 * (x_hi - x_lo))


def _checked_weights(weights: Mapping[str, float] | None) -> dict[str, float]:
    """Return ``weights`` as a dict (empty if None).

    Raises
    ------
    ValueError
        If a key is neither ``temperature`` nor ``z``.
    """
    weights = dict(weights or {})
    unknown = set(weights) - {"temperature", "z"}
    if unknown:
        raise ValueError(f"calibrate: unknown weights {sorted(unknown)}; use 'temperature', 'z'")
    return weights


def _initial_theta(model: TwinModel, start: Mapping[str, float] | None) -> np.ndarray:
    """Return the first start: ``start``'s values by name, the specs' ``initial`` for the rest.

    Raises
    ------
    ValueError
        If ``start`` names a parameter the model does not have.
    """
    if not start:
        return model.initial()
    bad = set(start) - set(model.names)
    if bad:
        raise ValueError(
            f"calibrate: start has unknown parameters {sorted(bad)}; the model's are "
            f"{', '.join(model.names)}"
        )
    return np.array([float(start.get(p.name, p.initial)) for p in model.param_specs])


def prior_scales(model: TwinModel, theta: np.ndarray, prior_log_sd: float) -> np.ndarray:
    """Return the prior scale of each parameter at ``theta``, in the fitted space.

    ``prior_log_sd`` for a positive parameter (fitted in log space: 1 is a factor e); for the
    others ``max(|theta|, range / 20)`` in their unit, the scale the optimiser uses.
    """
    logs = np.array([p.log for p in model.param_specs])
    lo, hi = model.bounds()
    return np.where(logs, prior_log_sd, np.maximum(np.abs(theta), (hi - lo) / 20.0))


@dataclass(frozen=True)
class _Prior:
    """Gaussian prior rows: centre and scale of every parameter in the fitted space."""

    centre: np.ndarray
    scale: np.ndarray


def _prior(model: TwinModel, space: _Space, prior_log_sd: float | None) -> _Prior | None:
    """Return the prior centred on the specs' initial values (None without ``prior_log_sd``)."""
    if prior_log_sd is None:
        return None
    initial = model.initial()
    return _Prior(_to_x(initial, space.logs), prior_scales(model, initial, prior_log_sd))


def _objective(
    model: TwinModel, targets: list[_Target], space: _Space, prior: _Prior | None = None
) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]:
    """Return the weighted residuals of a fitted point ``x`` and their Jacobian, as functions.

    With a ``prior``, one row per parameter follows the data rows.
    """

    def fun(x: np.ndarray) -> np.ndarray:
        r = _weighted(model, space.theta(x)[None, :], targets)[0]
        return r if prior is None else np.concatenate([r, (x - prior.centre) / prior.scale])

    def jac(x: np.ndarray) -> np.ndarray:
        # all perturbed parameter vectors and the base point in one batched simulation
        h = _forward_difference_steps(x, space.x_hi)
        xs = np.vstack([x, x + np.diag(h)])
        r = _weighted(model, space.theta(xs), targets)
        j = ((r[1:] - r[0]) / h[:, None]).T
        return j if prior is None else np.vstack([j, np.diag(1.0 / prior.scale)])

    return fun, jac


def _multistart(
    model: TwinModel,
    targets: list[_Target],
    space: _Space,
    theta0: np.ndarray,
    *,
    n_starts: int,
    seed: int,
    max_nfev: int,
    tol: float,
    prior: _Prior | None = None,
    also_from: np.ndarray | None = None,
) -> OptimizeResult:
    """Run ``least_squares`` from each start; return the result of the lowest cost.

    The first start is ``theta0`` (clipped inside the bounds), then ``also_from`` if given;
    each of the other ``n_starts - 1`` adds normal noise of standard deviation 0.5 (``seed``)
    to the first's log-space coordinates. With a ``prior`` its rows join the residuals.
    """
    fun, jac = _objective(model, targets, space, prior)

    def start_at(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the fitted-space start of ``theta`` and its ``least_squares`` scales."""
        x = space.inside(_to_x(np.clip(theta, space.lo, space.hi), space.logs))
        scale = np.maximum(np.abs(theta), (space.hi - space.lo) / 20.0)
        return x, np.where(space.logs, 1.0, scale)

    x0, x_scale0 = start_at(theta0)
    starts = [(x0, x_scale0)] + ([start_at(also_from)] if also_from is not None else [])
    rng = np.random.default_rng(seed)
    starts += [
        (space.inside(x0 + np.where(space.logs, rng.normal(0.0, 0.5, x0.size), 0.0)), x_scale0)
        for _ in range(max(1, int(n_starts)) - 1)
    ]
    best = None
    for k, (xs, x_scale) in enumerate(starts):
        res = least_squares(
            fun,
            xs,
            jac=jac,
            bounds=(space.x_lo, space.x_hi),
            x_scale=x_scale,
            method="trf",
            max_nfev=max_nfev,
            ftol=tol,
            xtol=tol,
        )
        logger.debug("calibration start %d: cost %.4g, nfev %d", k, res.cost, res.nfev)
        if best is None or res.cost < best.cost:
            best = res
    assert best is not None
    return best


def _residual_tables(targets: list[_Target], raw: list[tuple]) -> dict[str, dict]:
    """Return :attr:`Calibration.residuals`: each campaign's residuals, NaN where unmeasured."""
    return {
        t.campaign.campaign_id: {
            "z_um": np.where(t.mask_z, rz, np.nan),
            "temperatures_K": pd.DataFrame(np.where(t.mask_t, rT, np.nan), columns=t.sensors),
        }
        for t, (rT, rz) in zip(targets, raw, strict=True)
    }


def _at_bounds(model: TwinModel, space: _Space, x: np.ndarray) -> list[str]:
    """Return the parameters within 0.1 % of their range (fitted space) of a bound."""
    span = space.x_hi - space.x_lo
    near = (x - space.x_lo < 1e-3 * span) | (space.x_hi - x < 1e-3 * span)
    return [p.name for p, b in zip(model.param_specs, near, strict=True) if b]


def _calibration(
    model: TwinModel,
    targets: list[_Target],
    space: _Space,
    best: OptimizeResult,
    raw_batch: list[tuple],
    noise: NoiseFloor,
    seconds: float,
) -> Calibration:
    """Assemble the :class:`Calibration` of the best ``least_squares`` result.

    ``raw_batch`` is :func:`_raw_residuals` at ``best.x`` alone; ``seconds`` the time the fit
    took, s.
    """
    raw = [(rT[0], rz[0]) for rT, rz in raw_batch]
    theta = space.theta(best.x)
    n_obs = int(sum(t.mask_t.sum() + t.mask_z.sum() for t in targets))
    n_data = int(sum(t.mask_t.size + t.mask_z.size for t in targets))
    sse = float(np.sum(best.fun[:n_data] ** 2))  # without the prior rows
    k = len(theta) + len(targets)
    _, aicc, bic = (float(c) for c in information_criteria(max(sse, 1e-300), n_obs, k))
    z_all = np.concatenate([rz[t.mask_z] for t, (_, rz) in zip(targets, raw, strict=True)])
    t_all = np.concatenate([rT[t.mask_t] for t, (rT, _) in zip(targets, raw, strict=True)])
    return Calibration(
        effects=model.effects,
        theta=theta,
        params={p.name: (float(v), p.unit) for p, v in zip(model.param_specs, theta, strict=True)},
        residuals=_residual_tables(targets, raw),
        sse=sse,
        n_obs=n_obs,
        n_params=k,
        aicc=aicc,
        bic=bic,
        rmse_z_um=root_mean_square(z_all),
        rmse_T_K=root_mean_square(t_all),
        converged=bool(best.success),
        noise=noise,
        at_bounds=_at_bounds(model, space, best.x),
        message=str(best.message),
        nfev=int(best.nfev),
        seconds=seconds,
    )


def _log_calibration(result: Calibration, n_campaigns: int) -> None:
    """Log the effects, RMS residuals, evaluations, time and parameters at bounds of a fit."""
    logger.info(
        "calibrated twin (%s) on %d campaigns: rmse Z %.3f um, T %.3f K, %d evaluations, %.1f s%s",
        ", ".join(sorted(result.effects)) or "baseline",
        n_campaigns,
        result.rmse_z_um,
        result.rmse_T_K,
        result.nfev,
        result.seconds,
        f"; at bounds: {', '.join(result.at_bounds)}" if result.at_bounds else "",
    )


def calibrate(
    model: TwinModel,
    campaigns: Sequence[MeasuredCampaign],
    weights: Mapping[str, float] | None = None,
    *,
    noise: NoiseFloor | None = None,
    start: Mapping[str, float] | None = None,
    n_starts: int = 1,
    seed: int = 0,
    max_nfev: int = 400,
    tol: float = 1e-6,
    prior_log_sd: float | None = None,
    also_from_initial: bool = False,
) -> Calibration:
    """Fit the model's bounded parameters to the campaigns by least squares.

    Parameters
    ----------
    model : TwinModel
    campaigns : sequence of MeasuredCampaign
        At least one; each needs at least one sensor on a node of the model.
    weights : mapping, optional
        ``{"temperature": w_t, "z": w_z}`` multipliers of the noise-normalised residuals
        (default 1 each).
    noise : NoiseFloor, optional
        Noise floors; default estimated from the data (:func:`estimate_noise`).
    start : mapping of str to float, optional
        Starting values by parameter name (e.g. a previous calibration's), clipped into the
        bounds; the others start at their spec's ``initial``.
    n_starts : int
        Starts: ``start``/initial, the others perturbed ~3x in log space; lowest cost wins.
    seed : int
        Seed of the perturbed starts.
    max_nfev : int
        Limit on function evaluations per start.
    tol : float
        ``ftol`` and ``xtol`` of ``least_squares`` (relative change of the cost / of the
        parameters at which it stops).
    prior_log_sd : float, optional
        Fit the maximum a posteriori point under priors centred on the specs' initial values,
        this scale in the log of a positive parameter (module docstring). Default: plain least
        squares.
    also_from_initial : bool
        With ``start``, start from the specs' initial values too (a warm start alone can carry
        a previous fit's local minimum); the lowest cost wins.

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        No campaign, or a starting value for an unknown parameter.
    """
    if not campaigns:
        raise ValueError("calibrate: give at least one campaign")
    weights = _checked_weights(weights)
    t0 = time.perf_counter()
    noise = noise or estimate_noise(campaigns)
    targets = _targets(model, campaigns, noise, weights)
    space = _space(model)
    theta0 = _initial_theta(model, start)
    with threadpool_limits(limits=1):  # BLAS threads only slow down these small matrices
        best = _multistart(
            model,
            targets,
            space,
            theta0,
            n_starts=n_starts,
            seed=seed,
            max_nfev=max_nfev,
            tol=tol,
            prior=_prior(model, space, prior_log_sd),
            also_from=model.initial() if start and also_from_initial else None,
        )
        raw = _raw_residuals(model, space.theta(best.x)[None, :], targets)
    result = _calibration(model, targets, space, best, raw, noise, time.perf_counter() - t0)
    _log_calibration(result, len(targets))
    return result


def predict(model: TwinModel, calibration: Calibration, campaign: MeasuredCampaign) -> Simulation:
    """Simulate ``campaign`` with the calibrated parameters.

    Raises
    ------
    ValueError
        If the calibration was made with another model (parameter names differ).
    """
    names = list(calibration.params)
    if names != model.names:
        raise ValueError(
            "predict: the calibration's parameters do not match the model's "
            f"({len(names)} vs {len(model.names)}); calibrate this model first"
        )
    return model.simulate(calibration.theta, campaign)

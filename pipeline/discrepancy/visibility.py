"""What the campaigns show of one candidate effect beyond what the calibrated baseline absorbs.

The figures behind :mod:`pipeline.discrepancy.identifiability`, at a baseline twin calibrated on
some campaigns (:class:`BaselinePoint`), for one effect whose sensor roles are present
(:func:`visibility`):

1. **Sensitivities.** Forward differences of the twin give the change of every predicted
   temperature and Z of every campaign per change of each parameter, weighted by the
   calibration's noise floors (:func:`pipeline.discrepancy.calibrate.weighted_residuals`:
   K / sigma_T, um / sigma_Z, the Z of each campaign about its mean): of the baseline twin at
   its calibrated values, and of the twin with the effect at the baseline's values and the
   effect's initial ones (:class:`~pipeline.discrepancy.model.ParamSpec` ``initial``, or where
   the effect vanishes, :data:`LINEARISED_AT`). Each column is scaled, as Brun et al. scale by
   a prior range, by the parameter's prior scale: ``prior_log_sd`` in the log of a positive
   parameter (1: a factor e), the calibration's scale ``max(|theta|, range / 20)`` for the
   others. ``ambient_variation`` has no parameter: its column is the change of the outputs
   when it is switched on.
2. **Collinearity index** of Brun, Reichert and Künsch (2001, *Practical identifiability
   analysis of large environmental simulation models*, Water Resour. Res. 37(4), 1015-1030),
   ``gamma = 1 / sqrt(min eigenvalue of S_n^T S_n)`` with the columns of ``S`` scaled to unit
   length (:mod:`pipeline.discrepancy.collinearity`), of the effect's parameters together with
   an orthonormal basis of the baseline's (the combinations of baseline parameters the data
   move; the baseline's own collinearity, e.g. a node's heat capacity against its cooling,
   would otherwise mark every effect), each column with its prior row appended
   (:func:`~pipeline.discrepancy.collinearity.with_prior`; a baseline parameter the outputs
   barely feel then cannot mimic the effect by an implausibly large move). Brun's index of
   all baseline and effect parameters as they are, without prior, is reported too
   (``collinearity_index_all_parameters``).
3. **Visible signal.** The response of the outputs to the effect at a plausible size (the twin
   with the effect at the ``plausible`` sizes given, by default :data:`PLAUSIBLE`, minus the
   calibrated baseline; ``ambient_variation``: switched on) is fitted by the baseline's
   sensitivities by least squares with the prior rows (a ridge fit: the baseline moves its
   parameters by about their prior scales); what is left is the part of the effect the
   baseline cannot absorb. Its RMS over the measured samples, in units of the noise floor and
   in um (Z) and K (temperatures), is the visible signal; the larger of the Z and temperature
   figures counts (the temperatures alone for ``sensor_lag``, which the search names on its
   temperature evidence only). The motor's loss is sized by the rise it gives its node
   (:data:`RISE_SIZED`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pipeline.discrepancy.calibrate import (
    NoiseFloor,
    ResidualRows,
    estimate_noise,
    prior_scales,
    weighted_residuals,
)
from pipeline.discrepancy.collinearity import (
    collinearity_index,
    effect_collinearity_index,
    orthonormal_basis,
    project_out,
    with_prior,
)
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import TwinModel, build_model, loaded_roles
from pipeline.discrepancy.search import SENSOR_ONLY_EFFECTS, campaign_roles
from pipeline.fit_statistics import root_mean_square

PLAUSIBLE = {
    "centrifugal_um_per_krpm2": -0.15,
    "bearing_exponent": 5.0 / 3.0,
    "sensor_lag_s": 600.0,
    "bending_um_per_K": 5.0,
    "motor_rise_K_per_krpm": 0.5,
    "motor_exponent": 1.0,
}
"""Default plausible size of each effect (``params.yaml`` overrides, with sources): the value of
its parameter, in its unit, or for a heat sized by its rise (:data:`RISE_SIZED`) that rise."""

RISE_SIZED = {
    "q_motor_W_per_krpm": (
        "motor_rise_K_per_krpm",
        "K/krpm",
        ("h_motor_W_per_K", "G_motor_headstock_W_per_K"),
    )
}
"""Heat parameters sized by the steady rise of their node over its surroundings: parameter ->
(size name, its unit, the node's conductances). The heat is ``rise x (h + G)`` at the
baseline's conductances, clipped into its bounds. Without a heat of its own, the twin's motor
node has its cooling and its link to the headstock fitted to a passive reading and known only
together with its heat capacity (on the demo the link sits at its 500 W/K bound, C at its 1e3 J/K
bound): a loss in watts would be a different rise on every calibration, while the rise is what
the motor's sensor reads (the report's own reading of the motor loss, q / (h + G))."""

LINEARISED_AT = {"q_motor_W_per_krpm": 0.0}
"""Effect parameters whose sensitivities are taken where the effect vanishes instead of at the
calibration's initial value: at the initial 5 W/krpm the motor's loss, its node's heat capacity
and its cooling scale together (Brun et al.'s index 7e4 on the demo without prior rows), a
collinearity of the parameters, not of the effect. The other effects start where they vanish
(0, or the exponent 1) except ``sensor_lag`` (120 s; it vanishes at 0 s, outside its
bounds)."""

RELATIVE_STEP = 1e-6
"""Forward-difference step of the sensitivities, relative (``max(1, |x|)``) in the coordinates
of the calibration (log of a positive parameter)."""


@dataclass(frozen=True)
class Visibility:
    """What the campaigns show of one effect beyond what the calibrated baseline absorbs.

    Attributes
    ----------
    collinearity_index : float
        Brun et al.'s index of the effect's parameters with an orthonormal basis of the
        baseline's sensitivities, each column with its prior row, >= 1.
    collinearity_index_all_parameters : float
        Brun et al.'s index of every baseline parameter and the effect's, as they are.
    signal_sigma : float
        The visible signal that counts, RMS in noise sigmas: the larger of the Z and the
        temperature figures (the temperatures alone for a sensor-only effect).
    signal_z_sigma, signal_t_sigma : float
        RMS of the visible part over the measured Z samples and temperature readings, in
        noise sigmas.
    signal_z_um : float
        The same on Z, um.
    signal_t_k : float
        The same on the temperatures, K.
    response_z_um, response_t_k : float
        RMS of the whole response to the effect at the plausible size, before the baseline
        absorbs a part of it, um and K.
    values : dict of str to (float, str)
        The effect's plausible size: name -> (value, unit), its parameters' values and, for a
        heat sized by its rise (:data:`RISE_SIZED`), that rise.
    visible : ndarray
        The visible part itself over the weighted residual rows (Z samples and temperature
        readings, noise sigmas): what :func:`overlap` compares across effects.
    """

    collinearity_index: float
    collinearity_index_all_parameters: float
    signal_sigma: float
    signal_z_sigma: float
    signal_t_sigma: float
    signal_z_um: float
    signal_t_k: float
    response_z_um: float
    response_t_k: float
    values: dict[str, tuple[float, str]]
    visible: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures (4 significant digits; None when not finite)."""
        return {
            "collinearity_index": json_figure(self.collinearity_index),
            "collinearity_index_all_parameters": json_figure(
                self.collinearity_index_all_parameters
            ),
            "signal_sigma": json_figure(self.signal_sigma),
            "signal_Z_sigma": json_figure(self.signal_z_sigma),
            "signal_T_sigma": json_figure(self.signal_t_sigma),
            "signal_Z_um": json_figure(self.signal_z_um),
            "signal_T_K": json_figure(self.signal_t_k),
            "response_Z_um": json_figure(self.response_z_um),
            "response_T_K": json_figure(self.response_t_k),
            "plausible_values": {
                k: {"value": json_figure(v), "unit": u} for k, (v, u) in self.values.items()
            },
        }


def json_figure(x: float) -> float | None:
    """Return ``x`` to 4 significant digits, or None when not finite (JSON has no NaN)."""
    x = float(x)
    return float(f"{x:.4g}") if np.isfinite(x) else None


@dataclass
class BaselinePoint:
    """The calibrated baseline twin the effects are measured against, and its sensitivities.

    Attributes
    ----------
    roles : frozenset of str
        Sensor roles the twins are built for.
    values : dict of str to float
        Calibrated baseline parameters, name -> value (their units).
    campaigns : list of MeasuredCampaign
        The campaigns of the calibration.
    noise : NoiseFloor
        The calibration's noise floors.
    residual : ndarray of shape (n_residuals,)
        The baseline's noise-weighted residuals on the campaigns (measured minus twin).
    sensitivities : ndarray of shape (n_residuals, n_params)
        Change of the weighted outputs per prior scale of each baseline parameter
        (:func:`~pipeline.discrepancy.calibrate.prior_scales`).
    basis : ndarray of shape (n_residuals + n_params, n_params)
        Orthonormal basis of the column space of ``sensitivities`` with one prior row per
        parameter appended (:func:`~pipeline.discrepancy.collinearity.with_prior`): what the
        baseline can absorb by moving its parameters within about their prior scales.
    prior_log_sd : float
        Prior scale of a positive parameter, in its natural log (the effect's too).
    load_roles : frozenset of str
        Roles that take an external heat load in some campaign.
    """

    roles: frozenset[str]
    values: dict[str, float]
    campaigns: list[MeasuredCampaign]
    noise: NoiseFloor
    residual: np.ndarray
    sensitivities: np.ndarray
    basis: np.ndarray
    prior_log_sd: float
    load_roles: frozenset[str] = frozenset()


def baseline_point(
    campaigns: Sequence[MeasuredCampaign],
    values: Mapping[str, float],
    roles: set[str] | None = None,
    noise: NoiseFloor | None = None,
    prior_log_sd: float = 1.0,
    load_roles: frozenset[str] | None = None,
) -> BaselinePoint:
    """Return the calibrated baseline on ``campaigns`` with its residuals and sensitivities.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        The campaigns of the calibration.
    values : mapping of str to float
        Calibrated baseline parameters by name (every parameter of the baseline twin).
    roles : set of str, optional
        Roles of the twin; default the campaigns' roles.
    noise : NoiseFloor, optional
        Default: estimated from the campaigns, as :func:`~pipeline.discrepancy.calibrate
        .calibrate` does.
    prior_log_sd : float
        Prior scale of a positive parameter, in its natural log
        (``params.yaml`` ``discrepancy.identifiability.prior_log_sd``).
    load_roles : frozenset of str, optional
        Roles the twin takes an external heat load on; default those of ``campaigns``
        (:func:`~pipeline.discrepancy.model.loaded_roles`).

    Returns
    -------
    BaselinePoint
    """
    roles = frozenset(roles if roles is not None else campaign_roles(campaigns))
    noise = noise or estimate_noise(campaigns)
    load_roles = frozenset(load_roles if load_roles is not None else loaded_roles(campaigns))
    model = build_model(roles, load_roles=load_roles)
    theta = np.array([float(values[name]) for name in model.names])
    moved = np.ones(theta.size, dtype=bool)
    perturbed, steps = _perturbed(model, theta, moved)
    r, _ = weighted_residuals(model, np.vstack([theta, perturbed]), campaigns, noise)
    sensitivities = _sensitivities(r, steps) * prior_scales(model, theta, prior_log_sd)[moved]
    return BaselinePoint(
        roles=roles,
        values={name: float(values[name]) for name in model.names},
        campaigns=list(campaigns),
        noise=noise,
        residual=r[0],
        sensitivities=sensitivities,
        basis=orthonormal_basis(with_prior(sensitivities)),
        prior_log_sd=prior_log_sd,
        load_roles=load_roles,
    )


def _perturbed(
    model: TwinModel, theta: np.ndarray, moved: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return one forward-difference parameter vector per moved parameter, and the steps.

    Steps are :data:`RELATIVE_STEP` in the calibration's coordinates (log of a positive
    parameter), taken backwards where the forward one would leave the upper bound.

    Parameters
    ----------
    model : TwinModel
    theta : ndarray of shape (n_params,)
    moved : ndarray of bool, shape (n_params,)
        The parameters to move.

    Returns
    -------
    thetas : ndarray of shape (n_moved, n_params)
        ``theta`` with one moved parameter changed per row, in order.
    steps : ndarray of shape (n_moved,)
        The steps in the calibration's coordinates.
    """
    logs = np.array([p.log for p in model.param_specs])
    _, hi = model.bounds()
    x = np.where(logs, np.log(np.where(logs, theta, 1.0)), theta)
    x_hi = np.where(logs, np.log(np.where(logs, hi, 1.0)), hi)
    h = RELATIVE_STEP * np.maximum(1.0, np.abs(x))
    h = np.where(x + h > x_hi, -h, h)
    xs = (x + np.diag(h))[moved]
    return np.where(logs, np.exp(np.where(logs, xs, 0.0)), xs), h[moved]


def _sensitivities(residuals: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Return the output sensitivities from the residuals at a point and its perturbations.

    ``residuals`` (1 + k, n) holds the weighted residuals (measured minus twin) at the point,
    then at each of the ``k`` perturbed points; the twin's outputs rise as the residuals fall.
    Returns an ndarray of shape (n, k).
    """
    return ((residuals[0] - residuals[1:]) / steps[:, None]).T


def _signals(
    effect: str, visible: np.ndarray, response: np.ndarray, rows: ResidualRows
) -> dict[str, float]:
    """Return the RMS figures of the visible part and of the whole response (sigma, um, K)."""
    z = rows.is_z & rows.observed
    t = ~rows.is_z & rows.observed
    z_sigma, t_sigma = root_mean_square(visible[z]), root_mean_square(visible[t])
    counted = [t_sigma] if effect in SENSOR_ONLY_EFFECTS else [z_sigma, t_sigma]
    finite = [v for v in counted if np.isfinite(v)]
    return {
        "signal_sigma": max(finite) if finite else float("nan"),
        "signal_z_sigma": z_sigma,
        "signal_t_sigma": t_sigma,
        "signal_z_um": root_mean_square((visible * rows.sigma)[z]),
        "signal_t_k": root_mean_square((visible * rows.sigma)[t]),
        "response_z_um": root_mean_square((response * rows.sigma)[z]),
        "response_t_k": root_mean_square((response * rows.sigma)[t]),
    }


def _effect_values(model: TwinModel, point: BaselinePoint, own: Mapping[str, float]) -> np.ndarray:
    """Return the twin's parameter vector: the baseline's values, ``own`` for the effect's.

    An effect parameter missing from ``own`` takes its spec's initial value.
    """
    return np.array(
        [point.values.get(p.name, own.get(p.name, p.initial)) for p in model.param_specs]
    )


def _plausible_size(
    model: TwinModel, point: BaselinePoint, plausible: Mapping[str, float]
) -> tuple[np.ndarray, dict[str, tuple[float, str]]]:
    """Return the parameter vector of the effect at its plausible size, and the size shown.

    A heat of :data:`RISE_SIZED` is its rise times the node's conductances at the baseline,
    clipped into its bounds; every other effect parameter takes its plausible value.

    Raises
    ------
    ValueError
        If a plausible value lies outside its parameter's bounds.
    """
    values, shown = {}, {}
    for p in model.param_specs:
        if p.effect is None:
            continue
        if p.name in RISE_SIZED:
            size, unit, conductances = RISE_SIZED[p.name]
            rise = plausible[size]
            heat = rise * sum(point.values[g] for g in conductances)
            values[p.name] = float(np.clip(heat, p.lower, p.upper))
            shown[size] = (rise, unit)
        else:
            values[p.name] = plausible[p.name]
        shown[p.name] = (values[p.name], p.unit)
    return model.check_theta(_effect_values(model, point, values)), shown


def visibility(effect: str, point: BaselinePoint, plausible: Mapping[str, float]) -> Visibility:
    """Measure what the campaigns show of ``effect`` at the calibrated baseline.

    One batched run of the twin with the effect, at the baseline's values and the effect's
    :data:`LINEARISED_AT` (or initial) values, each effect parameter moved in turn (its
    sensitivities), and at its plausible size (the response). See the module docstring.

    Raises
    ------
    ValueError
        If a plausible value lies outside its parameter's bounds, or the effect needs a role
        the twin lacks.
    """
    model = build_model(point.roles, frozenset({effect}), point.load_roles)
    own = np.array([p.effect is not None for p in model.param_specs])
    theta0 = _effect_values(model, point, LINEARISED_AT)
    sized, shown = _plausible_size(model, point, plausible)
    perturbed, steps = _perturbed(model, theta0, own)
    r, rows = weighted_residuals(
        model, np.vstack([theta0, perturbed, sized]), point.campaigns, point.noise
    )
    response = point.residual - r[-1]
    if own.any():
        scales = prior_scales(model, theta0, point.prior_log_sd)[own]
        effect_cols = _sensitivities(r[:-1], steps) * scales
    else:  # a switch without a parameter: its column is what switching it on changes
        effect_cols = (point.residual - r[0])[:, None]
    n_base = point.sensitivities.shape[1]
    visible = project_out(np.concatenate([response, np.zeros(n_base)]), point.basis)
    # the effect's own prior rows come after the baseline's, where the baseline has zeros
    padded = np.vstack([point.basis, np.zeros((effect_cols.shape[1], point.basis.shape[1]))])
    effect_rows = np.vstack([effect_cols, np.zeros((n_base, effect_cols.shape[1]))])
    return Visibility(
        collinearity_index=effect_collinearity_index(padded, with_prior(effect_rows)),
        collinearity_index_all_parameters=collinearity_index(
            np.hstack([point.sensitivities, effect_cols])
        ),
        **_signals(effect, visible[: response.size], response, rows),
        values=shown,
        visible=visible[: response.size],
    )


def overlap(first: Visibility, second: Visibility) -> float:
    """Return how far two effects' visible parts point the same way: ``|cos|`` of their angle.

    Both are what the calibrated baseline cannot absorb of each effect at its plausible size,
    on the same weighted residual rows. Near 1, the data cannot tell one effect from the other
    (either, once named, would fit what the other leaves); near 0, each has a signature of its
    own. NaN when either has no visible part.
    """
    a, b = first.visible, second.visible
    norm = float(np.linalg.norm(a) * np.linalg.norm(b))
    if a.size == 0 or a.size != b.size or norm == 0.0 or not np.isfinite(norm):
        return float("nan")
    return abs(float(a @ b)) / norm

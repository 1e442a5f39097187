"""The twin a test plan is scored with: the baseline refitted with its priors, and its spread.

The search's calibration is a plain least-squares fit: where the campaigns leave a combination
of parameters loose, it ends wherever the optimiser stopped. The motor node is the case that
matters. The spindle-only campaigns heat it only through its neighbours, so its heat capacity
and its two conductances are known only as a time constant and a ratio; their common scale is
free. On one trial machine the fit put the capacity at 1.5e3 J/K, with conductances of
0.6 W/K, and the twin expected a 25 W heater to warm the motor by 22 K in 2 h where the
machine warmed by 3 K, so safe plans were left out. (The other way, a node tied to a large
neighbour that the data do pin down, as on the demo, no refit corrects;
:mod:`~pipeline.discrepancy.plan_envelope` bounds that case.) So a plan is scored with
(:func:`plan_twin`):

1. **The maximum a posteriori point.** The baseline refitted from the search's values with
   Gaussian priors centred on the specs' typical values (``calibrate(..., prior_log_sd=)``,
   the prior scale of the identifiability settings). The data rows keep what the campaigns
   pin down, within a small change of the fit's SSE; the prior rows bring the loose
   combinations back to typical values (the motor above: 7e3 J/K, 2.6 W/K, 2.6 W/K; the SSE
   rose by 0.4 %).
2. **Its spread.** The Laplace approximation of the posterior at that point (Gelman et al.,
   *Bayesian Data Analysis*, 3rd ed., 2013, section 4.1): covariance
   ``(S^T S / s^2 + I)^-1`` in prior-scale units, with ``S`` the noise-weighted
   sensitivities per prior scale (:func:`~pipeline.discrepancy.visibility.baseline_point`)
   and ``s^2`` the fit's SSE per degree of freedom (at least 1), which widens the spread as
   much as the twin misses the data by more than the noise (the usual scaling of a
   least-squares covariance). :data:`N_DRAWS` parameter vectors are drawn from it (seeded,
   clipped into the bounds). The test plans take the :data:`RISE_QUANTILE` quantile of their
   peak rise over the draws as the rise they are held to (:func:`peak_rises`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from pipeline.discrepancy.calibrate import calibrate, prior_scales
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import TwinModel, build_model
from pipeline.discrepancy.visibility import BaselinePoint, baseline_point

N_DRAWS = 32
"""Parameter vectors drawn from the posterior."""

RISE_QUANTILE = 0.9
"""Quantile of a plan's peak rise over the draws that the safety envelope holds it to."""

DRAW_SEED = 0
"""Seed of the draws: the same campaigns give the same proposal."""


@dataclass(frozen=True)
class PlanTwin:
    """The twin a test plan is scored with.

    Attributes
    ----------
    values : dict of str to float
        The maximum a posteriori baseline parameters, name -> value (their units).
    draws : ndarray of shape (N_DRAWS, n_params)
        Parameter vectors drawn from the posterior, in the order of ``names``.
    names : list of str
        The baseline twin's parameter names.
    sse_ratio : float
        The refit's SSE over the search calibration's (data rows only), >= about 1.
    """

    values: dict[str, float]
    draws: np.ndarray
    names: list[str]
    sse_ratio: float

    def moved(self, calibrated: Mapping[str, float], factor: float = 2.0) -> dict[str, tuple]:
        """Return the parameters the refit moved by more than ``factor`` (either way).

        Returns
        -------
        dict of str to (float, float)
            Name -> (calibrated value, planning value).
        """
        out = {}
        for name, value in self.values.items():
            before = float(calibrated[name])
            if before > 0 and value > 0 and max(value / before, before / value) > factor:
                out[name] = (before, value)
        return out


def plan_twin(point: BaselinePoint, n_draws: int = N_DRAWS, seed: int = DRAW_SEED) -> PlanTwin:
    """Refit the baseline of ``point`` with its priors and draw from the posterior.

    Parameters
    ----------
    point : BaselinePoint
        The search's calibrated baseline on its campaigns.
    n_draws : int
    seed : int

    Returns
    -------
    PlanTwin
    """
    model = build_model(point.roles, load_roles=point.load_roles)
    fit = calibrate(
        model,
        point.campaigns,
        noise=point.noise,
        start=point.values,
        prior_log_sd=point.prior_log_sd,
    )
    values = {name: value for name, (value, _) in fit.params.items()}
    at_map = baseline_point(
        point.campaigns, values, set(point.roles), point.noise, point.prior_log_sd, point.load_roles
    )
    s2 = max(1.0, fit.sse / max(1, fit.n_obs - fit.n_params))
    sens = at_map.sensitivities
    cov = np.linalg.inv(sens.T @ sens / s2 + np.eye(sens.shape[1]))
    draws = _draws(model, fit.theta, cov, point.prior_log_sd, n_draws, seed)
    before = float(np.sum(point.residual**2))
    return PlanTwin(values, draws, list(model.names), fit.sse / max(before, 1e-300))


def _draws(
    model: TwinModel,
    theta: np.ndarray,
    cov: np.ndarray,
    prior_log_sd: float,
    n_draws: int,
    seed: int,
) -> np.ndarray:
    """Return ``n_draws`` parameter vectors ``theta + scale * u``, ``u ~ N(0, cov)``, clipped.

    ``u`` is in prior-scale units of the fitted space (log of a positive parameter).
    """
    logs = np.array([p.log for p in model.param_specs])
    lo, hi = model.bounds()
    scales = prior_scales(model, theta, prior_log_sd)
    chol = np.linalg.cholesky((cov + cov.T) / 2.0)
    u = np.random.default_rng(seed).standard_normal((n_draws, theta.size)) @ chol.T
    x = np.where(logs, np.log(np.where(logs, theta, 1.0)), theta) + scales * u
    return np.clip(np.where(logs, np.exp(np.where(logs, x, 0.0)), x), lo, hi)


def peak_rises(model: TwinModel, thetas: np.ndarray, campaign: MeasuredCampaign) -> np.ndarray:
    """Largest rise over its first value of any sensed structure node, per parameter vector, K.

    Parameters
    ----------
    model : TwinModel
        Built for the campaign's roles and loads.
    thetas : ndarray of shape (P, n_params)
    campaign : MeasuredCampaign
        A plan's campaign (:func:`~pipeline.discrepancy.plan_proposal.simulate_plan`).

    Returns
    -------
    ndarray of shape (P,)
    """
    cols = [i for i, node in enumerate(model.nodes) if node in model.sensed_nodes]
    with threadpool_limits(limits=1):  # BLAS threads only slow down these small matrices
        readings = model.run_batch(thetas, [campaign])[0]["readings"][:, :, cols]
    return (readings - readings[:, :1, :]).max(axis=(1, 2))

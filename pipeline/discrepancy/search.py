"""Forward selection of the physical effects the twin is missing.

Start from the baseline twin (no effect). At each step, for every candidate effect not yet in
the model whose sensor roles are present: add it, recalibrate (from the current model's
calibrated values and from the parameters' initial values, keeping the lower cost), and measure
its evidence

* ``delta_bic`` (and ``delta_aicc``): change of the information criterion of the calibration
  on all campaigns against the current model (negative = better);
* ``rmse_heldout_um`` / ``rmse_heldout_T_K``: displacement RMS (um) and temperature RMS (K) on
  campaigns *not used for calibration*, pooled over cross-validation folds across campaigns
  (leave-one-campaign-out up to ``n_folds`` campaigns, else ``n_folds`` folds dealt
  round-robin), and their relative reductions ``heldout_reduction`` (Z) and
  ``heldout_T_reduction`` against the current model.

An effect *passes* when ``delta_bic <= max_delta_bic`` and the held-out Z RMS falls by at least
``min_heldout_reduction`` or the held-out temperature RMS by at least
``min_heldout_temperature_reduction``. An effect of the sensors alone (``sensor_lag``,
:data:`SENSOR_ONLY_EFFECTS`) qualifies only through the temperatures: it cannot change the real
displacement, so when it improves the held-out Z but not the readings, its extra dynamics stand
in for something else the twin lacks (seen on trial data with no lag hidden: held-out Z -29 %,
temperatures -1 %). Candidates are ranked by ``delta_bic``; the best passing one
is added and the search repeats until none passes. The calibrations of a step run in parallel
(joblib, ``n_jobs``).

After a proposed test (a rerun with the earlier run's outcome,
:mod:`pipeline.discrepancy.followup`), an effect the test was proposed for may also meet the
held-out threshold on the test's new campaigns alone, provided the pooled held-out RMS of the
same route (Z or temperatures) does not rise (:func:`qualifies_on_test`). The earlier
campaigns were classed unable to show it: there it can at best leave their residual as it was,
so a pooled threshold asks the test's campaigns for a larger fall the more earlier campaigns
there are (on an independent machine model, eight campaigns and a 500 W column heater test:
bending's held-out Z fell by 19 % pooled over the ten, where four campaigns and the same test
gave 29 %). Every other check (delta BIC on all campaigns, the plausibility, own-evidence and
visibility gates) applies as before.

An effect whose own signature is measured in the held-out residuals and removed by it (a
*signature* callable; the workflow's is
:func:`pipeline.discrepancy.speed_steps.step_signature`: centrifugal growth's steps at the
speed changes) qualifies on it whatever its pooled held-out Z RMS does. The threshold on a
pooled RMS is there to keep out a term that only stands in for a misfit it does not own; the
signature answers that directly, while a pooled RMS dilutes a step (a few samples at each speed
change) with the thermal misfit it was never meant to remove. The pooled RMS may even rise: on
an independent machine model (centrifugal growth and nonlinear bearing heat hidden, eight
campaigns) the growth took the held-out jumps at 19 speed changes from 4.9 to 1.3 um, while the
held-out Z RMS rose by 48 %, most on two campaigns of eight (1.5 -> 4.2 and 1.8 -> 3.9 um), as
in the calibration on all of them: without the growth the twin had switched its shaft's
expansion off (0.01 um/K, its bound) to stand in for the nose's retraction; with it the shaft
expanded (0.94 um/K) and met the machine's own shaft, which the twin's is not. The report then
says that the displacement gap did not shrink. Every other check applies as before but the
own-evidence check (:func:`~pipeline.discrepancy.own_evidence.own_evidence_reason`): a signature
no other candidate makes is evidence of its own wherever it lies.

The search works through an *evaluator*: ``evaluator(effects, train_ids, test_ids, start) ->
FitResult`` (``start``: parameter name -> starting value, or None). :class:`TwinEvaluator`
builds, calibrates and predicts the twin of :mod:`pipeline.discrepancy.model` /
:mod:`pipeline.discrepancy.calibrate`; tests may pass a fake one with known evidence.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd
from joblib import delayed

from pipeline.discrepancy.followup import FollowUp, reduction_on, suspect_reason
from pipeline.discrepancy.own_evidence import (
    implausible_reason,
    own_evidence_reason,
    weak_campaigns,
)
from pipeline.fit_statistics import root_mean_square
from pipeline.progress import run_jobs
from pipeline.settings.base import unknown_name_error
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.thermal.effects import EFFECTS

logger = logging.getLogger(__name__)

CANDIDATE_EFFECTS = tuple(EFFECTS)
"""The effects the search may name (the kernel's registry), in the order they are reported."""

SENSOR_ONLY_EFFECTS = frozenset({"sensor_lag"})
"""Effects that change what the sensors read, not the structure or the displacement."""


@dataclass(frozen=True)
class SearchSettings:
    """Thresholds and resources of the search (``params.yaml`` ``discrepancy:``).

    Attributes
    ----------
    candidates : tuple of str
        Effects offered, names from :data:`CANDIDATE_EFFECTS`.
    min_heldout_reduction : float
        Relative reduction of the held-out Z RMS that qualifies an effect, 0..1.
    min_heldout_t_reduction : float
        Relative reduction of the held-out temperature RMS that qualifies an effect, 0..1
        (> 1 disables this route).
    max_delta_bic : float
        Largest change of BIC for an effect to be named (negative = the data prefer it).
    n_folds : int
        Cross-validation folds across campaigns (leave-one-campaign-out when there are at most
        this many campaigns).
    n_jobs : int
        Parallel calibrations (joblib processes); 1 = serial.
    max_effects : int
        Stop after naming this many effects.
    hold_out_validation : bool
        Search on the campaigns not in the ``validation`` split only, and check the named
        effects on the validation campaigns afterwards (:class:`ValidationCheck`); the twin
        candidate of ``evaluate`` then gets an effect set chosen without them.
    """

    candidates: tuple[str, ...] = CANDIDATE_EFFECTS
    min_heldout_reduction: float = 0.2
    min_heldout_t_reduction: float = 0.2
    max_delta_bic: float = -10.0
    n_folds: int = 4
    n_jobs: int = 2
    max_effects: int = 6
    hold_out_validation: bool = True

    @classmethod
    def from_settings(cls, settings: DiscrepancySettings) -> SearchSettings:
        """Build from the ``discrepancy`` section (empty ``candidates``: every effect).

        Raises
        ------
        ParamsError
            (a ``KeyError``) If a candidate is not in :data:`CANDIDATE_EFFECTS`.
        """
        candidates = settings.candidates or CANDIDATE_EFFECTS
        for position, name in enumerate(candidates):
            if name not in CANDIDATE_EFFECTS:
                raise unknown_name_error(
                    ("discrepancy", "candidates", position),
                    name,
                    CANDIDATE_EFFECTS,
                    "effect",
                    "registered effects",
                )
        return cls(
            candidates=candidates,
            min_heldout_reduction=settings.min_heldout_reduction,
            min_heldout_t_reduction=settings.min_heldout_temperature_reduction,
            max_delta_bic=settings.max_delta_bic,
            n_folds=settings.n_folds,
            n_jobs=settings.n_jobs,
            max_effects=settings.max_effects or len(candidates),
            hold_out_validation=settings.hold_out_validation,
        )


@dataclass
class FitResult:
    """One calibration and its predictions on some campaigns.

    Attributes
    ----------
    bic, aicc : float
        Information criteria of the calibration (on its training campaigns).
    params : dict
        Parameter name -> (value, unit).
    z_residual_um : dict
        Predicted campaign id -> measured minus twin Z, ndarray (n,), um.
    t_residual_k : dict
        Predicted campaign id -> measured minus twin temperatures, DataFrame (n, sensors), K.
    converged : bool
    seconds : float
        Wall time of the calibration and predictions, s.
    """

    bic: float
    aicc: float
    params: dict[str, tuple[float, str]]
    z_residual_um: dict[str, np.ndarray]
    t_residual_k: dict[str, pd.DataFrame] = field(default_factory=dict)
    converged: bool = True
    seconds: float = 0.0


Evaluator = Callable[[frozenset, tuple, tuple, Mapping[str, float] | None], FitResult]


@dataclass
class ModelEvidence:
    """Full calibration and cross-validation of one set of effects.

    Attributes
    ----------
    effects : frozenset of str
    full : FitResult
        Calibrated on all campaigns, predicted on all (in-sample).
    heldout : FitResult-like
        ``z_residual_um`` / ``t_residual_k`` of every campaign predicted by the fold that held
        it out; ``bic``/``aicc`` NaN.
    folds : list of FitResult
        The calibration of each fold (starting values of the next step's fold fits).
    """

    effects: frozenset[str]
    full: FitResult
    heldout: FitResult
    folds: list[FitResult] = field(default_factory=list)

    @property
    def rmse_heldout_um(self) -> float:
        """Held-out Z RMS pooled over all samples of all campaigns, um."""
        return pooled_rms(self.heldout.z_residual_um.values())

    @property
    def rmse_heldout_t_k(self) -> float:
        """Held-out temperature RMS pooled over all sensors and campaigns, K."""
        return _pooled_t(self.heldout)

    def per_campaign(self) -> dict[str, dict[str, float]]:
        """Held-out RMS per campaign: ``{id: {"z_um": .., "t_k": ..}}``."""
        return rms_by_campaign(self.heldout)


def rms_by_campaign(fit: FitResult) -> dict[str, dict[str, float]]:
    """RMS of a fit's residuals per predicted campaign: ``{id: {"z_um": .., "t_k": ..}}``."""
    out = {}
    for cid, z in fit.z_residual_um.items():
        t = fit.t_residual_k.get(cid)
        out[cid] = {
            "z_um": pooled_rms([z]),
            "t_k": pooled_rms([t.to_numpy(dtype=float).ravel()]) if t is not None else float("nan"),
        }
    return out


@dataclass
class ValidationCheck:
    """The baseline and the augmented twin predicting the validation campaigns.

    Both are calibrated on every searched campaign; the search never saw these.

    Attributes
    ----------
    campaign_ids : list of str
        Validation campaigns.
    baseline, final : FitResult
        Residuals of the baseline and of the augmented twin on them.
    """

    campaign_ids: list[str]
    baseline: FitResult
    final: FitResult

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready figures: Z (um) and temperature (K) RMS before and after, per campaign."""
        before, after = rms_by_campaign(self.baseline), rms_by_campaign(self.final)
        return {
            "campaigns": list(self.campaign_ids),
            "rmse_um_before": _num(pooled_rms(self.baseline.z_residual_um.values())),
            "rmse_um_after": _num(pooled_rms(self.final.z_residual_um.values())),
            "rmse_T_K_before": _num(_pooled_t(self.baseline)),
            "rmse_T_K_after": _num(_pooled_t(self.final)),
            "per_campaign": {
                cid: {"before": before[cid], "after": after.get(cid, {})} for cid in before
            },
        }


def _pooled_t(fit: FitResult) -> float:
    return pooled_rms(f.to_numpy(dtype=float).ravel() for f in fit.t_residual_k.values())


@dataclass(frozen=True)
class Candidate:
    """Evidence of one candidate effect at one step.

    Attributes
    ----------
    effect : str
    delta_bic, delta_aicc : float
        Criterion of the augmented model minus the current one (all campaigns).
    rmse_heldout_um : float
        Held-out Z RMS of the augmented model, um.
    heldout_reduction : float
        ``1 - rmse_heldout_um / current held-out RMS``.
    rmse_heldout_t_k : float
        Held-out temperature RMS of the augmented model, K.
    heldout_t_reduction : float
        ``1 - rmse_heldout_t_k / current held-out temperature RMS``.
    passes : bool
        It qualifies by one route (held-out Z, temperatures, its test's campaigns or its
        signature) and its BIC change is at most ``max_delta_bic``.
    converged : bool
    on_test : tuple of (float, float) or None
        Held-out Z and temperature reductions on the campaigns of the test proposed for the
        effect (None: no such test in this run).
    passes_on_test : bool
        It passes through those campaigns alone (:func:`qualifies_on_test`), not pooled.
    signature : str or None
        Its own signature measured in the held-out residuals and removed by it, in words
        (None: not shown, or the effect has none).
    passes_on_signature : bool
        It passes through that signature alone: no held-out Z, temperature or test route
        qualified.
    """

    effect: str
    delta_bic: float
    delta_aicc: float
    rmse_heldout_um: float
    heldout_reduction: float
    rmse_heldout_t_k: float
    heldout_t_reduction: float
    passes: bool
    converged: bool
    on_test: tuple[float, float] | None = None
    passes_on_test: bool = False
    signature: str | None = None
    passes_on_signature: bool = False

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "effect": self.effect,
            "delta_bic": _num(self.delta_bic),
            "delta_aicc": _num(self.delta_aicc),
            "rmse_heldout_um": _num(self.rmse_heldout_um),
            "heldout_reduction": _num(self.heldout_reduction),
            "rmse_heldout_T_K": _num(self.rmse_heldout_t_k),
            "heldout_T_reduction": _num(self.heldout_t_reduction),
            "passes": bool(self.passes),
            "converged": bool(self.converged),
            **(
                {}
                if self.on_test is None
                else {
                    "heldout_reduction_on_test": _num(self.on_test[0]),
                    "heldout_T_reduction_on_test": _num(self.on_test[1]),
                    "passes_on_test": bool(self.passes_on_test),
                }
            ),
            **(
                {}
                if self.signature is None
                else {
                    "signature": self.signature,
                    "passes_on_signature": bool(self.passes_on_signature),
                }
            ),
        }


@dataclass
class Step:
    """One named effect.

    Attributes
    ----------
    effect : str
    evidence : Candidate
    before, after : ModelEvidence
        The model before and after adding the effect.
    """

    effect: str
    evidence: Candidate
    before: ModelEvidence
    after: ModelEvidence

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields: evidence, held-out RMS before/after, calibrated parameters."""
        return {
            "effect": self.effect,
            "evidence": self.evidence.to_dict(),
            "rmse_um_before": _num(self.before.rmse_heldout_um),
            "rmse_um_after": _num(self.after.rmse_heldout_um),
            "rmse_T_K_before": _num(self.before.rmse_heldout_t_k),
            "rmse_T_K_after": _num(self.after.rmse_heldout_t_k),
            "per_campaign_before": self.before.per_campaign(),
            "per_campaign_after": self.after.per_campaign(),
            "parameters": {
                k: {"value": _num(v), "unit": u} for k, (v, u) in self.after.full.params.items()
            },
            "effect_parameters": {
                k: {"value": _num(v), "unit": u}
                for k, (v, u) in self.after.full.params.items()
                if k not in self.before.full.params
            },
        }


@dataclass
class SearchResult:
    """Outcome of :func:`forward_search`.

    Attributes
    ----------
    named_effects : list of str
        Effects added, in order; empty when none passed.
    baseline, final : ModelEvidence
    steps : list of Step
    rounds : list of list of Candidate
        Evidence of every candidate tried at every step (the last round is the one where none
        passed, or the search hit ``max_effects``).
    untestable : dict
        Effect -> roles it needs that no campaign has.
    folds : list of list of str
        Held-out campaigns of each fold.
    seconds : float
        Wall time, s.
    validation : ValidationCheck or None
        The named effects checked on the validation campaigns, None when none was held out.
    suspects : dict of str to str
        Effects that passed but were held back (by the plausibility or own-evidence checks,
        or by the search's gate; after a proposed test:
        :func:`pipeline.discrepancy.followup.suspect_reason`), with the reason.
    """

    named_effects: list[str]
    baseline: ModelEvidence
    final: ModelEvidence
    steps: list[Step]
    rounds: list[list[Candidate]]
    untestable: dict[str, list[str]]
    folds: list[list[str]]
    seconds: float
    validation: ValidationCheck | None = None
    suspects: dict[str, str] = field(default_factory=dict)

    @property
    def rmse_um_before(self) -> float:
        """Held-out Z RMS of the baseline, um."""
        return self.baseline.rmse_heldout_um

    @property
    def rmse_um_after(self) -> float:
        """Held-out Z RMS of the final model, um."""
        return self.final.rmse_heldout_um

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (``discrepancy.json`` without the localisation)."""
        return {
            "named_effects": list(self.named_effects),
            "suspects": [{"effect": e, "reason": r} for e, r in self.suspects.items()],
            "rmse_um_before": _num(self.rmse_um_before),
            "rmse_um_after": _num(self.rmse_um_after),
            "rmse_T_K_before": _num(self.baseline.rmse_heldout_t_k),
            "rmse_T_K_after": _num(self.final.rmse_heldout_t_k),
            "per_campaign": {
                cid: {
                    "before": before,
                    "after": self.final.per_campaign().get(cid, {}),
                }
                for cid, before in self.baseline.per_campaign().items()
            },
            "steps": [s.to_dict() for s in self.steps],
            "candidates_by_step": [
                {"step": i + 1, "candidates": [c.to_dict() for c in r]}
                for i, r in enumerate(self.rounds)
            ],
            "untestable": {k: list(v) for k, v in self.untestable.items()},
            "baseline_parameters": {
                k: {"value": _num(v), "unit": u} for k, (v, u) in self.baseline.full.params.items()
            },
            "final_parameters": {
                k: {"value": _num(v), "unit": u} for k, (v, u) in self.final.full.params.items()
            },
            "folds": self.folds,
            "validation": self.validation.to_dict() if self.validation else None,
            "seconds": round(self.seconds, 1),
        }


def _num(x: float) -> float | None:
    x = float(x)
    return round(x, 6) if np.isfinite(x) else None


def pooled_rms(arrays) -> float:
    """RMS of the finite values of several arrays together (NaN if none)."""
    parts = [np.asarray(a, dtype=float).ravel() for a in arrays]
    return root_mean_square(np.concatenate(parts) if parts else [])


def make_folds(campaign_ids: Sequence[str], n_folds: int) -> list[list[str]]:
    """Split campaigns into held-out folds.

    Leave-one-campaign-out when there are at most ``n_folds`` campaigns, else ``n_folds``
    folds dealt round-robin in the given order (campaigns are usually named by date, so each
    fold spans the seasons).

    Raises
    ------
    ValueError
        With fewer than 2 campaigns (nothing to hold out).
    """
    ids = list(campaign_ids)
    if len(ids) < 2:
        raise ValueError(
            f"the discrepancy search needs at least 2 valid spindle campaigns to hold one out; "
            f"got {len(ids)}; add campaigns to the raw folder"
        )
    k = min(max(int(n_folds), 2), len(ids))
    return [ids[i::k] for i in range(k)]


def _run(
    evaluator: Evaluator, effects: frozenset, train: tuple, test: tuple, start: Mapping | None
) -> FitResult:
    t0 = time.perf_counter()
    result = evaluator(effects, train, test, start)
    result.seconds = time.perf_counter() - t0
    return result


def _fit_tasks(
    effect_sets: Sequence[frozenset],
    ids: tuple[str, ...],
    folds: Sequence[Sequence[str]],
    current: ModelEvidence | None,
) -> list[tuple]:
    """Return the calibrations to run: per effect set, the full fit then one per fold.

    Each is ``(effects, train_ids, test_ids, start)``; ``start`` holds the parameters of the
    same calibration of ``current`` (name -> value), or None.
    """
    starts = [None] * (1 + len(folds))
    if current is not None:
        starts = [current.full.params] + [f.params for f in current.folds]
        starts = [{k: v for k, (v, _) in p.items()} or None for p in starts]
    tasks = []
    for effects in effect_sets:
        tasks.append((effects, ids, ids, starts[0]))
        for k, fold in enumerate(folds):
            train = tuple(c for c in ids if c not in set(fold))
            tasks.append((effects, train, tuple(fold), starts[1 + k]))
    return tasks


def _model_evidence(effects: frozenset, chunk: Sequence[FitResult]) -> ModelEvidence:
    """Return the evidence of one effect set from its full fit and its folds' fits, in order.

    The held-out result pools the folds' residuals (um, K); it converged if every fold did.
    """
    full, cv = chunk[0], chunk[1:]
    heldout = FitResult(
        bic=float("nan"),
        aicc=float("nan"),
        params={},
        z_residual_um={k: v for r in cv for k, v in r.z_residual_um.items()},
        t_residual_k={k: v for r in cv for k, v in r.t_residual_k.items()},
        converged=all(r.converged for r in cv),
    )
    return ModelEvidence(frozenset(effects), full, heldout, list(cv))


def evaluate_many(
    evaluator: Evaluator,
    effect_sets: Sequence[frozenset],
    campaign_ids: Sequence[str],
    folds: Sequence[Sequence[str]],
    n_jobs: int = 1,
    current: ModelEvidence | None = None,
) -> list[ModelEvidence]:
    """Full calibration plus cross-validation of several effect sets, in parallel.

    Parameters
    ----------
    evaluator : callable
        ``evaluator(effects, train_ids, test_ids, start) -> FitResult`` (``start``: parameter
        name -> starting value, or None).
    effect_sets : sequence of frozenset
    campaign_ids : sequence of str
        All campaigns.
    folds : sequence of sequence of str
        Held-out campaigns of each fold.
    n_jobs : int
        joblib processes; 1 runs in this process.
    current : ModelEvidence, optional
        Calibrations whose values start the new ones (full fit and the same fold).

    Returns
    -------
    list of ModelEvidence
        One per effect set, same order.
    """
    tasks = _fit_tasks(effect_sets, tuple(campaign_ids), folds, current)
    jobs = [delayed(_run)(evaluator, *t) for t in tasks]
    results = run_jobs(jobs, 1 if len(tasks) == 1 else n_jobs, "calibrations", "fits", logger)
    per = 1 + len(folds)
    return [
        _model_evidence(effects, results[i * per : (i + 1) * per])
        for i, effects in enumerate(effect_sets)
    ]


def qualifies_on_test(
    effect: str,
    on_test: tuple[float, float],
    pooled: tuple[float, float],
    settings: SearchSettings,
) -> bool:
    """Return whether an effect meets the held-out threshold on its proposed test's campaigns.

    Parameters
    ----------
    effect : str
    on_test : (float, float)
        Held-out Z and temperature reductions (0..1) on the campaigns of the test proposed for
        ``effect``.
    pooled : (float, float)
        The same reductions pooled over every campaign searched.
    settings : SearchSettings

    A route (Z, not for an effect of the readings only, or temperatures) counts when its
    reduction on the test's campaigns reaches the search's threshold and its pooled
    reduction is not negative: the test shows the effect and the effect costs nothing on the
    campaigns that could not show it.
    """
    z_test, t_test = on_test
    z_all, t_all = pooled
    z_ok = (
        effect not in SENSOR_ONLY_EFFECTS
        and z_test >= settings.min_heldout_reduction
        and z_all >= 0.0
    )
    t_ok = t_test >= settings.min_heldout_t_reduction and t_all >= 0.0
    return bool(z_ok or t_ok)


def candidate_evidence(
    effect: str,
    current: ModelEvidence,
    augmented: ModelEvidence,
    settings: SearchSettings,
    on_test: tuple[float, float] | None = None,
    signature: str | None = None,
) -> Candidate:
    """Compare an augmented model with the current one and apply the thresholds.

    ``on_test``: the held-out Z and temperature reductions on the campaigns of a test proposed
    for ``effect`` (:func:`qualifies_on_test`), None when this run has none. ``signature``:
    the effect's own signature measured and removed (:data:`SignatureEvidence`), in words, or
    None; with it the effect qualifies whatever its held-out Z RMS does.
    """
    before = current.rmse_heldout_um
    after = augmented.rmse_heldout_um
    reduction = 1.0 - after / before if before > 0 else 0.0
    t_before, t_after = current.rmse_heldout_t_k, augmented.rmse_heldout_t_k
    t_reduction = 1.0 - t_after / t_before if t_before > 0 else float("nan")
    by_z = effect not in SENSOR_ONLY_EFFECTS and (
        np.isfinite(reduction) and reduction >= settings.min_heldout_reduction
    )
    by_t = np.isfinite(t_reduction) and t_reduction >= settings.min_heldout_t_reduction
    by_test = (
        on_test is not None
        and not (by_z or by_t)
        and qualifies_on_test(effect, on_test, (reduction, t_reduction), settings)
    )
    by_signature = signature is not None and not (by_z or by_t or by_test)
    qualifies = by_z or by_t or by_test or by_signature
    delta_bic = augmented.full.bic - current.full.bic
    delta_aicc = augmented.full.aicc - current.full.aicc
    passes = bool(qualifies and np.isfinite(delta_bic) and delta_bic <= settings.max_delta_bic)
    return Candidate(
        effect=effect,
        delta_bic=float(delta_bic),
        delta_aicc=float(delta_aicc),
        rmse_heldout_um=float(after),
        heldout_reduction=float(reduction),
        rmse_heldout_t_k=float(t_after),
        heldout_t_reduction=float(t_reduction),
        passes=passes,
        converged=bool(augmented.full.converged and augmented.heldout.converged),
        on_test=on_test,
        passes_on_test=bool(passes and by_test),
        signature=signature,
        passes_on_signature=bool(passes and by_signature),
    )


TestEvidence = Callable[[str, ModelEvidence, ModelEvidence], tuple[float, float] | None]
"""``(effect, current, augmented) -> (z, t)``: held-out Z and temperature reductions on the
campaigns of the test proposed for ``effect``, or None when this run has none."""

SignatureEvidence = Callable[[str, ModelEvidence, ModelEvidence], str | None]
"""``(effect, current, augmented) -> words``: the effect's own signature (a structure of the
residual no other candidate makes) measured in the current model's held-out residuals and
removed by the augmented model, in words; None when not shown or the effect has none."""


def _ranked(
    pool: Sequence[str],
    current: ModelEvidence,
    models: Sequence[ModelEvidence],
    settings: SearchSettings,
    on_test: TestEvidence | None = None,
    signature: SignatureEvidence | None = None,
) -> list[Candidate]:
    """Return the evidence of each effect of ``pool`` (``models``, same order), by delta BIC."""
    tried = [
        candidate_evidence(
            e,
            current,
            m,
            settings,
            on_test(e, current, m) if on_test else None,
            signature(e, current, m) if signature else None,
        )
        for e, m in zip(pool, models, strict=True)
    ]
    order = np.argsort([c.delta_bic for c in tried], kind="stable")
    return [tried[i] for i in order]


def _verdict(candidate: Candidate) -> str:
    """Return the end of a candidate's log line: whether and how it passes."""
    if candidate.passes_on_test:
        return " passes on its test's campaigns"
    if candidate.passes_on_signature:
        return " passes on its own signature"
    return " passes" if candidate.passes else ""


def _log_round(step: int, ranked: Sequence[Candidate]) -> None:
    """Log the evidence of every candidate of one step of the search."""
    for c in ranked:
        logger.info(
            "step %d: %-22s held-out Z RMS %.2f um (%+.0f %%), T RMS %.3f K (%+.0f %%), "
            "delta BIC %+.1f%s",
            step,
            c.effect,
            c.rmse_heldout_um,
            -100 * c.heldout_reduction,
            c.rmse_heldout_t_k,
            -100 * c.heldout_t_reduction,
            c.delta_bic,
            _verdict(c),
        )


Gate = Callable[[str, ModelEvidence, ModelEvidence, ModelEvidence], str | None]
"""``(effect, baseline, current, augmented) -> reason``: why a passing effect stays a suspect,
or None."""


def first_reason(*gates: Gate) -> Gate:
    """Return the gate that gives the first reason of ``gates``, asked in order."""

    def gate(effect: str, *models: ModelEvidence) -> str | None:
        return next((r for g in gates if (r := g(effect, *models)) is not None), None)

    return gate


def _residuals(evidence: ModelEvidence) -> tuple[dict, dict]:
    """Held-out Z and temperature residuals of a model, per campaign."""
    return evidence.heldout.z_residual_um, evidence.heldout.t_residual_k


def _admitted(
    ranked: Sequence[Candidate],
    models: Mapping[str, ModelEvidence],
    trail: tuple[ModelEvidence, ModelEvidence, Sequence[str]],
    settings: SearchSettings,
    gate: Gate | None,
    suspects: dict[str, str],
) -> Candidate | None:
    """Return the best passing candidate whose evidence is its own; record the ones held back.

    ``trail`` is (baseline, current model, effects named so far). Its calibrated parameters
    must be the effect's physics (:func:`pipeline.discrepancy.own_evidence.implausible_reason`);
    a later effect must pass on the campaigns where the named ones act least
    (:func:`~pipeline.discrepancy.own_evidence.own_evidence_reason`), unless its own signature
    shows (:attr:`Candidate.signature`: a structure no other candidate makes is evidence of its
    own wherever it lies); then the ``gate``.
    """
    baseline, current, named = trail
    weak = weak_campaigns(_residuals(baseline), _residuals(current)) if named else []
    thresholds = (settings.min_heldout_reduction, settings.min_heldout_t_reduction)
    for candidate in (c for c in ranked if c.passes):
        augmented = models[candidate.effect]
        reason = implausible_reason(candidate.effect, augmented.full.params)
        if reason is None and candidate.signature is None:
            reason = own_evidence_reason(
                candidate.effect,
                named,
                weak,
                _residuals(current),
                _residuals(augmented),
                thresholds,
                candidate.effect in SENSOR_ONLY_EFFECTS,
            )
        if reason is None and gate is not None:
            reason = gate(candidate.effect, baseline, current, augmented)
        if reason is None:
            return candidate
        suspects[candidate.effect] = reason
        logger.warning("%s passes but stays a suspect: %s", candidate.effect, reason)
    return None


def _warn_untestable(untestable: Mapping[str, Sequence[str]] | None) -> dict[str, list[str]]:
    """Warn about each effect no sensor can test; return effect -> missing roles."""
    untestable = {k: list(v) for k, v in (untestable or {}).items() if v}
    for effect, roles in untestable.items():
        logger.warning(
            "effect %s cannot be tested: no sensor with role %s; map a sensor to it in "
            "campaign.yaml to test it",
            effect,
            " / ".join(roles),
        )
    return untestable


def forward_search(
    evaluator: Evaluator,
    campaign_ids: Sequence[str],
    settings: SearchSettings,
    untestable: Mapping[str, Sequence[str]] | None = None,
    gate: Gate | None = None,
    on_test: TestEvidence | None = None,
    signature: SignatureEvidence | None = None,
) -> SearchResult:
    """Name the missing effects by forward selection (see the module docstring).

    Parameters
    ----------
    evaluator : callable
        ``evaluator(effects, train_ids, test_ids, start) -> FitResult`` (``start``: parameter
        name -> starting value, or None).
    campaign_ids : sequence of str
    settings : SearchSettings
    untestable : mapping, optional
        Effect -> missing roles; these are never tried.
    gate : callable, optional
        Asked about each passing candidate, best first; one it gives a reason for is a
        suspect (not named, not tried again) and the next passing one is asked.
    on_test : callable, optional
        After a proposed test: each effect's held-out reductions on its test's campaigns
        (:func:`evidence_on_test`), through which it may also pass.
    signature : callable, optional
        Each effect's own signature shown (:data:`SignatureEvidence`), through which it may
        also pass.

    Returns
    -------
    SearchResult
    """
    start = time.perf_counter()
    untestable = _warn_untestable(untestable)
    folds = make_folds(campaign_ids, settings.n_folds)
    (current,) = evaluate_many(evaluator, [frozenset()], campaign_ids, folds, settings.n_jobs)
    baseline = current
    logger.info("baseline twin: held-out Z RMS %.2f um", baseline.rmse_heldout_um)
    named: list[str] = []
    suspects: dict[str, str] = {}
    steps: list[Step] = []
    rounds: list[list[Candidate]] = []
    while len(named) < settings.max_effects:
        pool = [
            e
            for e in settings.candidates
            if e not in named and e not in untestable and e not in suspects
        ]
        if not pool:
            break
        sets = [current.effects | {e} for e in pool]
        models = evaluate_many(evaluator, sets, campaign_ids, folds, settings.n_jobs, current)
        ranked = _ranked(pool, current, models, settings, on_test, signature)
        rounds.append(ranked)
        _log_round(len(rounds), ranked)
        by_effect = dict(zip(pool, models, strict=True))
        best = _admitted(ranked, by_effect, (baseline, current, named), settings, gate, suspects)
        if best is None:
            break
        after = models[pool.index(best.effect)]
        steps.append(Step(best.effect, best, current, after))
        named.append(best.effect)
        current = after
    return SearchResult(
        named_effects=named,
        baseline=baseline,
        final=current,
        steps=steps,
        rounds=rounds,
        untestable=untestable,
        folds=[list(f) for f in folds],
        seconds=time.perf_counter() - start,
        suspects=suspects,
    )


class TwinEvaluator:
    """Evaluator over the calibrated twin of :mod:`pipeline.discrepancy`.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
    roles : set of str, optional
        Roles the model is built for; default the union of the campaigns' roles.
    """

    def __init__(self, campaigns: Sequence, roles: set[str] | None = None) -> None:
        self.campaigns = {c.campaign_id: c for c in campaigns}
        self.roles = set(roles) if roles is not None else campaign_roles(campaigns)
        from pipeline.discrepancy.model import loaded_roles

        self.load_roles = loaded_roles(campaigns)

    def __call__(
        self, effects: frozenset, train: tuple, test: tuple, start: Mapping | None = None
    ) -> FitResult:
        """Calibrate ``effects`` on ``train``; residuals on ``test``.

        With ``start`` values (the current model's calibration on the same campaigns) the
        calibration runs from them and from the parameters' initial values, and the lower
        cost on ``train`` is kept. A warm start alone carries a local minimum down the search:
        on an independent machine model (four campaigns, two folds, centrifugal growth and
        nonlinear bearing heat hidden) the baseline's fit of one fold ended in a poor basin
        and the models started there stayed in it (bearing heat's fit of that fold: training
        BIC 5314, against 5082 from the initial values), which hid the growth's removal of the
        speed steps (held-out jumps 2.54 -> 2.26 um, against 2.55 -> 1.62 um).
        """
        from pipeline.discrepancy.calibrate import calibrate
        from pipeline.discrepancy.model import build_model

        model = build_model(self.roles, frozenset(effects), self.load_roles)
        start = {k: v for k, v in (start or {}).items() if k in set(model.names)} or None
        fit = calibrate(
            model, [self.campaigns[c] for c in train], start=start, also_from_initial=True
        )
        z_res, t_res = self._residuals(model, fit.theta, test)
        return FitResult(
            bic=float(fit.bic),
            aicc=float(fit.aicc),
            params={k: (float(v), str(u)) for k, (v, u) in fit.params.items()},
            z_residual_um=z_res,
            t_residual_k=t_res,
            converged=bool(fit.converged),
        )

    def predict(self, effects: frozenset, fit: FitResult, test: tuple) -> FitResult:
        """Residuals on ``test`` of an existing calibration ``fit`` of ``effects`` (no refit)."""
        from pipeline.discrepancy.model import build_model

        model = build_model(self.roles, frozenset(effects), self.load_roles)
        theta = np.array([fit.params[name][0] for name in model.names])
        z_res, t_res = self._residuals(model, theta, test)
        return replace(fit, z_residual_um=z_res, t_residual_k=t_res, seconds=0.0)

    def _residuals(self, model, theta: np.ndarray, test: tuple) -> tuple[dict, dict]:  # noqa: ANN001
        """Measured minus twin on ``test``: Z (um) and temperature (K) residuals by campaign."""
        campaigns = [self.campaigns[cid] for cid in test]
        z_res, t_res = {}, {}
        for campaign, sim in zip(campaigns, model.simulate_many(theta, campaigns), strict=True):
            cid = campaign.campaign_id
            z_res[cid] = np.asarray(campaign.z_um, dtype=float) - np.asarray(sim.z_um, dtype=float)
            cols = [c for c in sim.temperatures.columns if c in campaign.temperatures.columns]
            t_res[cid] = campaign.temperatures[cols].reset_index(drop=True) - sim.temperatures[
                cols
            ].reset_index(drop=True)
        return z_res, t_res


def campaign_roles(campaigns: Sequence) -> set[str]:
    """Union of the sensor roles of the campaigns."""
    return {r for c in campaigns for r in c.roles.values()}


def untestable_effects(candidates: Sequence[str], roles: set[str]) -> dict[str, list[str]]:
    """Effect -> missing roles, for the candidates that cannot be tested with ``roles``."""
    from pipeline.discrepancy.model import missing_roles

    out = {}
    for effect in candidates:
        missing = list(missing_roles(effect, roles))
        if missing:
            out[effect] = missing
    return out


def split_for_search(campaigns: Sequence, settings: SearchSettings) -> tuple[list, list]:
    """Campaigns to search on and validation campaigns to check the result on.

    With ``hold_out_validation`` the campaigns of the ``validation`` split are held back, as
    long as at least two others remain; otherwise every campaign is searched on.
    """
    searched = [c for c in campaigns if c.split != "validation"]
    held = [c for c in campaigns if c.split == "validation"]
    if not settings.hold_out_validation or not held:
        return list(campaigns), []
    if len(searched) < 2:
        logger.warning(
            "only %d campaign(s) outside the validation split: searching on all %d campaigns, "
            "the validation ones included",
            len(searched),
            len(campaigns),
        )
        return list(campaigns), []
    return searched, held


def follow_up_gate(follow: FollowUp | None, ids: Sequence[str], settings: SearchSettings) -> Gate:
    """Return the gate of :func:`forward_search` after an earlier run ``follow``.

    It measures each passing effect's held-out Z and temperature reductions on the campaigns
    ``follow`` had not seen and asks :func:`pipeline.discrepancy.followup.suspect_reason`.
    """
    new = list(ids) if follow is None else follow.new_campaigns(ids)

    def gate(
        effect: str, baseline: ModelEvidence, current: ModelEvidence, augmented: ModelEvidence
    ) -> str | None:
        z, t = _reductions_on(new, current, augmented)
        thresholds = (settings.min_heldout_reduction, settings.min_heldout_t_reduction)
        only_readings = effect in SENSOR_ONLY_EFFECTS
        return suspect_reason(effect, follow, ids, z, t, thresholds, only_readings)

    return gate


def _reductions_on(
    ids: Sequence[str], current: ModelEvidence, augmented: ModelEvidence
) -> tuple[float, float]:
    """Held-out Z and temperature reductions of ``augmented`` over ``current`` on ``ids``."""
    return (
        reduction_on(ids, current.heldout.z_residual_um, augmented.heldout.z_residual_um),
        reduction_on(ids, current.heldout.t_residual_k, augmented.heldout.t_residual_k),
    )


def evidence_on_test(follow: FollowUp | None, ids: Sequence[str]) -> TestEvidence | None:
    """Return the reductions on a proposed test's campaigns, for the effects it was meant for.

    None without an earlier run or without a campaign it had not seen; else a callable that
    gives, for an effect the earlier run proposed a test for (``follow.targets``), its
    held-out Z and temperature reductions on the new campaigns, and None for any other.
    """
    new = [] if follow is None else follow.new_campaigns(ids)
    if not new:
        return None

    def on_test(
        effect: str, current: ModelEvidence, augmented: ModelEvidence
    ) -> tuple[float, float] | None:
        return _reductions_on(new, current, augmented) if effect in follow.targets else None

    return on_test


def search_twin(
    campaigns: Sequence,
    settings: SearchSettings,
    follow: FollowUp | None = None,
    gate: Gate | None = None,
    signature: SignatureEvidence | None = None,
) -> SearchResult:
    """Run :func:`forward_search` on measured campaigns with the calibrated twin.

    The search uses the campaigns :func:`split_for_search` keeps; the baseline and the
    augmented twin, calibrated on all of those, then predict the validation campaigns
    (:attr:`SearchResult.validation`), which no step of the search has seen. ``gate`` is asked
    about every passing effect; after an earlier run (``follow``), a newly named effect must
    also owe its evidence to the new campaigns (:func:`follow_up_gate`). ``signature``: see
    :func:`forward_search`.
    """
    roles = campaign_roles(campaigns)
    evaluator = TwinEvaluator(campaigns, roles)
    searched, held = split_for_search(campaigns, settings)
    ids = [c.campaign_id for c in searched]
    untestable = untestable_effects(settings.candidates, roles)
    later = follow_up_gate(follow, ids, settings) if follow is not None else None
    gates = [g for g in (gate, later) if g is not None]
    combined = first_reason(*gates) if gates else None
    result = forward_search(
        evaluator, ids, settings, untestable, combined, evidence_on_test(follow, ids), signature
    )
    if held:
        held_ids = tuple(c.campaign_id for c in held)
        # the full calibrations of the search are already fitted on every searched campaign
        checks = [
            evaluator.predict(evidence.effects, evidence.full, held_ids)
            for evidence in (result.baseline, result.final)
        ]
        result.validation = ValidationCheck(list(held_ids), checks[0], checks[1])
        summary = result.validation.to_dict()
        logger.info(
            "validation campaigns (not searched): Z RMS %.2f -> %.2f um",
            summary["rmse_um_before"],
            summary["rmse_um_after"],
        )
    return result

"""The cross-season protocol: build a model on each training unit, apply it to every campaign.

From the PCDL paper (Miao et al. 2016, section 4.2): a model Mi built on batch Ki is applied to
every batch; its fit accuracy is scored on Ki, its prediction accuracy on the other training
batches and on the validation batches (section 5). Training units (one campaign, three seasons,
all training campaigns) are defined in :mod:`pipeline.protocol.units`; scores in
:mod:`pipeline.protocol.scoring`.

Models flagged ``needs_error_feedback`` (they use the measured error's own history) are scored in
two modes: ``one_step`` (each prediction uses the measured error up
to the previous sample, as on a machine that measures its error online) and ``free_run`` (their
own predictions fed back, as on a machine that does not). Other models are scored in mode
``static``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from sklearn.base import RegressorMixin, clone

from pipeline.fit_statistics import root_mean_square
from pipeline.protocol.scoring import compensation_ratio, residual_std
from pipeline.protocol.units import CampaignSeries, TrainingUnit, stack
from pipeline.warnings_capture import WarningCounts, captured

STATIC, ONE_STEP, FREE_RUN = "static", "one_step", "free_run"


@dataclass(frozen=True)
class Candidate:
    """One model on one sensor selection."""

    model: str
    selection: str


@dataclass(frozen=True)
class UnitResult:
    """A candidate fitted on one training unit, with its scores on every campaign.

    Attributes
    ----------
    candidate : Candidate
    unit : TrainingUnit
    sensors : list of str
        Model inputs (the selection made on this unit).
    chosen_params : dict
        What the fit decided (the estimator's ``chosen_params_``, when it has them).
    scores : DataFrame
        One row per (mode, test campaign); columns of ``schemas.CrossSeasonScoresModel``.
    predictions : dict
        ``{(mode, campaign_id): ndarray of shape (n,)}``, um.
    estimator : RegressorMixin
        The fitted estimator (for the physical twin ``twin``, a
        :class:`pipeline.protocol.twin_candidate.CalibratedTwin`).
    warnings : WarningCounts
        The warnings its fit and predictions emitted (captured, not printed).
    """

    candidate: Candidate
    unit: TrainingUnit
    sensors: list[str]
    chosen_params: dict
    scores: pd.DataFrame
    predictions: dict = field(repr=False)
    estimator: RegressorMixin = field(repr=False)
    warnings: WarningCounts = field(default_factory=WarningCounts)


def modes_of(estimator: RegressorMixin) -> tuple[str, ...]:
    """Scoring modes of an estimator: ``static``, or ``one_step`` and ``free_run``."""
    return (ONE_STEP, FREE_RUN) if getattr(estimator, "needs_error_feedback", False) else (STATIC,)


def predict_campaign(
    estimator: RegressorMixin, campaign: CampaignSeries, sensors: list[str], mode: str
) -> np.ndarray:
    """Predict one campaign's thermal error (um); NaN where a chosen sensor is missing.

    Parameters
    ----------
    estimator : fitted estimator
    campaign : CampaignSeries
    sensors : list of str
    mode : str
        ``static`` or ``free_run`` call ``predict(X)``; ``one_step`` also passes the measured
        error as ``y_history``.
    """
    X = campaign.features.reindex(columns=sensors)
    complete = X.notna().all(axis=1).to_numpy()
    predicted = np.full(len(X), np.nan)
    if not complete.any():
        return predicted
    if mode == ONE_STEP:
        history = np.nan_to_num(campaign.target[complete], nan=0.0)
        predicted[complete] = estimator.predict(X[complete], y_history=history)
    else:
        predicted[complete] = estimator.predict(X[complete])
    return predicted


def _role(unit: TrainingUnit, test: CampaignSeries) -> str:
    if test.split == "validation":
        return "validation"
    return "fit" if test.campaign_id in unit.campaigns else "prediction"


def score_row(
    candidate: Candidate, unit: TrainingUnit, mode: str, test: CampaignSeries, predicted: np.ndarray
) -> dict | None:
    """One row of the long score table: ``predicted`` (um) scored against ``test``'s target.

    Parameters
    ----------
    candidate : Candidate
    unit : TrainingUnit
        What the model was built on (sets ``scheme``, ``train_unit`` and the ``role``).
    mode : str
    test : CampaignSeries
    predicted : ndarray of shape (n,)
        Predicted thermal error of ``test``, um; NaN where there is no prediction.

    Returns
    -------
    dict or None
        Columns of ``schemas.CrossSeasonScoresModel``; ``None`` without any finite residual.
        The uncompensated RMS and eta are taken over the samples with a finite residual.
    """
    residual = test.target - predicted
    scored = np.isfinite(residual)
    n_samples = int(scored.sum())
    if n_samples == 0:
        return None
    rmse = root_mean_square(residual)
    uncompensated = root_mean_square(np.where(scored, test.target, np.nan))
    return {
        "axis": test.axis,
        "model": candidate.model,
        "selection": candidate.selection,
        "mode": mode,
        "scheme": unit.scheme,
        "train_unit": unit.name,
        "test_campaign": test.campaign_id,
        "test_split": test.split,
        "test_season": test.season,
        "role": _role(unit, test),
        "n_samples": n_samples,
        "rmse_um": rmse,
        "resid_std_um": residual_std(residual),
        "uncompensated_rms_um": uncompensated,
        "eta": compensation_ratio(rmse, uncompensated),
    }


def fit_and_score(
    candidate: Candidate,
    unit: TrainingUnit,
    campaigns: list[CampaignSeries],
    estimator: RegressorMixin,
    sensors: list[str],
) -> UnitResult:
    """Fit ``estimator`` on the unit's campaigns using ``sensors`` and score its test campaigns.

    Returns
    -------
    UnitResult
        ``scores`` has the columns of ``schemas.CrossSeasonScoresModel``; campaigns the unit is
        not scored on (:meth:`TrainingUnit.scores`) and campaigns without a finite residual
        get no row; ``warnings`` counts what the fit and its predictions warned.
    """
    training = [c for c in campaigns if c.campaign_id in unit.campaigns]
    X, y = stack(training, sensors)
    rows, predictions = [], {}
    with captured(fit=True) as counts:
        model = clone(estimator).fit(X, y)
        for mode in modes_of(model):
            for test in (c for c in campaigns if unit.scores(c.campaign_id)):
                predicted = predict_campaign(model, test, sensors, mode)
                predictions[(mode, test.campaign_id)] = predicted
                row = score_row(candidate, unit, mode, test, predicted)
                if row is not None:
                    rows.append(row)
    chosen = dict(getattr(model, "chosen_params_", {}) or {})
    frame = pd.DataFrame(rows)
    return UnitResult(candidate, unit, sensors, chosen, frame, predictions, model, counts)

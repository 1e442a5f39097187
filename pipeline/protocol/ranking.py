"""Which held-out score ranks an axis' candidates: the one that best says how the future goes.

Every held-out scheme the campaigns allow is scored (:mod:`pipeline.protocol.units`); one of
them ranks the candidates and chooses the champion. ``params.yaml`` ``protocol.rank_by`` names
it, or ``auto`` (the default) chooses it from the data at hand:

1. **The training campaigns span two seasons or more: leave-one-season-out** (``loso``). The
   season is what changes most between the days a compensation is built on and the days it
   runs (the PCDL paper's question, Miao et al. 2016); each season held out is a season the fit
   has not seen, with the hv-block buffer of its runs.
2. **One season, campaigns cut from one continuous record** (a run of two or more training
   campaigns): **rolling origin** (``forward``), when it forecasts at least
   :data:`MIN_FORECASTS` campaign. Inside one record the campaigns are neither independent nor
   exchangeable: the machine warms through the record and each campaign starts where the one
   before ended. Leave-one-out, even with a buffer, then trains on the hours after the held-out
   campaign, which a deployed model never has; the rolling origin only ever trains on the past,
   as the deployed model is. Cerqueira, Torgo and Mozetic (2020, "Evaluating time series
   forecasting models: an empirical study on performance estimation methods", Machine Learning
   109) found out-of-sample (forward) estimates the more accurate on real, non-stationary
   series, and cross-validation the more accurate on stationary ones; Bergmeir and Benitez
   (2012, "On the use of cross-validation for time series predictor evaluation", Information
   Sciences 191) that blocked cross-validation is sound when the series is stationary.
3. **One season, independent campaigns** (each its own run): **leave-one-campaign-out**
   (``loco``): no hours next to a held-out campaign are in training, and each fit sees all but
   one campaign, as close to the deployed fit as the data allow.
4. Otherwise whichever held-out scheme exists (``loco``, then ``forward``), or none.

Every held-out fit has fewer campaigns than the deployed one, so every held-out score leans
pessimistic; the rolling origin counts only fits on at least half of the training campaigns
(``protocol.forward_min_share``) to keep that lean small. The choice and why are stated in the
report, and the other schemes' scores stand beside it everywhere.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

from pipeline.protocol.units import (
    FORWARD,
    LOCO,
    LOSO,
    PROTOCOL_NAMES,
    CampaignSeries,
    TrainingUnit,
    held_out_schemes,
)

AUTO = "auto"
MIN_FORECASTS = 1
"""Forecast campaigns the rolling origin needs before ``auto`` ranks by it."""


@dataclass(frozen=True)
class RankingChoice:
    """The held-out scheme that ranks an axis' candidates.

    Attributes
    ----------
    scheme : str or None
        ``loso``, ``loco``, ``forward``; None when no held-out scheme exists.
    reason : str
        Why, in one sentence a user can check against the data.
    others : tuple of str
        The other held-out schemes scored beside it.
    """

    scheme: str | None
    reason: str
    others: tuple[str, ...] = ()


def ranking_scheme(
    series: list[CampaignSeries], units: list[TrainingUnit], rank_by: str = AUTO
) -> RankingChoice:
    """Choose the scheme that ranks the candidates (see the module docstring).

    Parameters
    ----------
    series : list of CampaignSeries
        The axis' campaigns.
    units : list of TrainingUnit
        Its training units (:func:`pipeline.protocol.units.training_units`).
    rank_by : str
        ``auto`` or a held-out scheme; a scheme the data do not allow falls back to ``auto``
        and the reason says so.
    """
    available = held_out_schemes(units)
    if rank_by != AUTO:
        if rank_by in available:
            reason = f"params.yaml protocol.rank_by names {PROTOCOL_NAMES[rank_by]}"
            return _choice(rank_by, reason, available)
        auto = ranking_scheme(series, units)
        reason = (
            f"params.yaml protocol.rank_by names {PROTOCOL_NAMES[rank_by]}, which these "
            f"campaigns do not allow; {auto.reason}"
        )
        return _choice(auto.scheme, reason, available)
    training = [s for s in series if s.split == "train"]
    seasons = sorted({s.season for s in training})
    forecasts = sum(len(u.tests) for u in units if u.scheme == FORWARD)
    runs = Counter(s.run_id or s.campaign_id for s in training)
    joined = max(runs.values(), default=0)
    if LOSO in available:
        reason = (
            f"the training campaigns span {len(seasons)} seasons ({', '.join(seasons)}): each "
            "fit is scored on a season it has not seen"
        )
        return _choice(LOSO, reason, available)
    if FORWARD in available and joined >= 2 and forecasts >= MIN_FORECASTS:
        reason = (
            f"one season, and {joined} training campaigns are cut from one continuous record: "
            f"each of {forecasts} campaigns is predicted by a fit on campaigns that ended "
            "before it started, as the deployed model only ever knows the past"
        )
        return _choice(FORWARD, reason, available)
    if LOCO in available:
        reason = (
            "one season of independent campaigns (none continues another): each fit is scored "
            "on the campaigns it left out"
            if joined < 2
            else f"one season, and the rolling origin forecasts only {forecasts} campaign(s): "
            "each fit is scored on the campaigns it left out, its neighbours in the record "
            "left out of training too"
        )
        return _choice(LOCO, reason, available)
    if FORWARD in available:
        return _choice(FORWARD, "the rolling origin is the only held-out scheme", available)
    return RankingChoice(None, "a single training campaign leaves no held-out score")


def _choice(scheme: str | None, reason: str, available: list[str]) -> RankingChoice:
    return RankingChoice(scheme, reason, tuple(s for s in available if s != scheme))

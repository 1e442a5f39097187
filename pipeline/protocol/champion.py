"""Choose each axis' champion, honestly, and describe it for registration.

The champion of an axis is chosen on the training campaigns only, by the score of the same kind
of fit that is then registered: a model built on several campaigns and applied to campaigns it
has not seen -- leave-one-season-out when the training campaigns span two seasons or more, else
leave-one-campaign-out (the *selection protocol*, :mod:`pipeline.protocol.units`). Candidates
are ranked by the mean RMS of the residual over the held-out campaigns (``<protocol>_Mn_rms_um``):
a compensation has to get the offset right too, which the PCDL paper's residual standard
deviation does not see (it is reported beside it). The validation campaigns never choose; they
only report the chosen model afterwards.

Eligible: candidates that run from the machine's own inputs (temperatures, spindle speed): mode
``static`` or ``free_run``. One-step-ahead scores need the measured error online and would win
trivially; the physical twin (model ``twin``) needs the spindle program and the sensor roles,
which the registered model does not take; both are ranked in the report, never chosen.

No compensation (model ``none``) is always a candidate. A model is compared with it on the same
samples: it is eligible only if it predicted at least ``evaluate.champion.min_coverage`` of the
held-out samples ``none`` was scored on (a model whose input is missing in a campaign cannot
skip that campaign), and it becomes champion only if its compensation ratio on the protocol,
eta = 1 - mean RMS(residual) / mean RMS(uncompensated error) over the same held-out samples,
is at least the margin ``evaluate.champion.min_improvement`` (and above 0); otherwise the
champion is ``none`` and the report says plainly not to compensate that axis with these inputs.
With a single training campaign there is no held-out score, and the champion is ``none``.

The registered model is the candidate's fit on all training campaigns (unit ``all_training``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import pandas as pd

from pipeline.protocol.cross_season import FREE_RUN, STATIC, UnitResult
from pipeline.protocol.scoring import SCHEME_PREFIX
from pipeline.protocol.units import POOLED_UNIT, PROTOCOL_NAMES
from pipeline.separation.features import InputSpec

DEPLOYABLE_MODES = (STATIC, FREE_RUN)
NOT_REGISTRABLE_MODELS = ("twin",)
"""Candidates never chosen as champion (see the module docstring)."""
NO_COMPENSATION = "none"
KEYS = ("model", "selection", "mode")


def protocol_column(protocol: str | None) -> str | None:
    """Summary column the champion is chosen on, e.g. ``loso_Mn_rms_um`` (None: no protocol)."""
    return None if protocol is None else f"{SCHEME_PREFIX[protocol]}Mn_rms_um"


@dataclass(frozen=True)
class Decision:
    """The champion choice of one axis.

    Attributes
    ----------
    axis : str
    protocol : str or None
        ``loso``, ``loco`` or None (a single training campaign).
    column : str or None
        The score it was chosen on (um).
    ranked : DataFrame
        Eligible candidates with a finite score, best first (``none`` among them).
    champion : Series
        The champion's summary row (``none`` when nothing beats it).
    none_score : float, um
        ``none``'s protocol score (the mean held-out RMS of the uncompensated error).
    best_score : float, um
        The best eligible model's score (``none`` excluded); NaN if there is none.
    compensate : bool
        False when the champion is ``none``.
    reason : str
        Why, in one sentence.
    ineligible : dict
        ``(model, selection, mode)`` -> why that candidate cannot be champion
        (:func:`ineligibility`), for every candidate of the axis that cannot.
    """

    axis: str
    protocol: str | None
    column: str | None
    ranked: pd.DataFrame
    champion: pd.Series
    none_score: float
    best_score: float
    compensate: bool
    reason: str
    ineligible: dict[tuple[str, str, str], str] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """``model/selection/mode`` of the champion."""
        return "/".join(str(self.champion[k]) for k in KEYS)


def eligible(summary: pd.DataFrame) -> pd.DataFrame:
    """Rows of ``summary`` a machine can run from its own inputs (see the module docstring)."""
    return summary[
        summary["mode"].isin(DEPLOYABLE_MODES) & ~summary["model"].isin(NOT_REGISTRABLE_MODELS)
    ]


def ineligibility(row: pd.Series, protocol: str | None, min_coverage: float = 0.95) -> str | None:
    """Why a candidate cannot be champion, in words; ``None`` when it can.

    Parameters
    ----------
    row : Series
        One :func:`pipeline.protocol.scoring.candidate_summary` row.
    protocol : str or None
        ``loso``, ``loco`` or None (a single training campaign).
    min_coverage : float
        Share of none's held-out samples a model must have predicted.
    """
    if row["mode"] not in DEPLOYABLE_MODES:
        return (
            f"mode {row['mode']}: each prediction uses the measured error of the step before, "
            "which a machine does not have while it cuts"
        )
    if row["model"] in NOT_REGISTRABLE_MODELS:
        return (
            "the physical twin needs the spindle program and the sensor roles, which the "
            "registered model does not take"
        )
    column = protocol_column(protocol)
    if column is None:
        return "a single training campaign leaves no held-out score to rank by"
    if pd.isna(row.get(column)):
        return f"no {PROTOCOL_NAMES[protocol]} score"
    share = row.get(f"{protocol}_coverage")
    if share is not None and not (float(share) >= min_coverage):
        share = 0.0 if pd.isna(share) else float(share)
        return (
            f"predicted {100 * share:.0f} % of the held-out samples (needs "
            f"{100 * min_coverage:.0f} %): an input is missing in some campaigns"
        )
    if "pooled_S_rms_um" in row and pd.isna(row["pooled_S_rms_um"]):
        return "no fit on all training campaigns to register"
    return None


def choose_champion(
    summary: pd.DataFrame,
    axis: str,
    protocol: str | None,
    min_improvement: float,
    min_coverage: float = 0.95,
) -> Decision:
    """Choose the champion of one axis on the selection protocol.

    Parameters
    ----------
    summary : DataFrame
        :func:`pipeline.protocol.scoring.candidate_summary` rows of this axis; must hold ``none``.
    axis : str
    protocol : str or None
        ``loso``, ``loco``, or None without a held-out scheme.
    min_improvement : float
        Compensation ratio a model must reach on the protocol to be chosen (0 to 1).
    min_coverage : float
        Share of none's held-out samples a model must have predicted to be eligible.

    Returns
    -------
    Decision

    Raises
    ------
    ValueError
        If ``none`` is not among the candidates or ``min_improvement`` is outside [0, 1).
    """
    if not 0.0 <= min_improvement < 1.0:
        raise ValueError(
            f"params.yaml evaluate.champion.min_improvement is {min_improvement}; use a "
            "fraction in [0, 1), e.g. 0.1 for 10 % less RMS than no compensation"
        )
    rows = summary[summary["axis"] == axis]
    none_rows = rows[rows["model"] == NO_COMPENSATION]
    if none_rows.empty:
        raise ValueError(
            f"axis {axis}: the candidate '{NO_COMPENSATION}' was not scored; add "
            f"'{NO_COMPENSATION}: none' to params.yaml evaluate.candidates"
        )
    column = protocol_column(protocol)
    if column is None or column not in rows or not rows[column].notna().any():
        return Decision(
            axis,
            protocol,
            column,
            none_rows.iloc[:0],
            none_rows.iloc[0],
            math.nan,
            math.nan,
            False,
            "a single training campaign leaves no campaign to test a model on: there is "
            "no held-out score to choose a compensation by",
        )
    reasons = rows.apply(ineligibility, axis=1, args=(protocol, min_coverage))
    ineligible = {
        tuple(str(row[k]) for k in KEYS): str(reason)
        for (_, row), reason in zip(rows.iterrows(), reasons, strict=True)
        if isinstance(reason, str)
    }
    eligible_rows = rows[[not isinstance(reason, str) for reason in reasons]]
    decision = _decide(eligible_rows, axis, protocol, column, min_improvement)
    return replace(decision, ineligible=ineligible)


def _decide(
    ranked: pd.DataFrame, axis: str, protocol: str, column: str, min_improvement: float
) -> Decision:
    """Rank the eligible rows on ``column`` and choose: the best model, or ``none``."""
    ranked = ranked.sort_values([column, "model", "selection"]).reset_index(drop=True)
    none_row = ranked[ranked["model"] == NO_COMPENSATION].iloc[0]
    none_score = float(none_row[column])
    models = ranked[ranked["model"] != NO_COMPENSATION]
    name = PROTOCOL_NAMES[protocol]
    if models.empty:
        return Decision(
            axis,
            protocol,
            column,
            ranked,
            none_row,
            none_score,
            math.nan,
            False,
            f"no model has a {name} score",
        )
    best = models.iloc[0]
    best_score = float(best[column])
    eta = float(best.get(f"{protocol}_eta", 1.0 - best_score / none_score))
    uncompensated = best_score / (1.0 - eta) if eta < 1.0 else none_score
    if eta > 0.0 and eta >= min_improvement:
        reason = (
            f"on the campaigns it did not see ({name}) it leaves {best_score:.2f} um RMS, "
            f"against {uncompensated:.2f} um without compensation on the same samples: "
            f"{100 * eta:.0f} % less (eta {eta:.2f}), above the {100 * min_improvement:.0f} % "
            "margin"
        )
        return Decision(axis, protocol, column, ranked, best, none_score, best_score, True, reason)
    reason = (
        f"no model removes {100 * min_improvement:.0f} % of the error on the campaigns it did "
        f"not see ({name}): the best, {'/'.join(str(best[k]) for k in KEYS)}, leaves "
        f"{best_score:.2f} um RMS against {uncompensated:.2f} um without compensation (eta "
        f"{eta:.2f})"
    )
    return Decision(axis, protocol, column, ranked, none_row, none_score, best_score, False, reason)


def champion_card(
    decision: Decision, result: UnitResult, spec: InputSpec, sample_interval_s: float
) -> dict:
    """JSON-ready description of an axis' champion (``data/models/champion/<axis>/champion.json``).

    Parameters
    ----------
    decision : Decision
    result : UnitResult
        The champion's fit on all training campaigns.
    spec : InputSpec
        How its inputs are prepared (they travel with the model).
    sample_interval_s : float, s
        Median sampling interval of the training data (lagged models count lags in samples).

    Raises
    ------
    ValueError
        If ``result`` is not a fit on all training campaigns.
    """
    if result.unit.name != POOLED_UNIT:
        raise ValueError(f"the champion must be the fit on {POOLED_UNIT}, got {result.unit.name}")
    best = decision.champion
    scores = {
        key: (None if not isinstance(value, float) or math.isnan(value) else round(value, 4))
        for key, value in best.items()
        if key.endswith("_um") or key.endswith("eta") or key.endswith("eta_val")
    }
    return {
        "axis": decision.axis,
        "model": best["model"],
        "selection": best["selection"],
        "mode": best["mode"],
        "compensate": decision.compensate,
        "reason": decision.reason,
        "protocol": decision.protocol,
        "protocol_name": PROTOCOL_NAMES.get(decision.protocol or "", "none"),
        "chosen_on": decision.column,
        "none_score_um": None if math.isnan(decision.none_score) else round(decision.none_score, 4),
        "inputs": list(result.sensors),
        "input_spec": spec.to_dict(),
        "sample_interval_s": round(float(sample_interval_s), 3),
        "trained_on": list(result.unit.campaigns),
        "chosen_params": json_ready_params(result.chosen_params),
        "scores": scores,
    }


def standing(summary: pd.DataFrame, decision: Decision) -> pd.DataFrame:
    """Each candidate of the decision's axis: eligible or why not, its rank, champion or not.

    Parameters
    ----------
    summary : DataFrame
        :func:`pipeline.protocol.scoring.candidate_summary` rows (any axes).
    decision : Decision
        The axis' champion decision.

    Returns
    -------
    DataFrame
        Columns ``axis``, ``model``, ``selection``, ``mode``, ``eligible`` (bool),
        ``ineligible_reason`` (empty when eligible), ``rank`` (1 = best on the protocol score
        among the eligible candidates, ``none`` included; 0 when not ranked), ``champion``
        (bool), in the summary's order.
    """
    rows = summary[summary["axis"] == decision.axis]
    ranks = {
        tuple(str(row[k]) for k in KEYS): position
        for position, (_, row) in enumerate(decision.ranked.iterrows(), start=1)
    }
    champion = tuple(str(decision.champion[k]) for k in KEYS)
    records = []
    for _, row in rows.iterrows():
        key = tuple(str(row[k]) for k in KEYS)
        reason = decision.ineligible.get(key, "")
        if not reason and key not in ranks:
            reason = "not ranked: no score on the selection protocol"
        records.append(
            {
                "axis": decision.axis,
                **dict(zip(KEYS, key, strict=True)),
                "eligible": not reason,
                "ineligible_reason": reason,
                "rank": ranks.get(key, 0),
                "champion": key == champion,
            }
        )
    return pd.DataFrame(records)


def json_ready_params(params: dict) -> dict:
    """Return a fit's chosen parameters as JSON-ready Python values (arrays as lists)."""
    return {k: _plain(v) for k, v in params.items()}


def _plain(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    return value.item() if hasattr(value, "item") else value

"""What the MLflow runs mean, in words: the experiment's and each run's description.

MLflow shows the experiment tag ``mlflow.note.content`` as the experiment's description and a
run's tag of the same name as the run's description (markdown). The experiment description is
the vocabulary of every score name the pipeline logs; ``tests/test_track.py`` checks that every
column of :func:`pipeline.protocol.scoring.candidate_summary` and every per-group name of
:func:`pipeline.protocol.scoring.group_scores` is explained here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from pipeline.protocol.scoring import SCHEME_PREFIX

STATISTICS = {
    "S_um": "fit accuracy: the residual standard deviation on the campaign(s) the model was "
    "built on (um; the PCDL paper's S, eq. 8)",
    "Mn_um": "prediction accuracy: the mean, over the campaigns the model did not see, of the "
    "residual standard deviation (um)",
    "Sd_um": "the spread (standard deviation) of those held-out scores across campaigns (um)",
    "Mn_val_um": "as Mn_um over the validation campaigns, which never choose a model (um)",
    "Sd_val_um": "as Sd_um over the validation campaigns (um)",
    "eta": "compensation ratio on the held-out campaigns: 1 - mean RMS(residual) / mean "
    "RMS(error without compensation) on the same samples; 1 perfect, 0 no better than not "
    "compensating, negative worse",
    "eta_val": "the compensation ratio on the validation campaigns",
    "coverage": "share of the held-out samples scored for no compensation that this candidate "
    "predicted too (an input missing in a campaign lowers it)",
}
"""Summary statistics; ``_rms`` before ``_um`` (``Mn_rms_um``...) is the same statistic of the
root mean square of the residual instead of its standard deviation."""
RMS = (
    "`<statistic>_rms_um` (e.g. `Mn_rms_um`): the same statistic of the RMS of the residual, "
    "which counts a constant offset; the standard deviation (the paper's score) does not. A "
    "compensation applied in another season suffers its offset, so the champion is chosen on "
    "an RMS score."
)
SCHEMES = {
    "campaign": "the paper's per-campaign protocol: a model built on one training campaign, "
    "applied to every other campaign",
    "loso": "leave-one-season-out: built on all training campaigns of the other seasons, "
    "applied to the left-out season (ranks the candidates when the training campaigns span "
    "two seasons or more)",
    "loco": "leave-one-campaign-out: built on all other training campaigns but the left-out "
    "one's neighbours in the same continuous record, applied to the left-out one (ranks within "
    "one season of independent campaigns)",
    "forward": "rolling origin: each training campaign predicted by a fit on the training "
    "campaigns that ended before it started (ranks within one season when campaigns are cut "
    "from one continuous record)",
    "pooled": "built on all training campaigns (the registered model's fit), applied to the "
    "validation campaigns",
}
GROUPS = {
    "loso_<season>_rms_um": "mean RMS of the residual over one season's campaigns, predicted by "
    "the fit that left that season out (um); `loso_<season>_eta` its compensation ratio",
    "loco_<campaign>_rms_um": "the same for one left-out campaign",
    "forward_<campaign>_rms_um": "the same for one campaign predicted by the fit on the "
    "campaigns before it",
    "pooled_val_<season>_rms_um": "mean RMS over one season's validation campaigns, predicted by "
    "the fit on all training campaigns (um); `pooled_val_<season>_eta` its ratio",
}
MODES = {
    "static": "predicts from the temperatures (and spindle speed) of the same instant",
    "free_run": "models on the error's own history, run on their own predictions: what a "
    "machine can do while it cuts",
    "one_step": "the same models fed the measured error of the step before; a machine does not "
    "have it while it cuts, so one_step is never eligible (its low scores are not comparable)",
}
TAGS = {
    "eligible": "true when the candidate can be registered and run from the machine's own "
    "inputs; `ineligible_reason` says why not",
    "rank": "1 = best eligible candidate of its axis on the score named by `ranked_by` (`none`, "
    "no compensation, is ranked too)",
    "champion": "true on the one child per axis that was registered",
    "ranked_by": "the score the axis' candidates are ranked and the champion chosen by",
}
EVIDENCE = {
    "scores.json": "every (training unit, test campaign) score: rmse_um, "
    "resid_std_um, eta, season, split, samples",
    "unit_scores.json": "the summary statistics of each training unit",
    "heldout_scores.json": "the per-season (or per-campaign) scores, all of them",
    "fits.json": "the inputs and decisions of each fit",
    "cross_season_rms.png": "heat-map: RMS of the residual, model built on each "
    "training unit (rows) applied to each campaign (columns, with its season)",
}


class StandingLike(Protocol):
    """What :func:`child_description` reads of a candidate's standing."""

    eligible: bool
    reason: str
    rank: int
    champion: bool


def _bullets(items: Mapping[str, str], code: bool = True) -> list[str]:
    return [f"- `{name}`: {text}" if code else f"- {name}: {text}" for name, text in items.items()]


def experiment_description(experiment: str) -> str:
    """Markdown description of the experiment: how to read its runs and every score name."""
    prefixes = ", ".join(
        f"`{prefix or '(none)'}` {scheme}" for scheme, prefix in SCHEME_PREFIX.items()
    )
    lines = [
        f"# {experiment}: thermal-error models compared across seasons",
        "",
        "One parent run per `dvc repro` (`pipeline-<hash>`), one child run per candidate "
        "`<axis>/<model>/<selection>/<mode>`. To compare: show the children (filter "
        "`tags.eligible = 'true'`), sort by the metric named in the tag `ranked_by` (lower is "
        "better), tick two runs, Compare: headline scores, per-season scores and the heat-maps "
        "under `` side by side. Every score is in um unless it is a ratio.",
        "",
        f"**Score names** `<scheme prefix><statistic>`, prefixes: {prefixes}.",
        "",
        "Schemes:",
        *_bullets({SCHEME_PREFIX[k] or "(no prefix)": v for k, v in SCHEMES.items()}),
        "",
        "Statistics:",
        *_bullets(STATISTICS),
        f"- {RMS}",
        "",
        "Per held-out group:",
        *_bullets(GROUPS),
        "",
        "Modes:",
        *_bullets(MODES),
        "",
        "Tags of a child run:",
        *_bullets(TAGS),
        "",
        "Evidence (artifacts of every child run):",
        *_bullets(EVIDENCE),
        "",
        "The parent run holds each axis' champion as `<axis>.champion.<score name>` (and "
        "`<axis>.champion.none.<score name>`: no compensation on the same samples), the whole "
        "params.yaml and the report files. The champion is registered from its child run as "
        "a new version of `thermal-error-spindle-<axis>`; the promotion gate gives it the alias "
        "`champion` when it proves better than the current one (version tags `gate`, "
        "`gate_reason`).",
    ]
    return "\n".join(lines)


def _um(value: Any) -> str:
    return "-" if value is None else f"{float(value):.2f} um"


def child_description(
    name: str,
    standing: StandingLike,
    scores: Mapping[str, float],
    groups: Sequence[Mapping[str, Any]],
    ranked_by: str,
) -> str:
    """Markdown description of one candidate's run: its standing, headline and group scores."""
    if standing.champion:
        status = f"**Champion** of its axis (rank {standing.rank} on `{ranked_by}`)."
    elif standing.eligible:
        status = f"Eligible, rank {standing.rank} on `{ranked_by}`."
    else:
        status = f"Not eligible: {standing.reason}."
    lines = [f"**{name}**. {status}"]
    if ranked_by and ranked_by in scores:
        scheme = ranked_by.split("_", 1)[0]
        eta = scores.get(f"{scheme}_eta")
        lines.append(
            f"Held-out: `{ranked_by}` = {_um(scores[ranked_by])}"
            + (f", eta {eta:.2f}." if eta is not None else ".")
        )
    per_group = [
        f"{row['held_out']} {_um(row.get('rms_um'))}" for row in groups if row["split"] == "train"
    ]
    if per_group:
        lines.append("Per held-out group: " + ", ".join(per_group) + ".")
    validation = [
        f"{row['held_out']} {_um(row.get('rms_um'))}"
        for row in groups
        if row["split"] == "validation"
    ]
    if validation:
        lines.append("Validation (fit on all training campaigns): " + ", ".join(validation) + ".")
    lines.append(
        "Evidence: `scores.json` (every training unit x test campaign), "
        "`cross_season_rms.png` (heat-map)."
    )
    return "\n\n".join(lines)


def parent_description(
    commit: str, synthetic: str, identity: str, champions: Mapping[str, Mapping[str, Any]]
) -> str:
    """Markdown description of a pipeline run: provenance and each axis' champion."""
    lines = [
        f"Thermal-error pipeline run: git commit {commit}, synthetic data: {synthetic}, "
        f"identity {identity[:12]}. One child run per candidate axis/model/selection/mode; the "
        "tag champion=true marks each axis' champion, rank its place."
    ]
    for axis, card in champions.items():
        label = "/".join(str(card[k]) for k in ("model", "selection", "mode"))
        column = card.get("chosen_on")
        score = (card.get("scores") or {}).get(column) if column else None
        verdict = "compensate" if card.get("compensate") else "do NOT compensate"
        lines.append(
            f"Axis {axis}: champion **{axis}/{label}** ({verdict}): `{column}` = {_um(score)} "
            f"against {_um(card.get('none_score_um'))} without compensation."
        )
    return "\n\n".join(lines)

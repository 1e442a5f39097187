"""Every candidate of an axis built on each training unit, scored, and the champion chosen.

:func:`evaluate_axis` runs each candidate (model x selection, see
:mod:`pipeline.protocol.candidates`; ``none``, no compensation, is one of them; the physical twin
``twin``, :mod:`pipeline.protocol.twin_candidate`) on each training unit
(:mod:`pipeline.protocol.units`) and scores it on every campaign
(:mod:`pipeline.protocol.cross_season`); :func:`decide` chooses the axis' champion on the
selection protocol (:mod:`pipeline.protocol.champion`) and :func:`champion_of` gives it with its
card and input example. The ``evaluate`` stage reads the inputs and writes what these return.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from pipeline.models.registry import MODELS
from pipeline.protocol.candidates import candidate_list, run_all
from pipeline.protocol.champion import (
    NO_COMPENSATION,
    Decision,
    champion_card,
    choose_champion,
    json_ready_params,
    standing,
)
from pipeline.protocol.cross_season import UnitResult
from pipeline.protocol.ranking import RankingChoice, ranking_scheme
from pipeline.protocol.scoring import SCHEME_PREFIX, metrics_tree
from pipeline.protocol.twin_candidate import (
    TWIN_MODEL,
    TWIN_SELECTION,
    TwinSetup,
    run_twin,
    split_twin,
)
from pipeline.protocol.units import (
    POOLED_UNIT,
    CampaignSeries,
    TrainingUnit,
    training_units,
)
from pipeline.separation.features import InputSpec, SpeedResponses
from pipeline.settings.base import unknown_name_error
from pipeline.settings.evaluate import ChampionSettings, EvaluateSettings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.warnings_capture import WarningCounts
from schemas import CrossSeasonScoresModel

LOGGER = logging.getLogger(__name__)


CANDIDATE = ["model", "selection", "mode"]


PLAIN_BASELINES = (("mlr", "all"), ("ridge", "all"))
"""Every temperature, no lag, no speed: the references a model must clearly beat."""


EXAMPLE_ROWS = 10


def label(row) -> str:
    """Short name of a candidate, e.g. ``dl/fc_grd/static``."""
    return "/".join(str(row[key]) for key in CANDIDATE)


@dataclass
class AxisEvaluation:
    """Everything ``evaluate`` computed for one displacement axis.

    Attributes
    ----------
    axis : str
    series : list of CampaignSeries
    units : list of TrainingUnit
    scores : DataFrame
        Long score rows (``schemas.CrossSeasonScoresModel``).
    results : list of UnitResult
    ranking : RankingChoice
        The held-out scheme that ranks the candidates, and why
        (:func:`pipeline.protocol.ranking.ranking_scheme`).
    skipped : dict of str to str
        Candidate (``model/selection``) -> why it was not scored.
    decision : Decision or None
        Set once the champion is chosen.
    """

    axis: str
    series: list[CampaignSeries]
    units: list[TrainingUnit]
    scores: pd.DataFrame
    results: list[UnitResult]
    ranking: RankingChoice
    skipped: dict[str, str] = field(default_factory=dict)
    decision: Decision | None = None

    @property
    def protocol(self) -> str | None:
        """The ranking scheme: ``loso``, ``loco``, ``forward`` or None."""
        return self.ranking.scheme

    @property
    def warnings(self) -> dict[tuple[str, str], WarningCounts]:
        """(model, selection) -> the warnings of its fits on every training unit, summed."""
        found: dict[tuple[str, str], WarningCounts] = {}
        for result in self.results:
            key = (result.candidate.model, result.candidate.selection)
            found.setdefault(key, WarningCounts()).add(result.warnings)
        return found


def check_models(settings: EvaluateSettings) -> None:
    """Check the model names of ``evaluate`` and their hyper-parameters, before any fit.

    Raises
    ------
    ParamsError
        For a model of ``candidates`` or ``model_params`` that is not registered (nor the
        twin), or a hyper-parameter its estimator does not have, naming the key path, the
        names allowed there and the closest one.
    """
    registered = [*sorted(MODELS), TWIN_MODEL]
    for model in [*settings.candidates, *settings.model_params]:
        if model not in registered:
            section = "candidates" if model in settings.candidates else "model_params"
            raise unknown_name_error(
                ("evaluate", section, model), model, registered, "model", "registered"
            )
    for model, params in settings.model_params.items():
        if model == TWIN_MODEL:
            continue  # the twin's calibration settings (pipeline.protocol.twin_candidate)
        accepted = sorted(MODELS[model].estimator().get_params())
        for name in params:
            if name not in accepted:
                raise unknown_name_error(
                    ("evaluate", "model_params", model, name),
                    name,
                    accepted,
                    "hyper-parameter",
                    f"{model} accepts",
                )


def evaluate_axis(
    axis: str,
    series: list[CampaignSeries],
    selected: dict,
    params: EvaluateSettings,
    twin: TwinSetup | None = None,
    twin_skipped: str | None = None,
    protocol: ProtocolSettings | None = None,
) -> AxisEvaluation:
    """Score every candidate of one axis on every training unit.

    Parameters
    ----------
    axis : str
    series : list of CampaignSeries
        The axis' valid spindle campaigns.
    selected : dict
        ``selected.json`` ``axes[axis]``: ``{method: {unit: {"inputs": [...], ...}}}``.
    params : EvaluateSettings
        The ``evaluate`` section: ``candidates``, ``full_grid``, ``model_params``, ``n_jobs``.
    twin : TwinSetup, optional
        Needed when ``candidates`` has ``twin: roles`` and ``twin_skipped`` is None.
    twin_skipped : str, optional
        Why the twin is not scored on this axis.
    protocol : ProtocolSettings, optional
        The ``protocol`` section: the held-out units' buffer and rolling origin and ``rank_by``
        (default: its defaults).

    Returns
    -------
    AxisEvaluation

    Raises
    ------
    ValueError
        If the twin is a candidate, not skipped, and ``twin`` is not given.
    """
    protocol = protocol or ProtocolSettings()
    units = training_units(series, protocol)
    ranking = ranking_scheme(series, units, protocol.rank_by)
    pairs, with_twin = split_twin(params.candidates)
    candidates = candidate_list(pairs, selected, params.full_grid)
    model_params, n_jobs = params.model_params, params.n_jobs
    results = run_all(
        candidates, units, series, selected, model_params, n_jobs, f"axis {axis} candidates"
    )
    skipped = {}
    if with_twin and twin_skipped is not None:
        skipped[f"{TWIN_MODEL}/{TWIN_SELECTION}"] = twin_skipped
        LOGGER.info("axis %s: twin candidate skipped: %s", axis, twin_skipped)
    elif with_twin:
        if twin is None:
            raise ValueError(
                f"params.yaml evaluate.candidates has '{TWIN_MODEL}' but no TwinSetup was given; "
                "build one with pipeline.stages.evaluate.read_twin_setup"
            )
        settings = dict(model_params.get(TWIN_MODEL) or {})
        setup = replace(twin, calibration={**twin.calibration, **settings})
        results = results + run_twin(units, series, setup, n_jobs)
    scores = pd.concat([r.scores for r in results], ignore_index=True)
    scores = CrossSeasonScoresModel.validate(scores, lazy=True)
    return AxisEvaluation(axis, series, units, scores, results, ranking, skipped)


def decide(
    evaluations: list[AxisEvaluation],
    summary: pd.DataFrame,
    settings: ChampionSettings | None = None,
) -> None:
    """Choose every axis' champion (sets ``decision``); ``settings``: ``evaluate.champion``."""
    settings = settings or ChampionSettings()
    margin, min_coverage = settings.min_improvement, settings.min_coverage
    for item in evaluations:
        item.decision = choose_champion(summary, item.axis, item.protocol, margin, min_coverage)
        LOGGER.info("axis %s: ranked by %s: %s", item.axis, item.protocol, item.ranking.reason)
        LOGGER.info(
            "axis %s: champion %s: %s", item.axis, item.decision.label, item.decision.reason
        )


def fitted_record(evaluations: list[AxisEvaluation]) -> dict:
    """JSON-ready record of every fit: inputs, what it decided and what it warned.

    Keyed ``<axis>/<model>/<selection>/<unit>``; ``warnings`` is
    :meth:`pipeline.warnings_capture.WarningCounts.to_dict` (count and first message by category).
    """
    return {
        f"{e.axis}/{r.candidate.model}/{r.candidate.selection}/{r.unit.name}": {
            "axis": e.axis,
            "model": r.candidate.model,
            "selection": r.candidate.selection,
            "train_unit": r.unit.name,
            "scheme": r.unit.scheme,
            "inputs": r.sensors,
            "chosen_params": json_ready_params(r.chosen_params),
            "warnings": r.warnings.to_dict(),
        }
        for e in evaluations
        for r in e.results
    }


def find_result(item: AxisEvaluation, model: str, selection: str, unit: str) -> UnitResult:
    """Return the candidate's fit on ``unit``."""
    return next(
        r
        for r in item.results
        if r.unit.name == unit and (r.candidate.model, r.candidate.selection) == (model, selection)
    )


def held_out_result(
    item: AxisEvaluation, row: pd.Series, campaign: CampaignSeries
) -> UnitResult | None:
    """Return the candidate's fit that predicted ``campaign`` without seeing it.

    Validation campaigns: the fit on all training campaigns; training campaigns: the fit of the
    ranking scheme's unit that left the campaign out and was scored on it (the forecast of the
    rolling origin); None without one.
    """
    for result in item.results:
        if (result.candidate.model, result.candidate.selection) != (row["model"], row["selection"]):
            continue
        unit = result.unit
        held_out = campaign.campaign_id not in unit.campaigns
        if (campaign.split == "validation" and unit.name == POOLED_UNIT) or (
            campaign.split == "train"
            and unit.scheme == item.protocol
            and held_out
            and unit.scores(campaign.campaign_id)
        ):
            return result
    return None


def held_out_prediction(
    item: AxisEvaluation, row: pd.Series, campaign: CampaignSeries
) -> np.ndarray | None:
    """Return a candidate's prediction of ``campaign`` (um) by a fit that did not see it.

    The fit is :func:`held_out_result`'s; None without one.
    """
    result = held_out_result(item, row, campaign)
    return None if result is None else result.predictions.get((row["mode"], campaign.campaign_id))


def held_out_fits(item: AxisEvaluation, row: pd.Series) -> dict[str, dict]:
    """Return the candidate's fits that predicted campaigns they did not see, by unit.

    Returns
    -------
    dict
        Unit name -> ``{"estimator", "inputs", "trained_on", "campaigns"}`` (the campaigns it
        predicted held out, :func:`held_out_result`): what the replay proof runs each campaign
        with.
    """
    fits: dict[str, dict] = {}
    for campaign in item.series:
        result = held_out_result(item, row, campaign)
        if result is None:
            continue
        entry = fits.setdefault(
            result.unit.name,
            {
                "estimator": result.estimator,
                "inputs": list(result.sensors),
                "trained_on": sorted(result.unit.campaigns),
                "campaigns": [],
            },
        )
        entry["campaigns"].append(campaign.campaign_id)
    return fits


def best_plain_baseline(summary: pd.DataFrame, column: str | None) -> pd.Series | None:
    """Return the better plain all-temperature regression on the protocol, if scored."""
    if column is None or column not in summary:
        return None
    plain = summary[
        summary[["model", "selection"]].apply(tuple, axis=1).isin(PLAIN_BASELINES)
        & summary[column].notna()
    ]
    return None if plain.empty else plain.sort_values(column).iloc[0]


@dataclass(frozen=True)
class AxisComparison:
    """What the report compares on one axis, computed once after the champion is chosen.

    Attributes
    ----------
    best : Series
        Summary row of the best-ranked candidate that compensates (the champion's when every
        candidate is ``none``).
    plain : Series or None
        Summary row of the better plain all-temperature regression (:func:`best_plain_baseline`).
    best_heldout, plain_heldout : DataFrame
        Their predictions of each campaign by a fit that did not see it (:func:`heldout_table`,
        um); ``plain_heldout`` is empty without a plain baseline.
    groups : DataFrame
        The axis' held-out scores per season or campaign
        (:func:`pipeline.protocol.scoring.group_scores`).
    """

    best: pd.Series
    plain: pd.Series | None
    best_heldout: pd.DataFrame
    plain_heldout: pd.DataFrame
    groups: pd.DataFrame


def compare_axis(
    item: AxisEvaluation, summary: pd.DataFrame, groups: pd.DataFrame
) -> AxisComparison:
    """Return the axis' comparison of its best model with the plain baseline.

    Parameters
    ----------
    item : AxisEvaluation
        With ``decision`` set (:func:`decide`).
    summary : DataFrame
        :func:`pipeline.protocol.scoring.candidate_summary` of every axis' scores.
    groups : DataFrame
        :func:`pipeline.protocol.scoring.group_scores` of every axis' scores.
    """
    decision = item.decision
    models = decision.ranked[decision.ranked["model"] != NO_COMPENSATION]
    best = models.iloc[0] if len(models) else decision.champion
    plain = best_plain_baseline(summary[summary["axis"] == item.axis], decision.column)
    return AxisComparison(
        best=best,
        plain=plain,
        best_heldout=heldout_table(item, best),
        plain_heldout=empty_heldout_table() if plain is None else heldout_table(item, plain),
        groups=groups[groups["axis"] == item.axis],
    )


def input_spec(inputs: list[str], features: str, separation: dict) -> InputSpec:
    """How the champion's inputs are prepared: reference, speed responses, window (separation)."""
    settings = separation.get("settings") or {}
    window = settings.get("resample_s")
    return InputSpec(
        tuple(inputs),
        features,
        str(settings.get("cold_reference", "first_sample")),
        int(settings.get("cold_n", 1)),
        SpeedResponses.from_dict(settings.get("speed_responses")),
        None if window is None else float(window),
    )


def input_example(table: pd.DataFrame, spec: InputSpec, campaign_id: str) -> pd.DataFrame:
    """Return the first rows of a training campaign as the registered model takes them."""
    rows = table[table["campaign_id"] == campaign_id].sort_values("elapsed_s").head(EXAMPLE_ROWS)
    columns = ["campaign_id", "elapsed_s", *(["rpm"] if spec.needs_speed else []), *spec.sensors]
    return rows[columns].reset_index(drop=True)


def all_scores(evaluations: list[AxisEvaluation]) -> pd.DataFrame:
    """Return the long score table of every axis (its columns even when there is none)."""
    return pd.concat([empty_scores(), *(e.scores for e in evaluations)], ignore_index=True)


def ranked_summary(summary: pd.DataFrame, decisions: list[Decision]) -> pd.DataFrame:
    """Add each candidate's standing (:func:`pipeline.protocol.champion.standing`) to the summary.

    Returns
    -------
    DataFrame
        ``summary`` plus ``eligible``, ``ineligible_reason``, ``rank``, ``champion``
        (``reports/model_scores.csv``); the key columns alone when there is no candidate.
    """
    if not len(summary.columns):
        return pd.DataFrame(columns=["axis", *CANDIDATE])
    if not decisions:
        return summary
    standings = pd.concat([standing(summary, decision) for decision in decisions])
    return summary.merge(standings, on=["axis", *CANDIDATE], how="left")


def empty_scores() -> pd.DataFrame:
    """Return one machine's long score table with its columns and no row.

    The optional ``machine`` column is the stage's, written beside each machine's scores.
    """
    columns = CrossSeasonScoresModel.to_schema().columns
    return pd.DataFrame(
        {name: pd.Series(dtype=str(col.dtype)) for name, col in columns.items() if col.required}
    )


def champion_metrics(card: dict) -> dict:
    """Return an axis' champion entry of ``metrics/cross_season.json``.

    The champion's held-out scores of the ranking scheme and of every other held-out scheme
    beside it, and its validation scores, under their one name (``loso_Mn_rms_um``,
    ``loso_eta``, ``forward_Mn_rms_um``, ``loco_Mn_rms_um``, ``pooled_Mn_val_rms_um``,
    ``pooled_eta_val``), ``compensate`` and under ``none`` what no compensation leaves on the
    ranking scheme's held-out samples.
    """
    scores = card["scores"]
    protocol = card["protocol"]
    schemes = ([protocol] if protocol else []) + list(card.get("other_protocols") or [])
    names = [
        f"{SCHEME_PREFIX[scheme]}{statistic}"
        for scheme in schemes
        for statistic in ("Mn_rms_um", "eta")
    ]
    entry = {name: scores.get(name) for name in [*names, "pooled_Mn_val_rms_um", "pooled_eta_val"]}
    if protocol:
        entry["none"] = {f"{SCHEME_PREFIX[protocol]}Mn_rms_um": card["none_score_um"]}
    return {"compensate": card["compensate"], **entry}


def round_tree(tree):
    """Round every number to 4 decimals, NaN as None: the JSON metrics of the stage."""
    if isinstance(tree, dict):
        return {k: round_tree(v) for k, v in tree.items()}
    if isinstance(tree, bool | str) or tree is None:
        return tree
    return None if not np.isfinite(tree) else round(float(tree), 4)


@dataclass(frozen=True)
class Champion:
    """An axis' champion as it is saved and registered.

    Attributes
    ----------
    card : dict
        :func:`pipeline.protocol.champion.champion_card`: what it is, its scores, its inputs.
    result : UnitResult
        Its fit on all training campaigns (the estimator that is saved).
    example : DataFrame
        The first rows of a training campaign as the registered model takes them.
    heldout : DataFrame
        Its prediction of every campaign by a fit that did not see it
        (:func:`heldout_table`).
    heldout_fits : dict
        Those fits, by unit (:func:`held_out_fits`).
    """

    card: dict
    result: UnitResult
    example: pd.DataFrame
    heldout: pd.DataFrame
    heldout_fits: dict = field(default_factory=dict)


def champion_of(
    item: AxisEvaluation, table: pd.DataFrame, features: str, separation: dict
) -> Champion:
    """Return the champion of an axis whose decision is made, fitted on all training campaigns.

    Parameters
    ----------
    item : AxisEvaluation
        With ``decision`` set (:func:`decide`).
    table : DataFrame
        The separated thermal error (``data/separated/spindle_thermal_error.parquet``).
    features : str
        ``temperature_rise`` or ``absolute``.
    separation : dict
        ``data/separated/spindle_runs.json`` (reference, speed responses, window).
    """
    best = item.decision.champion
    result = find_result(item, best["model"], best["selection"], POOLED_UNIT)
    spec = input_spec(result.sensors, features, separation)
    training = [s for s in item.series if s.split == "train"]
    times = [np.diff(s.features.index.get_level_values("elapsed_s")) for s in training]
    interval = float(np.median(np.concatenate(times))) if times else float("nan")
    card = champion_card(item.decision, result, spec, interval)
    card["ranking_reason"] = item.ranking.reason
    card["other_protocols"] = list(item.ranking.others)
    rows = table[table["axis"] == item.axis]
    example = input_example(rows, spec, training[0].campaign_id)
    return Champion(card, result, example, heldout_table(item, best), held_out_fits(item, best))


HELDOUT_COLUMNS = ["campaign_id", "elapsed_s", "measured_um", "predicted_um"]


def heldout_table(item: AxisEvaluation, row: pd.Series) -> pd.DataFrame:
    """Return a candidate's prediction of each campaign by a fit that did not see it (um).

    Training campaigns: the ranking scheme's fit that left the campaign out (the rolling
    origin's forecast of it); validation campaigns: the fit on all training campaigns
    (:func:`held_out_prediction`). Campaigns without such a fit are left out; rows in time
    order with ``campaign_id``, ``elapsed_s`` (s), ``measured_um`` (the thermal error) and
    ``predicted_um`` (NaN where an input is missing). This is how the promotion gate scores a
    new champion on campaigns the registered one never saw, without letting it see them.
    """
    frames = []
    for campaign in item.series:
        predicted = held_out_prediction(item, row, campaign)
        if predicted is None:
            continue
        elapsed = campaign.features.index.get_level_values("elapsed_s").to_numpy(dtype=float)
        frames.append(
            pd.DataFrame(
                {
                    "campaign_id": campaign.campaign_id,
                    "elapsed_s": elapsed,
                    "measured_um": campaign.target,
                    "predicted_um": predicted,
                }
            )
        )
    return pd.concat(frames, ignore_index=True) if frames else empty_heldout_table()


def empty_heldout_table() -> pd.DataFrame:
    """Return a :func:`heldout_table` without rows."""
    return pd.DataFrame({name: pd.Series(dtype=float) for name in HELDOUT_COLUMNS})


def evaluation_metrics(
    evaluations: list[AxisEvaluation],
    scores: pd.DataFrame,
    cards: dict[str, dict],
    skipped_axes: dict[str, str],
) -> dict:
    """Return ``metrics/cross_season.json``'s content, rounded to 4 decimals (um, ratios).

    Per axis: every candidate's scores (:func:`pipeline.protocol.scoring.metrics_tree`), the
    champion's (:func:`champion_metrics`) and why candidates were skipped; axes without a model
    with their reason.
    """
    tree = metrics_tree(scores)
    metrics = {
        e.axis: {
            "candidates": tree[e.axis],
            "champion": champion_metrics(cards[e.axis]),
            "skipped": dict(e.skipped),
        }
        for e in evaluations
    }
    metrics |= {axis: {"skipped": {"axis": why}} for axis, why in skipped_axes.items()}
    return round_tree(metrics)

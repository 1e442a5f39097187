"""DVC stage ``evaluate``: every candidate of every axis, built on each training unit, scored.

Reads ``data/separated/spindle_thermal_error.parquet`` (one block of rows per displacement axis),
``data/separated/spindle_runs.json`` (runs, references, speed responses) and the inputs chosen
in ``reports/selection/selected.json``. For each axis, runs each candidate (model x selection,
see :mod:`pipeline.candidates`; ``none``, no compensation, is one of them; the physical twin
``twin``, see :mod:`pipeline.twin_candidate`, which also reads
``data/validated/spindle/campaigns.parquet`` and ``reports/discrepancy/discrepancy.json``, or
is skipped with the reason) on each training unit (:mod:`pipeline.training_units`) and scores
it on every campaign (:mod:`pipeline.cross_season`, :mod:`pipeline.scoring`), then chooses the
axis' champion on the selection protocol (:mod:`pipeline.champion`). Writes the long score
table, one row of scores per candidate, ``metrics/cross_season.json`` (a DVC metric), the
fitted-model record read by ``track``, the matrices (CSV, one heat-map per candidate),
``reports/model_comparison.md`` with its figures, each axis' champion
(``data/models/champion/<axis>/``) and two DVC plot tables.
"""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass, field, replace

import joblib
import numpy as np
import pandas as pd

from pipeline import comparison_report, paths, plots
from pipeline.candidates import candidate_list, run_all
from pipeline.champion import (
    NO_COMPENSATION,
    Decision,
    champion_card,
    choose_champion,
    standing,
)
from pipeline.config import load_section
from pipeline.cross_season import UnitResult
from pipeline.errors import MissingInputError
from pipeline.features import InputSpec, SpeedResponses, check_feature_kind
from pipeline.scoring import candidate_summary, group_scores, metrics_tree, score_matrix
from pipeline.training_units import (
    POOLED_UNIT,
    CampaignSeries,
    TrainingUnit,
    protocol_scheme,
    series_by_axis,
    training_units,
)
from pipeline.twin_candidate import (
    TWIN_MODEL,
    TWIN_SELECTION,
    TwinSetup,
    named_effects,
    run_twin,
    skip_reason,
    split_twin,
    twin_campaigns,
)
from schemas import CrossSeasonScoresModel

LOGGER = logging.getLogger(__name__)

CANDIDATE = ["model", "selection", "mode"]
PLAIN_BASELINES = (("mlr", "all"), ("ridge", "all"))
"""Every temperature, no lag, no speed: the references a model must clearly beat."""
DEFAULT_MARGIN = 0.1
DEFAULT_COVERAGE = 0.95
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
    skipped: dict[str, str] = field(default_factory=dict)
    decision: Decision | None = None

    @property
    def protocol(self) -> str | None:
        """``loso``, ``loco`` or None."""
        return protocol_scheme(self.units)


def evaluate_axis(
    axis: str,
    series: list[CampaignSeries],
    selected: dict,
    params: dict,
    twin: TwinSetup | None = None,
    twin_skipped: str | None = None,
) -> AxisEvaluation:
    """Score every candidate of one axis on every training unit.

    Parameters
    ----------
    axis : str
    series : list of CampaignSeries
        The axis' valid spindle campaigns.
    selected : dict
        ``selected.json`` ``axes[axis]``: ``{method: {unit: {"inputs": [...], ...}}}``.
    params : dict
        The ``evaluate`` section: ``candidates``, ``full_grid``, ``model_params``, ``n_jobs``.
    twin : TwinSetup, optional
        Needed when ``candidates`` has ``twin: roles`` and ``twin_skipped`` is None.
    twin_skipped : str, optional
        Why the twin is not scored on this axis.

    Returns
    -------
    AxisEvaluation

    Raises
    ------
    ValueError
        If the twin is a candidate, not skipped, and ``twin`` is not given.
    """
    units = training_units(series)
    pairs, with_twin = split_twin(params["candidates"])
    candidates = candidate_list(pairs, selected, bool(params.get("full_grid")))
    model_params = params.get("model_params") or {}
    n_jobs = int(params.get("n_jobs", 1))
    results = run_all(candidates, units, series, selected, model_params, n_jobs)
    skipped = {}
    if with_twin and twin_skipped is not None:
        skipped[f"{TWIN_MODEL}/{TWIN_SELECTION}"] = twin_skipped
        LOGGER.info("axis %s: twin candidate skipped: %s", axis, twin_skipped)
    elif with_twin:
        if twin is None:
            raise ValueError(
                f"params.yaml evaluate.candidates has '{TWIN_MODEL}' but no TwinSetup was given; "
                "build one with pipeline.evaluate.read_twin_setup"
            )
        settings = dict(model_params.get(TWIN_MODEL) or {})
        setup = replace(twin, calibration={**twin.calibration, **settings})
        results = results + run_twin(units, series, setup, n_jobs)
    scores = pd.concat([r.scores for r in results], ignore_index=True)
    scores = CrossSeasonScoresModel.validate(scores, lazy=True)
    return AxisEvaluation(axis, series, units, scores, results, skipped)


def decide(
    evaluations: list[AxisEvaluation], summary: pd.DataFrame, settings: dict | None = None
) -> None:
    """Choose every axis' champion (sets ``decision``); ``settings``: ``evaluate.champion``."""
    settings = settings or {}
    margin = float(settings.get("min_improvement", DEFAULT_MARGIN))
    min_coverage = float(settings.get("min_coverage", DEFAULT_COVERAGE))
    for item in evaluations:
        item.decision = choose_champion(summary, item.axis, item.protocol, margin, min_coverage)
        LOGGER.info("axis %s: champion %s: %s", item.axis, item.decision.label,
                    item.decision.reason)  # fmt: skip


def fitted_record(evaluations: list[AxisEvaluation]) -> dict:
    """JSON-ready record of every fit: inputs and what it decided, per axis, candidate, unit."""
    return {
        f"{e.axis}/{r.candidate.model}/{r.candidate.selection}/{r.unit.name}": {
            "axis": e.axis,
            "model": r.candidate.model,
            "selection": r.candidate.selection,
            "train_unit": r.unit.name,
            "scheme": r.unit.scheme,
            "inputs": r.sensors,
            "chosen_params": {k: _plain(v) for k, v in r.chosen_params.items()},
        }
        for e in evaluations
        for r in e.results
    }


def _plain(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def find_result(item: AxisEvaluation, model: str, selection: str, unit: str) -> UnitResult:
    """Return the candidate's fit on ``unit``."""
    return next(
        r for r in item.results
        if r.unit.name == unit and (r.candidate.model, r.candidate.selection) == (model, selection)
    )  # fmt: skip


def held_out_prediction(
    item: AxisEvaluation, row: pd.Series, campaign: CampaignSeries
) -> np.ndarray | None:
    """Return a candidate's prediction of ``campaign`` (um) by a fit that did not see it.

    Validation campaigns: the fit on all training campaigns; training campaigns: the fit of the
    protocol unit that left the campaign out; None without one.
    """
    for result in item.results:
        if (result.candidate.model, result.candidate.selection) != (row["model"], row["selection"]):
            continue
        unit = result.unit
        held_out = campaign.campaign_id not in unit.campaigns
        if (campaign.split == "validation" and unit.name == POOLED_UNIT) or (
            campaign.split == "train" and unit.scheme == item.protocol and held_out
        ):
            return result.predictions.get((row["mode"], campaign.campaign_id))
    return None


def best_plain_baseline(summary: pd.DataFrame, column: str | None) -> pd.Series | None:
    """Return the better plain all-temperature regression on the protocol, if scored."""
    if column is None or column not in summary:
        return None
    plain = summary[
        summary[["model", "selection"]].apply(tuple, axis=1).isin(PLAIN_BASELINES)
        & summary[column].notna()
    ]
    return None if plain.empty else plain.sort_values(column).iloc[0]


def prediction_panels(item: AxisEvaluation, first: pd.Series, second: pd.Series | None) -> dict:
    """Measured and predicted error of held-out campaigns, per campaign (um).

    The validation campaigns when there are any, else the training campaigns, each predicted by
    the protocol fit that left it out.
    """
    validation = [s for s in item.series if s.split == "validation"]
    shown = validation or [s for s in item.series if s.split == "train"]
    panels = {}
    for campaign in shown:
        one = held_out_prediction(item, first, campaign)
        if one is None:
            continue
        two = None if second is None else held_out_prediction(item, second, campaign)
        minutes = campaign.features.index.get_level_values("elapsed_s").to_numpy() / 60.0
        panels[campaign.campaign_id] = pd.DataFrame({
            "elapsed_min": minutes, "measured_um": campaign.target, "first_um": one,
            "second_um": np.full(len(minutes), np.nan) if two is None else two,
        })  # fmt: skip
    return panels


def write_matrices(scores: pd.DataFrame, title_suffix: str) -> list[str]:
    """Matrices CSV (every axis and candidate, both scores) and one heat-map per candidate.

    Each heat-map shows the RMS of the residual (um) of the candidate built on each training
    unit (rows) and applied to each campaign (columns, labelled with their season; training
    campaigns, then the validation ones), the fits on a unit's own campaigns outlined.

    Parameters
    ----------
    scores : DataFrame
        The long score table (``reports/cross_season_scores.csv``): ``axis``, ``model``,
        ``selection``, ``mode``, ``scheme``, ``train_unit``, ``test_campaign``, ``test_split``,
        ``test_season``, ``role``, ``resid_std_um`` and ``rmse_um`` (um).
    title_suffix : str
        Says whether the data are synthetic; ends the heat-maps' titles.

    Returns
    -------
    list of str
        Heat-map paths relative to ``reports/``.
    """
    cross = scores[scores["scheme"] != "pooled"]
    frames, figures = [], []
    paths.MATRICES.mkdir(parents=True, exist_ok=True)
    for path in paths.MATRICES.glob("*.png"):
        path.unlink()
    keys_all = ["axis", *CANDIDATE]
    for keys, group in cross.groupby(keys_all, sort=True):
        for column in ("resid_std_um", "rmse_um"):
            matrix = score_matrix(group, column)
            matrix.index = pd.MultiIndex.from_tuples(
                [(*keys, column, unit) for unit in matrix.index],
                names=[*keys_all, "score", "train_unit"],
            )
            frames.append(matrix)
        out = paths.MATRICES / f"{'__'.join(keys)}.png"
        campaigns = group.drop_duplicates("test_campaign")
        in_sample = group.assign(fit=(group["role"] == "fit").astype(float))
        plots.score_heatmaps(
            {"RMS of the residual (um)": score_matrix(group, "rmse_um")},
            f"Axis {keys[0]}, candidate {' / '.join(keys[1:])}: built on each training unit, "
            f"applied to every campaign ({title_suffix})",
            out,
            seasons=dict(zip(campaigns["test_campaign"], campaigns["test_season"], strict=True)),
            validation=set(campaigns.loc[campaigns["test_split"] == "validation", "test_campaign"]),
            in_sample=score_matrix(in_sample, "fit") > 0,
        )
        figures.append(out.relative_to(paths.REPORTS).as_posix())
    matrix = pd.concat(frames) if frames else pd.DataFrame(columns=[*keys_all, "score"])
    matrix.to_csv(paths.MATRIX_CSV, float_format="%.4f")
    return figures


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


def write_champion(item: AxisEvaluation, card: dict, result: UnitResult, example: pd.DataFrame):
    """Save an axis' champion: estimator (joblib), card (JSON), input example (CSV)."""
    folder = paths.CHAMPION / item.axis
    folder.mkdir(parents=True, exist_ok=True)
    joblib.dump(result.estimator, folder / paths.CHAMPION_ESTIMATOR_FILE)
    card_text = json.dumps(card, indent=2, sort_keys=True) + "\n"
    (folder / paths.CHAMPION_CARD_FILE).write_text(card_text)
    example.to_csv(folder / paths.CHAMPION_EXAMPLE_FILE, index=False)


def champions(
    evaluations: list[AxisEvaluation], table: pd.DataFrame, features: str, separation: dict
) -> dict[str, dict]:
    """Write every axis' champion; return the cards by axis."""
    for stale in paths.CHAMPION.glob("*") if paths.CHAMPION.is_dir() else []:
        if stale.is_dir() and stale.name not in {e.axis for e in evaluations}:
            for file in stale.iterdir():
                file.unlink()
            stale.rmdir()
    cards = {}
    for item in evaluations:
        best = item.decision.champion
        result = find_result(item, best["model"], best["selection"], POOLED_UNIT)
        spec = input_spec(result.sensors, features, separation)
        training = [s for s in item.series if s.split == "train"]
        times = [np.diff(s.features.index.get_level_values("elapsed_s")) for s in training]
        interval = float(np.median(np.concatenate(times))) if times else float("nan")
        card = champion_card(item.decision, result, spec, interval)
        rows = table[table["axis"] == item.axis]
        write_champion(item, card, result, input_example(rows, spec, training[0].campaign_id))
        cards[item.axis] = card
    return cards


@dataclass(frozen=True)
class AxisReport:
    """What one axis adds to the report and the DVC plot tables."""

    section: str
    plot_rows: list[dict]
    predictions: list[pd.DataFrame]


def report_axis(
    item: AxisEvaluation,
    summary: pd.DataFrame,
    card: dict,
    selected: dict,
    separation: dict,
    heatmaps: list[str],
    origin: str,
    twin_text: str,
) -> AxisReport:
    """One axis' report section, its held-out figure and its rows of the DVC plot tables."""
    rows = summary[summary["axis"] == item.axis]
    decision = item.decision
    models = decision.ranked[decision.ranked["model"] != NO_COMPENSATION]
    first = models.iloc[0] if len(models) else decision.champion
    second = best_plain_baseline(rows, decision.column)
    panels = prediction_panels(item, first, second)
    figure = paths.COMPARISON_FIGURES / f"heldout_{item.axis}.png"
    labels = (f"best model: {label(first)}",
              "no plain baseline" if second is None else f"plain: {label(second)}")  # fmt: skip
    where = (
        "validation campaigns, built on all training campaigns"
        if any(s.split == "validation" for s in item.series)
        else "each training campaign, predicted by the fit that left it out"
    )
    seasons = {s.campaign_id: s.season for s in item.series}
    title = f"Axis {item.axis}: {where} ({origin})"
    plots.predicted_vs_measured(panels, labels, title, figure, seasons=seasons)
    groups = group_scores(item.scores)
    context = comparison_report.AxisContext(
        item.axis, rows, decision, card, selected["axes"][item.axis], item.series,
        item.skipped, second, groups,
    )  # fmt: skip
    figures = comparison_report.AxisFigures(
        figure.relative_to(paths.REPORTS).as_posix(), labels,
        [h for h in heatmaps if h.startswith(f"matrices/{item.axis}__")],
    )  # fmt: skip
    plot_rows = [
        {
            "axis": item.axis, "candidate": f"{item.axis}: {label(row)}",
            "heldout_rms_um": row.get(decision.column) if decision.column else np.nan,
            "eta": row.get(f"{item.protocol}_eta") if item.protocol else np.nan,
        }
        for _, row in rows.iterrows()
    ]  # fmt: skip
    predictions = [
        frame.rename(columns={"first_um": "predicted_um"}).drop(columns="second_um")
        .assign(axis=item.axis, campaign_id=campaign)
        for campaign, frame in panels.items()
    ]  # fmt: skip
    section = comparison_report.axis_section(context, separation, figures, twin_text)
    return AxisReport(section, plot_rows, predictions)


def all_scores(evaluations: list[AxisEvaluation]) -> pd.DataFrame:
    """Return the long score table of every axis (its columns even when there is none)."""
    return pd.concat([empty_scores(), *(e.scores for e in evaluations)], ignore_index=True)


def ranked_summary(summary: pd.DataFrame, decisions: list[Decision]) -> pd.DataFrame:
    """Add each candidate's standing (:func:`pipeline.champion.standing`) to the summary.

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


def write_tables(
    evaluations: list[AxisEvaluation],
    scores: pd.DataFrame,
    summary: pd.DataFrame,
    table: pd.DataFrame,
    features: str,
    separation: dict,
    skipped_axes: dict[str, str],
) -> dict[str, dict]:
    """Write scores, summary, metrics, fitted record and champions; return the champion cards."""
    for path in (paths.SCORES_LONG, paths.CROSS_SEASON_METRICS, paths.PLOT_MODEL_SCORES,
                 paths.COMPARISON_FIGURES / "x", paths.CHAMPION / "x"):  # fmt: skip
        path.parent.mkdir(parents=True, exist_ok=True)
    scores.to_csv(paths.SCORES_LONG, index=False, float_format="%.6g")
    ranked = ranked_summary(summary, [e.decision for e in evaluations])
    ranked.to_csv(paths.CANDIDATE_SCORES, index=False, float_format="%.4f")
    group_scores(scores).to_csv(paths.GROUP_SCORES, index=False, float_format="%.4f")
    cards = champions(evaluations, table, features, separation)
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
    paths.CROSS_SEASON_METRICS.write_text(json.dumps(_round(metrics), indent=2, sort_keys=True))
    paths.FITTED_MODELS.write_text(json.dumps(fitted_record(evaluations), indent=2, sort_keys=True))
    return cards


def write_outputs(
    evaluations: list[AxisEvaluation],
    summary: pd.DataFrame,
    table: pd.DataFrame,
    selected: dict,
    features: str,
    separation: dict,
    twin_text: str = "",
    skipped_axes: dict[str, str] | None = None,
) -> dict[str, dict]:
    """Write every output declared for the stage in ``dvc.yaml``; return the champion cards.

    Axes of ``skipped_axes`` (axis -> why it has no model) are named in the report and the
    metrics; with no axis at all every output is still written, empty, and the report says why.
    ``twin_text``: the report's paragraph on the twin candidate (:func:`twin_section`);
    ``summary``: :func:`pipeline.scoring.candidate_summary` of :func:`all_scores`.
    """
    skipped_axes = dict(skipped_axes or {})
    scores = all_scores(evaluations)
    cards = write_tables(evaluations, scores, summary, table, features, separation, skipped_axes)
    synthetic = bool(table["synthetic"].any())
    origin = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    heatmaps = write_matrices(scores, origin)
    parts = [
        report_axis(e, summary, cards[e.axis], selected, separation, heatmaps, origin, twin_text)
        for e in evaluations
    ]
    sections = [part.section for part in parts]
    sections += [f"## Axis {axis}\n\nNo model: {why}.\n" for axis, why in skipped_axes.items()]
    paths.MODEL_COMPARISON.write_text(
        comparison_report.render(sections, separation, synthetic, [e.axis for e in evaluations])
    )
    plot_rows = [row for part in parts for row in part.plot_rows]
    pd.DataFrame(plot_rows).to_csv(paths.PLOT_MODEL_SCORES, index=False, float_format="%.4f")
    frames = [frame for part in parts for frame in part.predictions]
    predictions = pd.concat(frames, ignore_index=True) if frames else (
        pd.DataFrame(columns=["elapsed_min", "measured_um", "predicted_um", "axis", "campaign_id"])
    )  # fmt: skip
    predictions.round(4).to_csv(paths.PLOT_PREDICTIONS, index=False)
    return cards


def empty_scores() -> pd.DataFrame:
    """Return the long score table with its columns and no row."""
    columns = CrossSeasonScoresModel.to_schema().columns
    return pd.DataFrame({name: pd.Series(dtype=str(col.dtype)) for name, col in columns.items()})


def champion_metrics(card: dict) -> dict:
    """Return an axis' champion entry of ``metrics/cross_season.json``.

    The champion's held-out and validation scores under their one name (``loso_Mn_rms_um``,
    ``loso_eta``, ``pooled_Mn_val_rms_um``, ``pooled_eta_val``; ``loco_`` for
    leave-one-campaign-out), ``compensate``, and under ``none`` what no compensation leaves on
    the same held-out samples.
    """
    scores = card["scores"]
    protocol = card["protocol"]
    names = [f"{protocol}_Mn_rms_um", f"{protocol}_eta"] if protocol else []
    entry = {name: scores.get(name) for name in [*names, "pooled_Mn_val_rms_um", "pooled_eta_val"]}
    if protocol:
        entry["none"] = {f"{protocol}_Mn_rms_um": card["none_score_um"]}
    return {"compensate": card["compensate"], **entry}


def _round(tree):
    if isinstance(tree, dict):
        return {k: _round(v) for k, v in tree.items()}
    if isinstance(tree, bool | str) or tree is None:
        return tree
    return None if not np.isfinite(tree) else round(float(tree), 4)


def read_twin_setup(table: pd.DataFrame, series: list[CampaignSeries]) -> TwinSetup:
    """Everything the ``twin`` candidate reads besides the separated table (axis Z rows).

    The sensor roles and spindle programs from ``data/validated/spindle/campaigns.parquet``; the
    effects from ``reports/discrepancy/discrepancy.json`` (absent: the baseline twin, with a
    warning); the cold reference from ``params.yaml`` ``separate`` (``cold_reference``,
    ``cold_n``), so that the twin's drift is referenced as the separation stage references the
    measured one.
    """
    meta = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    effects, source = named_effects(read_discrepancy())
    separate = load_section("separate")
    return TwinSetup(
        campaigns=twin_campaigns(table, meta, series),
        effects=effects,
        effects_source=source,
        cold_reference=str(separate["cold_reference"]),
        cold_n=int(separate["cold_n"]),
    )


def read_discrepancy() -> dict | None:
    """``reports/discrepancy/discrepancy.json``, or None (with a warning) when absent."""
    if not paths.DISCREPANCY_DOCUMENT.is_file():
        LOGGER.warning("%s not found: the twin candidate is the baseline twin",
                       paths.DISCREPANCY_DOCUMENT)  # fmt: skip
        return None
    return json.loads(paths.DISCREPANCY_DOCUMENT.read_text(encoding="utf-8"))


def sensor_roles() -> frozenset[str]:
    """Every sensor role of the valid spindle campaigns."""
    meta = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    return frozenset(
        str((spec or {}).get("role", "other"))
        for text in meta["sensors_json"]
        for spec in json.loads(text).values()
    )


def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``evaluate`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal evaluate", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("evaluate")
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    if not paths.SELECTED.is_file():
        raise MissingInputError(
            f"{paths.SELECTED} not found: run the select stage first (dvc repro select)"
        )
    document = json.loads(paths.SELECTED.read_text())
    features, selected = check_feature_kind(str(document["features"])), document["axes"]
    separation = json.loads(paths.SPINDLE_RUNS.read_text())
    with_twin = split_twin(params["candidates"])[1]
    discrepancy = read_discrepancy() if with_twin else None
    held_back = discrepancy is None or discrepancy.get("validation") is not None
    roles = sensor_roles() if with_twin else frozenset()
    evaluations, twin_source = [], None
    skipped_axes = dict(document.get("skipped_axes") or {})
    for axis, series in series_by_axis(table, features).items():
        if axis not in selected:
            continue
        skipped, twin = None, None
        if with_twin:
            skipped = skip_reason(axis, discrepancy, series, roles)
            if skipped is None:
                twin = read_twin_setup(table[table["axis"] == axis], series)
                twin_source = twin.effects_source
        evaluations.append(evaluate_axis(axis, series, selected[axis], params, twin, skipped))
    summary = candidate_summary(all_scores(evaluations))
    decide(evaluations, summary, params.get("champion"))
    twin_text = (
        "" if twin_source is None else comparison_report.twin_section(twin_source, held_back)
    )
    write_outputs(
        evaluations, summary, table, document, features, separation, twin_text, skipped_axes
    )
    return 0

"""DVC stage ``evaluate``: every candidate model, built on each training unit, scored everywhere.

Reads ``data/separated/spindle_thermal_error.parquet`` and the sensitive points of
``reports/selection/selected.json``. Runs each candidate (model x selection, see
:mod:`pipeline.candidates`; the physical twin ``twin``, see :mod:`pipeline.twin_candidate`, which
also reads ``data/validated/spindle/campaigns.parquet`` for the sensor roles and spindle programs
and ``reports/discrepancy/discrepancy.json`` for its effects) on each training unit (each
training campaign, each season left out, all training campaigns; :mod:`pipeline.training_units`)
and scores it on every campaign (:mod:`pipeline.cross_season`, :mod:`pipeline.scoring`).
Writes the long score table, one row of scores per candidate, ``metrics/cross_season.json`` (a
DVC metric), the fitted-model record read by ``track``, the matrices (CSV, one heat-map per
candidate), ``reports/model_comparison.md`` with its figures, the champion model
(``data/models/champion/``) and two DVC plot tables.
"""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import replace

import joblib
import numpy as np
import pandas as pd

from pipeline import comparison_report, paths, plots
from pipeline.candidates import candidate_list, run_all
from pipeline.champion import champion_card, rank_candidates
from pipeline.config import load_section
from pipeline.cross_season import UnitResult
from pipeline.scoring import candidate_summary, metrics_tree, score_matrix
from pipeline.select import feature_prefix, sensor_columns
from pipeline.training_units import POOLED_UNIT, CampaignSeries, campaign_series, training_units
from pipeline.twin_candidate import (
    TWIN_MODEL,
    TwinSetup,
    named_effects,
    run_twin,
    split_twin,
    twin_campaigns,
)
from schemas import CrossSeasonScoresModel

LOGGER = logging.getLogger(__name__)

CANDIDATE = ["model", "selection", "mode"]


def label(row) -> str:
    """Short name of a candidate, e.g. ``dl/fc_grd/static``."""
    return "/".join(str(row[key]) for key in CANDIDATE)


def evaluate(
    series: list[CampaignSeries], selected: dict, params: dict, twin: TwinSetup | None = None
) -> tuple[pd.DataFrame, list[UnitResult]]:
    """Score every candidate on every training unit.

    Parameters
    ----------
    series : list of CampaignSeries
        All valid spindle campaigns.
    selected : dict
        ``selected.json`` ``methods``: ``{method: {unit: {"sensors": [...], ...}}}``.
    params : dict
        The ``evaluate`` section: ``candidates``, ``full_grid``, ``model_params``, ``n_jobs``.
    twin : TwinSetup, optional
        Needed when ``candidates`` has ``twin: roles`` (:func:`read_twin_setup`).

    Returns
    -------
    scores : DataFrame
        Long score table (``schemas.CrossSeasonScoresModel``).
    results : list of UnitResult

    Raises
    ------
    ValueError
        If the twin is a candidate and ``twin`` is not given.
    """
    units = training_units(series)
    pairs, with_twin = split_twin(params["candidates"])
    if with_twin and twin is None:
        raise ValueError(
            f"params.yaml evaluate.candidates has '{TWIN_MODEL}' but no TwinSetup was given; "
            "build one with pipeline.evaluate.read_twin_setup"
        )
    candidates = candidate_list(pairs, selected, bool(params.get("full_grid")))
    model_params = params.get("model_params") or {}
    n_jobs = int(params.get("n_jobs", 1))
    results = run_all(candidates, units, series, selected, model_params, n_jobs)
    if with_twin:
        settings = dict(model_params.get(TWIN_MODEL) or {})
        setup = replace(twin, calibration={**twin.calibration, **settings})
        results = results + run_twin(units, series, setup, n_jobs)
    scores = pd.concat([r.scores for r in results], ignore_index=True)
    return CrossSeasonScoresModel.validate(scores, lazy=True), results


def fitted_record(results: list[UnitResult]) -> dict:
    """JSON-ready record of every fit: sensors and what the fit decided, per candidate and unit."""
    return {
        f"{r.candidate.model}/{r.candidate.selection}/{r.unit.name}": {
            "model": r.candidate.model,
            "selection": r.candidate.selection,
            "train_unit": r.unit.name,
            "scheme": r.unit.scheme,
            "sensors": r.sensors,
            "chosen_params": {k: _plain(v) for k, v in r.chosen_params.items()},
        }
        for r in results
    }


def _plain(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def pooled_result(results: list[UnitResult], model: str, selection: str) -> UnitResult:
    """Return the candidate's fit on all training campaigns."""
    return next(
        r for r in results
        if r.unit.name == POOLED_UNIT and (r.candidate.model, r.candidate.selection)
        == (model, selection)
    )  # fmt: skip


def prediction_panels(
    series: list[CampaignSeries], first: tuple[UnitResult, str], second: tuple[UnitResult, str]
) -> dict[str, pd.DataFrame]:
    """Measured and two candidates' predicted error on each validation campaign (um)."""
    panels = {}
    for campaign in (s for s in series if s.split == "validation"):
        minutes = campaign.features.index.get_level_values("elapsed_s").to_numpy() / 60.0
        panels[campaign.campaign_id] = pd.DataFrame({
            "elapsed_min": minutes,
            "measured_um": campaign.target,
            "first_um": first[0].predictions[(first[1], campaign.campaign_id)],
            "second_um": second[0].predictions[(second[1], campaign.campaign_id)],
        })  # fmt: skip
    return panels


def write_matrices(scores: pd.DataFrame, title_suffix: str) -> list[str]:
    """Matrices CSV (every candidate, both scores) and one heat-map PNG per candidate.

    Returns
    -------
    list of str
        Heat-map paths relative to ``reports/``.
    """
    cross = scores[scores["scheme"] != "pooled"]
    frames, figures = [], []
    for path in paths.MATRICES.glob("*.png"):
        path.unlink()
    for keys, group in cross.groupby(CANDIDATE, sort=True):
        for column in ("resid_std_um", "rmse_um"):
            matrix = score_matrix(group, column)
            matrix.index = pd.MultiIndex.from_tuples(
                [(*keys, column, unit) for unit in matrix.index],
                names=[*CANDIDATE, "score", "train_unit"],
            )
            frames.append(matrix)
        out = paths.MATRICES / f"{'__'.join(keys)}.png"
        plots.score_heatmaps(
            {"residual standard deviation (um)": score_matrix(group, "resid_std_um")},
            f"{'/'.join(keys)}: built on one training unit, applied to every campaign "
            f"({title_suffix})",
            out,
        )
        figures.append(out.relative_to(paths.REPORTS).as_posix())
    pd.concat(frames).to_csv(paths.MATRIX_CSV, float_format="%.4f")
    return figures


def write_champion(card: dict, result: UnitResult) -> None:
    """Save the champion estimator (joblib) and its card (JSON) for ``track`` to register."""
    paths.CHAMPION.mkdir(parents=True, exist_ok=True)
    joblib.dump(result.estimator, paths.CHAMPION_ESTIMATOR)
    paths.CHAMPION_CARD.write_text(json.dumps(card, indent=2, sort_keys=True) + "\n")


def write_outputs(
    series: list[CampaignSeries],
    selected: dict,
    features: str,
    scores: pd.DataFrame,
    results: list[UnitResult],
    synthetic: bool,
    twin_source: str | None = None,
) -> dict:
    """Write every output declared for the stage in ``dvc.yaml``; return the champion card.

    ``twin_source`` says which twin the ``twin`` candidate is (report note); ``None`` without it.
    """
    for path in (paths.SCORES_LONG, paths.CROSS_SEASON_METRICS, paths.PLOT_MODEL_SCORES):
        path.parent.mkdir(parents=True, exist_ok=True)
    scores.to_csv(paths.SCORES_LONG, index=False, float_format="%.6g")
    summary = candidate_summary(scores)
    summary.to_csv(paths.CANDIDATE_SCORES, index=False, float_format="%.4f")
    paths.CROSS_SEASON_METRICS.write_text(
        json.dumps(_round(metrics_tree(scores)), indent=2, sort_keys=True)
    )
    paths.FITTED_MODELS.write_text(json.dumps(fitted_record(results), indent=2, sort_keys=True))

    ranked, column = rank_candidates(summary)
    best, worst = ranked.iloc[0], ranked.iloc[-1]
    champion = pooled_result(results, best["model"], best["selection"])
    card = champion_card(best, column, champion, features)
    write_champion(card, champion)

    origin = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    heatmaps = write_matrices(scores, origin)
    worst_fit = pooled_result(results, worst["model"], worst["selection"])
    panels = prediction_panels(series, (champion, best["mode"]), (worst_fit, worst["mode"]))
    figure = paths.COMPARISON_FIGURES / "best_worst_validation.png"
    labels = (f"best: {label(best)}", f"worst: {label(worst)}")
    plots.predicted_vs_measured(
        panels, labels, f"Validation campaigns, models built on all training campaigns ({origin})",
        figure,
    )  # fmt: skip
    n_campaigns = {
        split: sum(s.split == split for s in series) for split in ("train", "validation")
    }
    paths.MODEL_COMPARISON.write_text(
        comparison_report.render(
            summary,
            card,
            selected,
            heatmaps,
            figure.relative_to(paths.REPORTS).as_posix(),
            labels,
            n_campaigns,
            synthetic,
            twin_source,
        )  # fmt: skip
    )

    plot_scores = summary.assign(candidate=summary.apply(label, axis=1))
    plot_scores[["candidate", "Mn_um", "Mn_val_um"]].to_csv(
        paths.PLOT_MODEL_SCORES, index=False, float_format="%.4f"
    )
    rows = []
    for campaign, frame in panels.items():
        rows.append(frame.rename(columns={"first_um": "predicted_um"})
                    .drop(columns="second_um").assign(campaign_id=campaign))  # fmt: skip
    predictions = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()
    predictions.round(4).to_csv(paths.PLOT_PREDICTIONS, index=False)
    return card


def _round(tree):
    if isinstance(tree, dict):
        return {k: _round(v) for k, v in tree.items()}
    return None if not np.isfinite(tree) else round(float(tree), 4)


def read_twin_setup(table: pd.DataFrame, series: list[CampaignSeries]) -> TwinSetup:
    """Everything the ``twin`` candidate reads besides the separated table.

    The sensor roles and spindle programs from ``data/validated/spindle/campaigns.parquet``; the
    effects from ``reports/discrepancy/discrepancy.json`` (absent: the baseline twin, with a
    warning); the cold reference from ``params.yaml`` ``separate`` (``cold_reference``,
    ``cold_n``), so that the twin's drift is referenced as the separation stage references the
    measured one.
    """
    meta = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    document = None
    if paths.DISCREPANCY_DOCUMENT.is_file():
        document = json.loads(paths.DISCREPANCY_DOCUMENT.read_text(encoding="utf-8"))
    effects, source = named_effects(document)
    if document is None:
        LOGGER.warning("%s not found: the twin candidate is the %s", paths.DISCREPANCY_DOCUMENT,
                       source)  # fmt: skip
    separate = load_section("separate")
    return TwinSetup(
        campaigns=twin_campaigns(table, meta, series),
        effects=effects,
        effects_source=source,
        cold_reference=str(separate["cold_reference"]),
        cold_n=int(separate["cold_n"]),
    )


def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``evaluate`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal evaluate", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("evaluate")
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    if not paths.SELECTED.is_file():
        raise FileNotFoundError(
            f"{paths.SELECTED} not found: run the select stage first (dvc repro select)"
        )
    document = json.loads(paths.SELECTED.read_text())
    features, selected = str(document["features"]), document["methods"]
    series = campaign_series(table, sensor_columns(table), feature_prefix(features))
    twin = read_twin_setup(table, series) if split_twin(params["candidates"])[1] else None
    scores, results = evaluate(series, selected, params, twin)
    card = write_outputs(series, selected, features, scores, results,
                         bool(table["synthetic"].any()),
                         None if twin is None else twin.effects_source)  # fmt: skip
    LOGGER.info(
        "champion %s/%s/%s on %s: %s %.2f um; report %s", card["model"], card["selection"],
        card["mode"], ", ".join(card["sensors"]) or "no sensor", card["chosen_on"],
        card["scores_um"].get(card["chosen_on"]) or float("nan"), paths.MODEL_COMPARISON,
    )  # fmt: skip
    return 0

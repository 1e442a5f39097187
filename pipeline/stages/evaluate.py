"""DVC stage ``evaluate``: every candidate of every axis, built on each training unit, scored.

Reads ``data/separated/spindle_thermal_error.parquet`` (one block of rows per displacement axis),
``data/separated/spindle_runs.json`` (runs, references, speed responses) and the inputs chosen
in ``reports/selection/selected.json``. For each axis, runs each candidate (model x selection,
see :mod:`pipeline.protocol.candidates`; ``none``, no compensation, is one of them; the physical
twin ``twin``, see :mod:`pipeline.protocol.twin_candidate`, which also reads
``data/validated/spindle/campaigns.parquet`` and ``reports/discrepancy/discrepancy.json``, or
is skipped with the reason) on each training unit (:mod:`pipeline.protocol.units`) and scores
it on every campaign (:mod:`pipeline.protocol.cross_season`, :mod:`pipeline.protocol.scoring`),
then chooses the axis' champion on the selection protocol (:mod:`pipeline.protocol.champion`).
Writes the long score table, one row of scores per candidate, ``metrics/cross_season.json`` (a DVC
metric), the fitted-model record read by ``track``, the matrices (CSV, one heat-map per candidate),
``reports/model_comparison.md`` with its figures, each axis' champion
(``data/models/champion/<axis>/``) and two DVC plot tables.
"""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass

import joblib
import pandas as pd

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.protocol.evaluation import (
    AxisComparison,
    AxisEvaluation,
    Champion,
    all_scores,
    champion_of,
    check_models,
    compare_axis,
    decide,
    evaluate_axis,
    evaluation_metrics,
    fitted_record,
    ranked_summary,
)
from pipeline.protocol.scoring import candidate_summary, group_scores
from pipeline.protocol.twin_candidate import (
    TwinSetup,
    named_effects,
    skip_reason,
    split_twin,
    twin_campaigns,
)
from pipeline.protocol.units import (
    CampaignSeries,
    series_by_axis,
)
from pipeline.reporting import comparison as comparison_report
from pipeline.reporting.evaluation import report_axis, write_matrices
from pipeline.separation.features import check_feature_kind
from pipeline.settings.base import load_settings
from pipeline.settings.evaluate import EvaluateSettings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


def write_champions(champions: dict[str, Champion]) -> None:
    """Save each axis' champion: estimator, card, input example, held-out predictions and fits.

    Folders of axes that no longer have a champion are removed.
    """
    for stale in paths.CHAMPION.glob("*") if paths.CHAMPION.is_dir() else []:
        if stale.is_dir() and stale.name not in champions:
            for file in stale.iterdir():
                file.unlink()
            stale.rmdir()
    for axis, champion in champions.items():
        folder = paths.CHAMPION / axis
        folder.mkdir(parents=True, exist_ok=True)
        joblib.dump(champion.result.estimator, folder / paths.CHAMPION_ESTIMATOR_FILE)
        card_text = json.dumps(champion.card, indent=2, sort_keys=True) + "\n"
        (folder / paths.CHAMPION_CARD_FILE).write_text(card_text)
        champion.example.to_csv(folder / paths.CHAMPION_EXAMPLE_FILE, index=False)
        champion.heldout.to_parquet(folder / paths.CHAMPION_HELDOUT_FILE, index=False)
        joblib.dump(champion.heldout_fits, folder / paths.HELDOUT_FITS_FILE)


@dataclass(frozen=True)
class Outcome:
    """Everything the stage writes, computed before anything is written.

    Attributes
    ----------
    evaluations : list of AxisEvaluation
        One per axis with a model, champion decided.
    scores : DataFrame
        The long score table of every axis.
    summary : DataFrame
        :func:`pipeline.protocol.scoring.candidate_summary` of ``scores``.
    groups : DataFrame
        :func:`pipeline.protocol.scoring.group_scores` of ``scores``.
    champions : dict of str to Champion
        Each axis' champion (:func:`pipeline.protocol.evaluation.champion_of`).
    comparisons : dict of str to AxisComparison
        Each axis' best model against the plain baseline
        (:func:`pipeline.protocol.evaluation.compare_axis`).
    skipped_axes : dict of str to str
        Axis -> why it has no model; named in the report and the metrics.
    """

    evaluations: list[AxisEvaluation]
    scores: pd.DataFrame
    summary: pd.DataFrame
    groups: pd.DataFrame
    champions: dict[str, Champion]
    comparisons: dict[str, AxisComparison]
    skipped_axes: dict[str, str]


def write_tables(outcome: Outcome) -> None:
    """Write scores, summary, metrics, fitted record and champions."""
    for path in (
        paths.SCORES_LONG,
        paths.CROSS_SEASON_METRICS,
        paths.PLOT_MODEL_SCORES,
        paths.COMPARISON_FIGURES / "x",
        paths.CHAMPION / "x",
    ):
        path.parent.mkdir(parents=True, exist_ok=True)
    evaluations, scores = outcome.evaluations, outcome.scores
    outcome.scores.to_csv(paths.SCORES_LONG, index=False, float_format="%.6g")
    ranked = ranked_summary(outcome.summary, [e.decision for e in evaluations])
    ranked.to_csv(paths.CANDIDATE_SCORES, index=False, float_format="%.4f")
    outcome.groups.to_csv(paths.GROUP_SCORES, index=False, float_format="%.4f")
    write_champions(outcome.champions)
    cards = {axis: champion.card for axis, champion in outcome.champions.items()}
    metrics = evaluation_metrics(evaluations, scores, cards, outcome.skipped_axes)
    paths.CROSS_SEASON_METRICS.write_text(json.dumps(metrics, indent=2, sort_keys=True))
    paths.FITTED_MODELS.write_text(json.dumps(fitted_record(evaluations), indent=2, sort_keys=True))


def write_outputs(
    outcome: Outcome,
    table: pd.DataFrame,
    selected: dict,
    separation: dict,
    twin_text: str = "",
) -> None:
    """Write every output declared for the stage in ``dvc.yaml``.

    With no axis at all every output is still written, empty, and the report says why.
    ``twin_text``: the report's paragraph on the twin candidate
    (:func:`pipeline.reporting.comparison.twin_section`).
    """
    write_tables(outcome)
    synthetic = bool(table["synthetic"].any())
    origin = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    heatmaps = write_matrices(outcome.scores, origin)
    parts = [
        report_axis(
            e,
            outcome.comparisons[e.axis],
            outcome.summary,
            outcome.champions[e.axis].card,
            selected,
            separation,
            heatmaps,
            origin,
            twin_text,
        )
        for e in outcome.evaluations
    ]
    sections = [part.section for part in parts]
    sections += [
        f"## Axis {axis}\n\nNo model: {why}.\n" for axis, why in outcome.skipped_axes.items()
    ]
    axes = [e.axis for e in outcome.evaluations]
    paths.MODEL_COMPARISON.write_text(
        comparison_report.render(sections, separation, synthetic, axes)
    )
    plot_rows = [row for part in parts for row in part.plot_rows]
    pd.DataFrame(plot_rows).to_csv(paths.PLOT_MODEL_SCORES, index=False, float_format="%.4f")
    frames = [frame for part in parts for frame in part.predictions]
    predictions = (
        pd.concat(frames, ignore_index=True)
        if frames
        else pd.DataFrame(
            columns=["elapsed_min", "measured_um", "predicted_um", "axis", "campaign_id"]
        )
    )
    predictions.round(4).to_csv(paths.PLOT_PREDICTIONS, index=False)


def read_twin_setup(
    table: pd.DataFrame, series: list[CampaignSeries], separate: SeparateSettings
) -> TwinSetup:
    """Everything the ``twin`` candidate reads besides the separated table (axis Z rows).

    The sensor roles and spindle programs from ``data/validated/spindle/campaigns.parquet``; the
    effects from ``reports/discrepancy/discrepancy.json`` (absent: the baseline twin, with a
    warning); the cold reference from ``separate`` (``params.yaml``: ``cold_reference``,
    ``cold_n``), so that the twin's drift is referenced as the separation stage references the
    measured one.
    """
    meta = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    effects, source = named_effects(read_discrepancy())
    return TwinSetup(
        campaigns=twin_campaigns(table, meta, series),
        effects=effects,
        effects_source=source,
        cold_reference=separate.cold_reference,
        cold_n=separate.cold_n,
    )


def read_discrepancy() -> dict | None:
    """``reports/discrepancy/discrepancy.json``, or None (with a warning) when absent."""
    if not paths.DISCREPANCY_DOCUMENT.is_file():
        LOGGER.warning(
            "%s not found: the twin candidate is the baseline twin", paths.DISCREPANCY_DOCUMENT
        )
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


@summarise_warnings(details=str(paths.MODEL_COMPARISON))
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``evaluate``, ``protocol`` and ``separate`` params sections."""
    parser = argparse.ArgumentParser(prog="thermal evaluate", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_settings(EvaluateSettings, "evaluate")
    check_models(params)
    protocol = load_settings(ProtocolSettings, "protocol")
    separate = load_settings(SeparateSettings, "separate")
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    if not paths.SELECTED.is_file():
        raise MissingInputError(
            f"{paths.SELECTED} not found: run the select stage first (dvc repro select)"
        )
    document = json.loads(paths.SELECTED.read_text())
    features, selected = check_feature_kind(str(document["features"])), document["axes"]
    separation = json.loads(paths.SPINDLE_RUNS.read_text())
    with_twin = split_twin(params.candidates)[1]
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
                twin = read_twin_setup(table[table["axis"] == axis], series, separate)
                twin_source = twin.effects_source
        evaluations.append(
            evaluate_axis(axis, series, selected[axis], params, twin, skipped, protocol)
        )
    scores = all_scores(evaluations)
    summary, groups = candidate_summary(scores), group_scores(scores)
    decide(evaluations, summary, params.champion)
    outcome = Outcome(
        evaluations,
        scores,
        summary,
        groups,
        champions={e.axis: champion_of(e, table, features, separation) for e in evaluations},
        comparisons={e.axis: compare_axis(e, summary, groups) for e in evaluations},
        skipped_axes=skipped_axes,
    )
    twin_text = (
        "" if twin_source is None else comparison_report.twin_section(twin_source, held_back)
    )
    write_outputs(outcome, table, document, separation, twin_text)
    return 0

"""DVC stage ``evaluate``: every candidate of every machine and axis, built on each unit, scored.

Reads ``data/separated/spindle_thermal_error.parquet`` (one block of rows per machine and
displacement axis), ``data/separated/spindle_runs.json`` (runs, references, speed responses) and the
inputs chosen in ``reports/selection/selected.json``. Each machine is evaluated on its own rows
(:mod:`pipeline.machines`): its scores are those of the machine alone. For each machine and axis,
runs each candidate (model x selection, see :mod:`pipeline.protocol.candidates`; ``none``, no
compensation, is one of them; the physical twin ``twin``, see
:mod:`pipeline.protocol.twin_candidate`, which also reads
``data/validated/spindle/campaigns.parquet`` and the machine's
``reports/discrepancy/<machine>/discrepancy.json``, or is skipped with the reason) on each training
unit (:mod:`pipeline.protocol.units`) and scores it on every campaign
(:mod:`pipeline.protocol.cross_season`, :mod:`pipeline.protocol.scoring`), then chooses the axis'
champion on the selection protocol (:mod:`pipeline.protocol.champion`). Writes the long score table,
one row of scores per candidate (a leading ``machine`` column), ``metrics/cross_season.json`` (a DVC
metric, ``{"machines": {machine: ...}}``), the fitted-model record read by ``track`` (the same
nesting), the matrices (CSV, one heat-map per candidate), ``reports/model_comparison.md`` with its
figures, each machine and axis' champion (``data/models/champion/<machine>/<axis>/``) and two DVC
plot tables.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
from dataclasses import dataclass
from functools import partial

import joblib
import pandas as pd

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.fit_cache import StageCache
from pipeline.machines import MACHINE_COLUMN, machine_key, with_machine
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
from pipeline.separation.features import check_feature_kind, separated_by_machine
from pipeline.settings.base import load_settings
from pipeline.settings.evaluate import EvaluateSettings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


def champion_folder(machine: str, axis: str):
    """``data/models/champion/<machine>/<axis>/`` (the machine as :func:`machine_key` writes it)."""
    return paths.CHAMPION / machine_key(machine) / axis


def write_champions(champions: dict[tuple[str, str], Champion]) -> None:
    """Save each machine and axis' champion: estimator, card, input example, held-out fits.

    Folders of machines and axes that no longer have a champion are removed.
    """
    kept = {champion_folder(machine, axis) for machine, axis in champions}
    kept_machines = {folder.parent for folder in kept}
    for machine_folder in paths.CHAMPION.iterdir() if paths.CHAMPION.is_dir() else []:
        if machine_folder not in kept_machines:
            shutil.rmtree(machine_folder)
            continue
        for stale in machine_folder.iterdir():
            if stale not in kept:
                shutil.rmtree(stale)
    for (machine, axis), champion in champions.items():
        folder = champion_folder(machine, axis)
        folder.mkdir(parents=True, exist_ok=True)
        joblib.dump(champion.result.estimator, folder / paths.CHAMPION_ESTIMATOR_FILE)
        card_text = json.dumps(champion.card, indent=2, sort_keys=True) + "\n"
        (folder / paths.CHAMPION_CARD_FILE).write_text(card_text)
        champion.example.to_csv(folder / paths.CHAMPION_EXAMPLE_FILE, index=False)
        champion.heldout.to_parquet(folder / paths.CHAMPION_HELDOUT_FILE, index=False)
        joblib.dump(champion.heldout_fits, folder / paths.HELDOUT_FITS_FILE)


@dataclass(frozen=True)
class Outcome:
    """Everything the stage computed for one machine, before anything is written.

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
    twin_source : str or None
        Where the twin candidate's effects came from (None: the twin was not scored).
    """

    evaluations: list[AxisEvaluation]
    scores: pd.DataFrame
    summary: pd.DataFrame
    groups: pd.DataFrame
    champions: dict[str, Champion]
    comparisons: dict[str, AxisComparison]
    skipped_axes: dict[str, str]
    twin_source: str | None = None


def _combined(outcomes: dict[str, Outcome], table_of) -> pd.DataFrame:
    """Return the machines' ``table_of(outcome)`` side by side, a leading ``machine``."""
    frames = [with_machine(table_of(o), m) for m, o in outcomes.items()]
    frames = [f for f in frames if not f.empty] or frames[:1]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["machine"])


def write_tables(outcomes: dict[str, Outcome]) -> None:
    """Write scores, summary, metrics, fitted record and champions of every machine."""
    for path in (
        paths.SCORES_LONG,
        paths.CROSS_SEASON_METRICS,
        paths.PLOT_MODEL_SCORES,
        paths.COMPARISON_FIGURES / "x",
        paths.CHAMPION / "x",
    ):
        path.parent.mkdir(parents=True, exist_ok=True)
    _combined(outcomes, lambda o: o.scores).to_csv(
        paths.SCORES_LONG, index=False, float_format="%.6g"
    )
    ranked = _combined(
        outcomes, lambda o: ranked_summary(o.summary, [e.decision for e in o.evaluations])
    )
    ranked.to_csv(paths.CANDIDATE_SCORES, index=False, float_format="%.4f")
    groups = _combined(outcomes, lambda o: o.groups)
    groups.to_csv(paths.GROUP_SCORES, index=False, float_format="%.4f")
    write_champions({(m, axis): c for m, o in outcomes.items() for axis, c in o.champions.items()})
    metrics = {
        m: evaluation_metrics(
            o.evaluations,
            o.scores,
            {axis: champion.card for axis, champion in o.champions.items()},
            o.skipped_axes,
        )
        for m, o in outcomes.items()
    }
    text = json.dumps({"machines": metrics}, indent=2, sort_keys=True)
    paths.CROSS_SEASON_METRICS.write_text(text)
    fitted = {m: fitted_record(o.evaluations) for m, o in outcomes.items()}
    paths.FITTED_MODELS.write_text(json.dumps({"machines": fitted}, indent=2, sort_keys=True))


def machine_sections(
    machine: str, outcome: Outcome, document: dict, separation: dict, context: dict
) -> tuple[list[str], list[dict], list[pd.DataFrame]]:
    """One machine's part of the report: its opening, its axes' sections and plot rows.

    ``context``: ``heatmaps``, ``origin`` and ``held_back`` (the twin text's wording).
    """
    twin_text = (
        ""
        if outcome.twin_source is None
        else comparison_report.twin_section(outcome.twin_source, context["held_back"])
    )
    parts = [
        report_axis(
            machine,
            e,
            outcome.comparisons[e.axis],
            outcome.summary,
            outcome.champions[e.axis].card,
            document,
            separation,
            context["heatmaps"],
            context["origin"],
            twin_text,
        )
        for e in outcome.evaluations
    ]
    axes = [e.axis for e in outcome.evaluations]
    sections = [comparison_report.machine_intro(machine, separation, axes)]
    sections += [part.section for part in parts]
    sections += [
        f"## Machine {machine}, axis {axis}\n\nNo model: {why}.\n"
        for axis, why in outcome.skipped_axes.items()
    ]
    plot_rows = [row for part in parts for row in part.plot_rows]
    return sections, plot_rows, [frame for part in parts for frame in part.predictions]


def write_outputs(
    outcomes: dict[str, Outcome],
    table: pd.DataFrame,
    selected: dict,
    separation: dict,
    held_back: bool = True,
) -> None:
    """Write every output declared for the stage in ``dvc.yaml``.

    With no machine or axis at all every output is still written, empty, and the report says
    why. ``held_back``: the discrepancy stage kept the validation campaigns out of its search
    (the twin paragraph's wording, :func:`pipeline.reporting.comparison.twin_section`).
    """
    write_tables(outcomes)
    synthetic = bool(table["synthetic"].any())
    origin = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    scores = _combined(outcomes, lambda o: o.scores)
    context = {
        "heatmaps": write_matrices(scores, origin) if not scores.empty else [],
        "origin": origin,
        "held_back": held_back,
    }
    sections, plot_rows, frames = [], [], []
    for machine, outcome in outcomes.items():
        part = machine_sections(
            machine,
            outcome,
            selected["machines"][machine],
            separation["machines"][machine],
            context,
        )
        sections += part[0]
        plot_rows += part[1]
        frames += part[2]
    paths.MODEL_COMPARISON.write_text(
        comparison_report.render(sections, separation, synthetic, list(outcomes))
    )
    pd.DataFrame(plot_rows).to_csv(paths.PLOT_MODEL_SCORES, index=False, float_format="%.4f")
    predictions = (
        pd.concat(frames, ignore_index=True)
        if frames
        else pd.DataFrame(
            columns=[
                "elapsed_min",
                "measured_um",
                "predicted_um",
                MACHINE_COLUMN,
                "axis",
                "campaign_id",
            ]
        )
    )
    predictions.round(4).to_csv(paths.PLOT_PREDICTIONS, index=False)


@dataclass(frozen=True)
class MachineTwin:
    """What the ``twin`` candidate reads of one machine besides the separated table.

    Attributes
    ----------
    discrepancy : dict or None
        The machine's ``reports/discrepancy/<machine>/discrepancy.json`` (None: absent, the
        baseline twin).
    campaigns : DataFrame
        The machine's rows of ``data/validated/spindle/campaigns.parquet`` (sensor roles,
        spindle programs).
    """

    discrepancy: dict | None
    campaigns: pd.DataFrame

    @property
    def roles(self) -> frozenset[str]:
        """Every sensor role of the machine's valid spindle campaigns."""
        return frozenset(
            str((spec or {}).get("role", "other"))
            for text in self.campaigns["sensors_json"]
            for spec in json.loads(text).values()
        )


def read_twins(machines: list[str]) -> dict[str, MachineTwin]:
    """Read what the ``twin`` candidate needs of each machine, each file once."""
    meta = pd.read_parquet(paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    return {
        machine: MachineTwin(
            read_discrepancy(machine),
            meta.loc[meta[MACHINE_COLUMN].astype(str) == machine].reset_index(drop=True),
        )
        for machine in machines
    }


def read_twin_setup(
    table: pd.DataFrame,
    series: list[CampaignSeries],
    separate: SeparateSettings,
    machine_twin: MachineTwin,
) -> TwinSetup:
    """Everything the ``twin`` candidate is built from (axis Z rows of ``table``).

    The sensor roles and spindle programs of the machine's campaigns and the effects its
    discrepancy document named (None: the baseline twin), from ``machine_twin``; the cold
    reference from ``separate`` (``params.yaml``: ``cold_reference``, ``cold_n``), so that the
    twin's drift is referenced as the separation stage references the measured one.
    """
    effects, source = named_effects(machine_twin.discrepancy)
    return TwinSetup(
        campaigns=twin_campaigns(table, machine_twin.campaigns, series),
        effects=effects,
        effects_source=source,
        cold_reference=separate.cold_reference,
        cold_n=separate.cold_n,
    )


def read_discrepancy(machine: str) -> dict | None:
    """Return the machine's discrepancy document, or None (with a warning) when absent."""
    path = paths.discrepancy_document(machine_key(machine))
    if not path.is_file():
        LOGGER.warning("%s not found: the twin candidate is the baseline twin", path)
        return None
    return json.loads(path.read_text(encoding="utf-8"))


@dataclass(frozen=True)
class StageSettings:
    """The sections the stage reads and the selection document's feature kind."""

    params: EvaluateSettings
    protocol: ProtocolSettings
    separate: SeparateSettings
    features: str


def evaluate_machine(
    machine: str,
    table: pd.DataFrame,
    document: dict,
    separation: dict,
    settings: StageSettings,
    machine_twin: MachineTwin | None = None,
) -> Outcome:
    """Every candidate of every axis of one machine, its champions chosen.

    ``table``, ``document`` and ``separation``: the machine's rows of the separated table, its
    entry of ``selected.json`` and of ``spindle_runs.json``; ``machine_twin``: what the twin
    candidate reads (None: the twin is not a candidate).
    """
    params, features = settings.params, settings.features
    selected = document["axes"]
    LOGGER.info(
        "machine %s: evaluating axes %s on its %d campaigns",
        machine,
        ", ".join(selected) or "none",
        table["campaign_id"].nunique(),
    )
    evaluations, twin_source = [], None
    for axis, series in series_by_axis(table, features).items():
        if axis not in selected:
            continue
        skipped, twin = None, None
        if machine_twin is not None:
            skipped = skip_reason(axis, machine_twin.discrepancy, series, machine_twin.roles)
            if skipped is None:
                rows = table[table["axis"] == axis]
                twin = read_twin_setup(rows, series, settings.separate, machine_twin)
                twin_source = twin.effects_source
        evaluations.append(
            evaluate_axis(axis, series, selected[axis], params, twin, skipped, settings.protocol)
        )
    scores = all_scores(evaluations)
    summary, groups = candidate_summary(scores), group_scores(scores)
    decide(evaluations, summary, params.champion)
    champions = {e.axis: champion_of(e, table, features, separation) for e in evaluations}
    for champion in champions.values():
        champion.card[MACHINE_COLUMN] = machine
    return Outcome(
        evaluations,
        scores,
        summary,
        groups,
        champions=champions,
        comparisons={e.axis: compare_axis(e, summary, groups) for e in evaluations},
        skipped_axes=dict(document.get("skipped_axes") or {}),
        twin_source=twin_source,
    )


def read_inputs() -> tuple[pd.DataFrame, dict, dict]:
    """Read the separated table, ``selected.json`` and ``spindle_runs.json``."""
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    if not paths.SELECTED.is_file():
        raise MissingInputError(
            f"{paths.SELECTED} not found: run the select stage first (dvc repro select)"
        )
    document = json.loads(paths.SELECTED.read_text())
    return table, document, json.loads(paths.SPINDLE_RUNS.read_text())


def cache_parts(
    machine: str,
    rows: pd.DataFrame,
    document: dict,
    separation: dict,
    settings: StageSettings,
    machine_twin: MachineTwin | None,
) -> list[tuple[str, object]]:
    """Everything one machine's evaluation is computed from (:mod:`pipeline.fit_cache`).

    The arguments are :func:`evaluate_machine`'s.
    """
    parts = [
        ("machine", machine),
        ("rows", rows),
        ("selected", document),
        ("features", settings.features),
        ("separation", separation),
        ("evaluate", settings.params),
        ("protocol", settings.protocol),
        ("separate", settings.separate),
    ]
    if machine_twin is not None:
        parts += [
            ("discrepancy", machine_twin.discrepancy),
            ("campaigns", machine_twin.campaigns),
        ]
    return parts


@summarise_warnings(details=str(paths.MODEL_COMPARISON))
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``evaluate``, ``protocol`` and ``separate`` params sections."""
    parser = argparse.ArgumentParser(prog="thermal evaluate", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_settings(EvaluateSettings, "evaluate")
    check_models(params)
    table, document, separation = read_inputs()
    settings = StageSettings(
        params,
        load_settings(ProtocolSettings, "protocol"),
        load_settings(SeparateSettings, "separate"),
        check_feature_kind(str(document["features"])),
    )
    machines = dict(separated_by_machine(table))
    twins = read_twins(list(machines)) if split_twin(params.candidates)[1] else {}
    cache = StageCache("evaluate")
    outcomes = {}
    for machine, rows in machines.items():
        inputs = (
            machine,
            rows,
            document["machines"][machine],
            separation["machines"][machine],
            settings,
            twins.get(machine),
        )
        outcomes[machine] = cache.result(
            machine, cache_parts(*inputs), partial(evaluate_machine, *inputs)
        )
    cache.prune()
    held_back = all(
        twin.discrepancy is None or twin.discrepancy.get("validation") is not None
        for twin in twins.values()
    )
    write_outputs(outcomes, table, document, separation, held_back)
    return 0

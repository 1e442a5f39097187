"""DVC stage ``compensation``: from each axis' champion to what the machine runs, and its proof.

Reads each machine and axis' champion (``data/models/champion/<machine>/<axis>/``: card,
estimator, held-out predictions and fits), the separated thermal error
(``data/separated/spindle_thermal_error.parquet``), the selections made on each training unit
(``reports/selection/selected.json``) and the linear-axis model (``reports/axis_model.json``),
each machine's part on its own. For each machine and axis it writes

- the runtime's bundle (``data/models/compensation/<machine>/<axis>/``,
  :mod:`pipeline.compensation.bundle`): the champion, one fallback per sensor it reads
  (:func:`pipeline.compensation.sensor_budget.fallback_fits`), the range of every input seen in
  training and the input checks of the ``validate`` stage;
- the controller exports (``reports/compensation/<machine>/<axis>/``,
  :mod:`pipeline.compensation.exports`):
  ``coefficients.json`` for models linear in their inputs, ``controller.json`` (the Heidenhain
  ``TEMPCOMP`` formula or why none fits, the SINUMERIK K0 / tan beta / P0 mapping);
- the proof on replay (:mod:`pipeline.compensation.replay`): ``proof.csv``, ``trace.csv`` and
  one figure per held-out campaign;

and, over all machines and axes, ``reports/compensation/compensation.{json,md}`` and
``metrics/compensation.json`` (``{"machines": {machine: ...}}``) and the sensor budget
(``reports/sensor_budget.{csv,png}``, a ``machine`` column).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import shutil
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import joblib
import pandas as pd

from pipeline import paths
from pipeline.compensation.bundle import (
    AxisBundle,
    InputChecks,
    ModelEntry,
    input_ranges,
    write_bundle,
)
from pipeline.compensation.exports import (
    LinearForm,
    coefficients_document,
    linear_form,
    sinumerik_mapping,
    spindle_k0_mapping,
    tempcomp_formula,
)
from pipeline.compensation.replay import AxisProof, proof_figure, replay_axis
from pipeline.compensation.report import render_report, summary_record
from pipeline.compensation.sensor_budget import budget_figure, fallback_fits, sensor_budget
from pipeline.config import DEFAULT_PARAMS
from pipeline.errors import MissingInputError
from pipeline.fit_cache import StageCache
from pipeline.machines import machine_key, with_machine
from pipeline.protocol.units import series_by_axis, training_units
from pipeline.separation.features import InputSpec, separated_by_machine
from pipeline.settings.base import load_settings
from pipeline.settings.compensation import CompensationSettings
from pipeline.settings.evaluate import EvaluateSettings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.select import SelectSettings
from pipeline.settings.validate import ValidateSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="thermal compensation",
        description=(
            "Build each axis' compensation bundle, controller exports, replay proof and "
            "sensor budget from its champion (the DVC stage `compensation`)."
        ),
    )
    parser.add_argument("--params", default=str(DEFAULT_PARAMS), help="params file (params.yaml)")
    return parser.parse_args(argv)


def champion_axes(machine: str) -> list[str]:
    """Axes of the machine with a saved champion, sorted."""
    root = paths.CHAMPION / machine_key(machine)
    if not root.is_dir():
        return []
    return sorted(p.name for p in root.iterdir() if (p / paths.CHAMPION_CARD_FILE).is_file())


def axis_bundle(
    folder: Path, rows: pd.DataFrame, fallbacks: list, checks: InputChecks
) -> AxisBundle:
    """Return the runtime's bundle of an axis: champion, fallbacks, training ranges, checks.

    ``folder``: the axis' champion (``data/models/champion/<machine>/<axis>/``).
    """
    axis = folder.name
    card = json.loads((folder / paths.CHAMPION_CARD_FILE).read_text(encoding="utf-8"))
    spec = InputSpec.from_dict(card["input_spec"])
    protocol_score = (card.get("scores") or {}).get(f"{card.get('protocol')}_Mn_rms_um")
    champion = ModelEntry(
        "champion", spec, joblib.load(folder / paths.CHAMPION_ESTIMATOR_FILE), protocol_score
    )
    entries = tuple(
        ModelEntry(
            f"without_{item.lost}",
            replace(spec, inputs=tuple(item.inputs)),
            item.estimator,
            item.heldout_rms_um,
        )
        for item in fallbacks
        if item.estimator is not None
    )
    training = rows[rows["campaign_id"].isin(card.get("trained_on") or [])]
    specs = [champion.spec, *(e.spec for e in entries)]
    return AxisBundle(axis, card, champion, entries, input_ranges(training, specs), checks)


def fallback_record(item) -> dict:
    """Return a fallback's entry of the stage's record (no estimator)."""
    return {
        "lost": item.lost,
        "inputs": list(item.inputs),
        "heldout_rms_um": item.heldout_rms_um,
        "champion_rms_um": item.champion_rms_um,
        "none_rms_um": item.none_rms_um,
        "n_campaigns": item.n_campaigns,
        "inputs_rule": item.inputs_rule,
        "note": item.note,
    }


def controller_document(
    bundle: AxisBundle, form: LinearForm | str, axis_model: dict | None, offset_sign: int
) -> dict:
    """Return what each controller takes for a spindle axis (``controller.json``)."""
    spec = bundle.champion.spec
    if isinstance(form, LinearForm):
        formula, reason = tempcomp_formula(form, spec, training_ranges=bundle.input_ranges)
    else:
        formula, reason = None, form
    return {
        "axis": bundle.axis,
        "runtime_offset": (
            "thermal compensate writes the offset (um) cyclically: SINUMERIK SD43900 (K0), "
            "a FANUC PMC offset, Heidenhain PLC module 9231 or LinuxCNC axis.L.eoffset"
        ),
        "heidenhain_tempcomp": {"formula": formula, "reason": reason},
        "sinumerik_spindle": spindle_k0_mapping(bundle.axis, offset_sign),
        "sinumerik_linear_axis": sinumerik_mapping(axis_model or {}, bundle.axis),
    }


def write_linear_axes(machine: str, axis_model: dict | None) -> dict:
    """Write the SINUMERIK mapping of each laser-measured linear axis; return them by axis."""
    mappings = {}
    for axis in (axis_model or {}).get("axis") or []:
        mapping = sinumerik_mapping(axis_model, str(axis))
        if mapping is None:
            continue
        out = paths.COMPENSATION_REPORTS / machine_key(machine) / f"linear_{axis}"
        out.mkdir(parents=True, exist_ok=True)
        (out / "sinumerik.json").write_text(json.dumps(mapping, indent=2) + "\n")
        mappings[str(axis)] = mapping
    return mappings


def write_axis(
    machine: str,
    bundle: AxisBundle,
    proof: AxisProof,
    axis_model: dict | None,
    settings: CompensationSettings,
) -> dict:
    """Write an axis' bundle, exports, proof table, traces and figures; return its record."""
    axis = bundle.axis
    write_bundle(paths.COMPENSATION_BUNDLES / machine_key(machine) / axis, bundle)
    out = paths.COMPENSATION_REPORTS / machine_key(machine) / axis
    out.mkdir(parents=True)
    form = linear_form(bundle.champion.estimator, bundle.champion.spec)
    coefficients = coefficients_document(
        form, bundle.champion.spec, bundle.input_ranges, bundle.card
    )
    (out / "coefficients.json").write_text(json.dumps(coefficients, indent=2) + "\n")
    controller = controller_document(bundle, form, axis_model, settings.offset_sign)
    (out / "controller.json").write_text(json.dumps(controller, indent=2) + "\n")
    proof.table.to_csv(out / "proof.csv", index=False, float_format="%.4f")
    proof.traces.to_csv(out / "trace.csv", index=False, float_format="%.4f")
    for campaign_id, part in proof.traces.groupby("campaign_id", sort=True):
        proof_figure(axis, part, out / f"replay_{campaign_id}.png")
    return summary_record(bundle, proof, coefficients, controller)


@dataclass(frozen=True)
class AxisWork:
    """One axis' inputs to the stage: its machine, series, training units, rows and selections."""

    machine: str
    axis: str
    series: list
    units: list
    rows: pd.DataFrame
    selected: dict


def compensate_axis(
    work: AxisWork,
    checks: InputChecks,
    settings: CompensationSettings,
    axis_model: dict | None,
    model_params: dict,
    n_jobs: int,
) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """Build, write and prove one axis' compensation; return its record, proof and budget."""
    folder = paths.CHAMPION / machine_key(work.machine) / work.axis
    card = json.loads((folder / paths.CHAMPION_CARD_FILE).read_text(encoding="utf-8"))
    scheme = card.get("protocol")
    fallbacks = fallback_fits(
        work.series, work.units, card, model_params, scheme, work.selected, n_jobs=n_jobs
    )
    bundle = axis_bundle(folder, work.rows, fallbacks, checks)
    fits = joblib.load(folder / paths.HELDOUT_FITS_FILE)
    heldout = pd.read_parquet(folder / paths.CHAMPION_HELDOUT_FILE)
    proof = replay_axis(bundle, work.rows, fits, heldout, settings)
    record = write_axis(work.machine, bundle, proof, axis_model, settings)
    record["fallbacks"] = [fallback_record(item) for item in fallbacks]
    budget = sensor_budget(
        work.series, work.units, card, model_params, scheme, work.selected, n_jobs=n_jobs
    )
    return record, proof.table, budget


@dataclass(frozen=True)
class StageSettings:
    """What every machine's compensation is built with."""

    settings: CompensationSettings
    checks: InputChecks
    protocol: ProtocolSettings
    features: str
    model_params: dict
    n_jobs: int


def compensate_machine(
    machine: str, table: pd.DataFrame, selected: dict, axis_model: dict | None, stage: StageSettings
) -> tuple[dict, pd.DataFrame, dict[str, pd.DataFrame]]:
    """Build, write and prove the compensation of every axis of one machine.

    Returns
    -------
    record : dict
        ``{"axes": {axis: record}, "linear_axes": {axis: SINUMERIK mapping}}``.
    budget : DataFrame
        The machine's sensor budget, a leading ``machine`` column.
    tables : dict of str to DataFrame
        Axis -> its replay proof table.
    """
    series = series_by_axis(table, stage.features)
    records, budgets, tables = {}, [], {}
    for axis in champion_axes(machine):
        units = training_units(series[axis], stage.protocol)
        rows = table[table["axis"] == axis]
        work = AxisWork(machine, axis, series[axis], units, rows, selected)
        records[axis], tables[axis], budget = compensate_axis(
            work, stage.checks, stage.settings, axis_model, stage.model_params, stage.n_jobs
        )
        budgets.append(with_machine(budget, machine))
        LOGGER.info("machine %s, axis %s: %s", machine, axis, records[axis]["headline"])
    linear = write_linear_axes(machine, axis_model)
    budget = pd.concat(budgets, ignore_index=True) if budgets else pd.DataFrame()
    return {"axes": records, "linear_axes": linear}, budget, tables


CHAMPION_KEY_FILES = (paths.CHAMPION_CARD_FILE, paths.CHAMPION_HELDOUT_FILE)
"""What a champion is known by in the cache key: its card (model, inputs, scores, training
campaigns) and its held-out predictions. Its pickled fits are not byte-stable: the same fit
loaded from the cache and saved again may be pickled differently."""


def champion_digests(folder: Path) -> dict[str, str]:
    """Return the SHA-256 of each axis' :data:`CHAMPION_KEY_FILES` under ``folder``."""
    return {
        path.relative_to(folder).as_posix(): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file() and path.name in CHAMPION_KEY_FILES
    }


def read_inputs() -> tuple[pd.DataFrame, dict, dict]:
    """Read the separated table, the selections and the axis models, by machine."""
    if not paths.SPINDLE_THERMAL_ERROR.is_file():
        raise MissingInputError(
            f"{paths.SPINDLE_THERMAL_ERROR} not found; run `dvc repro separate_spindle` first"
        )
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    selected = json.loads(paths.SELECTED.read_text(encoding="utf-8")).get("machines", {})
    axis_models = (
        json.loads(paths.AXIS_MODEL_REPORT.read_text(encoding="utf-8")).get("machines", {})
        if paths.AXIS_MODEL_REPORT.is_file()
        else {}
    )
    return table, selected, axis_models


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage; return 0."""
    args = _parse_args(argv)
    settings = load_settings(CompensationSettings, "compensation", args.params)
    limits = load_settings(ValidateSettings, "validate", args.params).limits()
    evaluate = load_settings(EvaluateSettings, "evaluate", args.params)
    stage = StageSettings(
        settings,
        InputChecks.from_limits(limits, settings.range_margin_degC),
        load_settings(ProtocolSettings, "protocol", args.params),
        load_settings(SelectSettings, "select", args.params).features,
        evaluate.model_params,
        evaluate.n_jobs,
    )
    table, selected, axis_models = read_inputs()
    for stale in (paths.COMPENSATION_REPORTS, paths.COMPENSATION_BUNDLES):
        if stale.is_dir():
            shutil.rmtree(stale)
    paths.COMPENSATION_REPORTS.mkdir(parents=True)
    machines, budgets, tables = {}, [], {}
    rows_of = dict(separated_by_machine(table))
    cache = StageCache("compensation")
    for machine in sorted(set(rows_of) | set(axis_models)):
        rows = rows_of.get(machine, table[:0])
        own = (selected.get(machine) or {}).get("axes", {})
        champions = paths.CHAMPION / machine_key(machine)
        parts = [
            ("rows", rows),
            ("selected", own),
            ("axis_model", axis_models.get(machine)),
            ("settings", stage),
            ("champions", champion_digests(champions)),
        ]
        machines[machine], budget, tables[machine] = cache.result_with_files(
            machine,
            parts,
            partial(compensate_machine, machine, rows, own, axis_models.get(machine), stage),
            [
                folder / machine_key(machine)
                for folder in (paths.COMPENSATION_BUNDLES, paths.COMPENSATION_REPORTS)
            ],
        )
        budgets.append(budget)
    cache.prune()
    budget = pd.concat(budgets, ignore_index=True) if budgets else pd.DataFrame()
    paths.METRICS.mkdir(parents=True, exist_ok=True)
    budget.to_csv(paths.SENSOR_BUDGET, index=False, float_format="%.4f")
    budget_figure(budget, paths.SENSOR_BUDGET_PLOT)
    document = {"settings": settings.model_dump(), "machines": machines}
    paths.COMPENSATION_SUMMARY.write_text(json.dumps(document, indent=2, default=str) + "\n")
    paths.COMPENSATION_REPORT.write_text(render_report(document, budget, tables))
    metrics = {
        machine: {axis: record["proof"] for axis, record in entry["axes"].items()}
        for machine, entry in machines.items()
    }
    text = json.dumps({"machines": metrics}, indent=2, sort_keys=True) + "\n"
    paths.COMPENSATION_METRICS.write_text(text)
    return 0

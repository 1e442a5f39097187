"""DVC stage ``select``: the sensitive inputs of every axis and training unit, by every method.

Reads ``data/separated/spindle_thermal_error.parquet``. For each displacement axis, each
selection method of ``params.yaml`` ``select.methods`` (registry :mod:`pipeline.selection`)
and each training unit (each training campaign, each season or campaign left out, all training
campaigns; see :mod:`pipeline.training_units`) it chooses the inputs from the training data
only. The inputs offered are the temperature sensors and, where the campaigns have a spindle
speed, the speed responses (:mod:`pipeline.features`); an entry's ``inputs:`` restricts a
method to the temperatures (``temperatures``), and ``method:`` lets one registry method appear
under two names (``all_speed: {method: all, inputs: temperatures_and_speed}``). Writes

- ``reports/selection/selected.json``: ``{"features": ..., "axes": {axis: {method: {unit:
  {"inputs": [...], "details": {...}}}}}}``, the input of ``evaluate``;
- ``reports/selection/<method>_evidence.csv``: the numbers each choice was made on, one block
  per axis and unit (leading columns ``axis``, ``unit``);
- ``reports/selection/stability.csv`` and ``stability_<axis>.png``: how often each input is
  chosen across the training campaigns, per method and axis (the PCDL paper's table 3:
  sensitive points vary from batch to batch).
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Mapping

import pandas as pd

from pipeline import paths, plots
from pipeline.config import load_section
from pipeline.features import check_feature_kind, is_speed_feature
from pipeline.selection import Selection, make_selector
from pipeline.training_units import (
    CampaignSeries,
    TrainingUnit,
    series_by_axis,
    stack,
    training_units,
)

LOGGER = logging.getLogger(__name__)

INPUT_SETS = ("temperatures", "temperatures_and_speed")
STABILITY_COLUMNS = ["method", "sensor", "times_chosen", "n_campaigns", "frequency"]


def method_entries(methods: Mapping[str, Mapping | None]) -> dict[str, tuple[str, str, dict]]:
    """Parse ``select.methods``: name -> (registry method, input set, its parameters).

    Raises
    ------
    ValueError
        If an entry's ``inputs`` is not one of :data:`INPUT_SETS`.
    """
    entries = {}
    for name, settings in methods.items():
        settings = dict(settings or {})
        method = str(settings.pop("method", name))
        inputs = str(settings.pop("inputs", "temperatures_and_speed"))
        if inputs not in INPUT_SETS:
            raise ValueError(
                f"params.yaml select.methods.{name}.inputs is '{inputs}'; use one of "
                f"{list(INPUT_SETS)}"
            )
        entries[str(name)] = (method, inputs, settings)
    return entries


def select_unit(
    entry: tuple[str, str, dict], unit: TrainingUnit, series: list[CampaignSeries]
) -> Selection:
    """Run one selection method on the campaigns of one training unit.

    Only inputs with readings in every campaign of the unit are candidates; with the input set
    ``temperatures``, the speed responses are not offered. When the unit's campaigns share no
    input (a sensor renamed, the only common one dead), the selection is empty and says why;
    the models fed by it are not fitted on that unit.
    """
    method, inputs, settings = entry
    training = [s for s in series if s.campaign_id in unit.campaigns]
    offered = [
        column
        for column in training[0].features.columns
        if all(s.features[column].notna().any() for s in training)
        and (inputs == "temperatures_and_speed" or not is_speed_feature(column))
    ]
    if not offered:
        reason = f"no input has readings in every campaign of {unit.name}"
        LOGGER.warning("%s: %s; nothing selected", method, reason)
        return Selection(method, [], pd.DataFrame(columns=["sensor"]), {"empty": reason})
    temperatures, error = stack(training, offered)
    return make_selector(method, **settings)(temperatures, error)


def select_axis(
    series: list[CampaignSeries], units: list[TrainingUnit], entries: dict
) -> dict[str, dict[str, Selection]]:
    """Every method on every training unit of one axis: ``{method: {unit name: Selection}}``."""
    return {
        name: {unit.name: select_unit(entry, unit, series) for unit in units}
        for name, entry in entries.items()
    }


def stability_table(
    selections: dict[str, dict[str, Selection]], units: list[TrainingUnit], inputs: list[str]
) -> pd.DataFrame:
    """How often each input is chosen across the training campaigns, per method.

    Parameters
    ----------
    selections : dict
        ``{method: {unit: Selection}}`` of one axis.
    units : list of TrainingUnit
        The campaign-scheme units are counted.
    inputs : list of str
        Every input; one row each per method, chosen or not.

    Returns
    -------
    DataFrame
        ``method``, ``sensor``, ``times_chosen``, ``n_campaigns``, ``frequency`` (0-1); one row
        per method and input.
    """
    campaigns = [unit.name for unit in units if unit.scheme == "campaign"]
    rows = []
    for method, by_unit in selections.items():
        counts: dict[str, int] = {}
        for name in campaigns:
            for sensor in by_unit[name].sensors:
                counts[sensor] = counts.get(sensor, 0) + 1
        for sensor in inputs:
            chosen = counts.get(sensor, 0)
            rows.append({
                "method": method, "sensor": sensor, "times_chosen": chosen,
                "n_campaigns": len(campaigns), "frequency": chosen / max(len(campaigns), 1),
            })  # fmt: skip
    return pd.DataFrame(rows)


def selected_record(
    features: str,
    selections: dict[str, dict[str, dict[str, Selection]]],
    skipped: dict[str, str] | None = None,
) -> dict:
    """JSON-ready record of the choices: inputs and decision details per axis, method and unit.

    ``skipped``: axis -> why nothing was selected on it (no training campaign).
    """
    return {
        "features": features,
        "skipped_axes": dict(skipped or {}),
        "axes": {
            axis: {
                method: {
                    unit: {"inputs": list(sel.sensors), "details": _plain(sel.details)}
                    for unit, sel in by_unit.items()
                }
                for method, by_unit in by_method.items()
            }
            for axis, by_method in selections.items()
        },
    }


def _plain(details: dict) -> dict:
    return {str(k): (v.item() if hasattr(v, "item") else v) for k, v in details.items()}


def write_outputs(
    features: str,
    selections: dict[str, dict[str, dict[str, Selection]]],
    units: dict[str, list[TrainingUnit]],
    inputs: dict[str, list[str]],
    synthetic: bool,
    skipped: dict[str, str] | None = None,
) -> None:
    """Write every output declared for the stage in ``dvc.yaml``."""
    paths.SELECTION.mkdir(parents=True, exist_ok=True)
    for stale in [*paths.SELECTION.glob("*_evidence.csv"), *paths.SELECTION.glob("*.png")]:
        stale.unlink()
    record = selected_record(features, selections, skipped)
    paths.SELECTED.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")
    methods = list(next(iter(selections.values()))) if selections else []
    for method in methods:
        evidence = pd.concat(
            [
                sel.evidence.assign(axis=axis, unit=unit)
                for axis, by_method in selections.items()
                for unit, sel in by_method[method].items()
            ],
            ignore_index=True,
        )
        first = ["axis", "unit"]
        evidence = evidence[[*first, *[c for c in evidence.columns if c not in first]]]
        evidence.to_csv(paths.SELECTION / f"{method}_evidence.csv", index=False,
                        float_format="%.6g")  # fmt: skip
    label = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    tables = [pd.DataFrame(columns=["axis", *STABILITY_COLUMNS])]
    for axis, by_method in selections.items():
        stability = stability_table(by_method, units[axis], inputs[axis]).assign(axis=axis)
        tables.append(stability)
        plots.selection_stability(
            stability,
            f"Axis {axis}: how often each input is chosen, across the training campaigns ({label})",
            paths.SELECTION / f"stability_{axis}.png",
        )
    stability = pd.concat(tables, ignore_index=True)[["axis", *STABILITY_COLUMNS]]
    stability.to_csv(paths.SELECTION_STABILITY, index=False, float_format="%.4f")


def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``select`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal select", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("select")
    features = check_feature_kind(str(params.get("features", "temperature_rise")))
    entries = method_entries(params["methods"])
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    selections, units, inputs, skipped = {}, {}, {}, {}
    for axis, series in series_by_axis(table, features).items():
        if not any(s.split == "train" for s in series):
            skipped[axis] = (
                f"no training campaign measured axis {axis} (only "
                f"{', '.join(s.campaign_id for s in series)}, split validation)"
            )
            LOGGER.warning("axis %s: %s; nothing selected", axis, skipped[axis])
            continue
        units[axis] = training_units(series)
        inputs[axis] = list(series[0].features.columns)
        selections[axis] = select_axis(series, units[axis], entries)
        for method, by_unit in selections[axis].items():
            LOGGER.info(
                "axis %s, %s: all training campaigns -> %s", axis, method,
                ", ".join(by_unit["all_training"].sensors),
            )  # fmt: skip
    if table.empty:
        LOGGER.warning("no spindle thermal error to select inputs for (see %s)", paths.SPINDLE_RUNS)
    write_outputs(features, selections, units, inputs, bool(table["synthetic"].any()), skipped)
    return 0

"""DVC stage ``select``: the sensitive inputs of every axis and training unit, by every method.

Reads ``data/separated/spindle_thermal_error.parquet``. For each displacement axis, each
selection method of ``params.yaml`` ``select.methods`` (registry :mod:`pipeline.selection`)
and each training unit (each training campaign, each season or campaign left out, all training
campaigns; see :mod:`pipeline.protocol.units`) it chooses the inputs from the training data
only. The inputs offered are the temperature sensors and, where the campaigns have a spindle
speed, the speed responses (:mod:`pipeline.separation.features`); an entry's ``inputs:`` restricts a
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

import pandas as pd

from pipeline import paths, plots
from pipeline.protocol.selection_runs import (
    STABILITY_COLUMNS,
    method_entries,
    select_axis,
    selected_record,
    stability_table,
)
from pipeline.protocol.units import (
    TrainingUnit,
    series_by_axis,
    training_units,
)
from pipeline.selection import Selection
from pipeline.settings.base import load_settings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.select import SelectSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


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
        evidence.to_csv(
            paths.SELECTION / f"{method}_evidence.csv", index=False, float_format="%.6g"
        )
    label = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    tables = [pd.DataFrame(columns=["axis", *STABILITY_COLUMNS])]
    for axis, by_method in selections.items():
        stability = stability_table(by_method, units[axis], inputs[axis]).assign(axis=axis)
        tables.append(stability)
        title = f"Axis {axis}: how often each input is chosen, across the training campaigns"
        figure = plots.selection_stability_figure(stability, f"{title} ({label})")
        plots.save_figure(figure, paths.SELECTION / f"stability_{axis}.png")
    stability = pd.concat(tables, ignore_index=True)[["axis", *STABILITY_COLUMNS]]
    stability.to_csv(paths.SELECTION_STABILITY, index=False, float_format="%.4f")


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``select`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal select", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    settings = load_settings(SelectSettings, "select")
    features = settings.features
    entries = method_entries(settings.methods)
    protocol = load_settings(ProtocolSettings, "protocol")
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
        units[axis] = training_units(series, protocol)
        inputs[axis] = list(series[0].features.columns)
        selections[axis] = select_axis(series, units[axis], entries)
        for method, by_unit in selections[axis].items():
            LOGGER.info(
                "axis %s, %s: all training campaigns -> %s",
                axis,
                method,
                ", ".join(by_unit["all_training"].sensors),
            )
    if table.empty:
        LOGGER.warning("no spindle thermal error to select inputs for (see %s)", paths.SPINDLE_RUNS)
    write_outputs(features, selections, units, inputs, bool(table["synthetic"].any()), skipped)
    return 0

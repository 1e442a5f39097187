"""DVC stage ``select``: the sensitive inputs of every axis and training unit, by every method.

Reads ``data/separated/spindle_thermal_error.parquet``. For each machine on its own
(:mod:`pipeline.machines`), each displacement axis, each
selection method of ``params.yaml`` ``select.methods`` (registry :mod:`pipeline.selection`)
and each training unit (each training campaign, each season or campaign left out, all training
campaigns; see :mod:`pipeline.protocol.units`) it chooses the inputs from the training data
only. The inputs offered are the temperature sensors and, where the campaigns have a spindle
speed, the speed responses (:mod:`pipeline.separation.features`); an entry's ``inputs:`` restricts a
method to the temperatures (``temperatures``), and ``method:`` lets one registry method appear
under two names (``all_speed: {method: all, inputs: temperatures_and_speed}``). Writes

- ``reports/selection/selected.json``: ``{"features": ..., "machines": {machine: {"axes":
  {axis: {method: {unit: {"inputs": [...], "details": {...}}}}}, "skipped_axes": {...}}}}``,
  the input of ``evaluate``;
- ``reports/selection/<method>_evidence.csv``: the numbers each choice was made on, one block
  per machine, axis and unit (leading columns ``machine``, ``axis``, ``unit``);
- ``reports/selection/stability.csv`` and ``stability_<machine>_<axis>.png``: how often each
  input is chosen across the training campaigns, per method, machine and axis (the PCDL paper's
  table 3: sensitive points vary from batch to batch).
"""

from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass, field
from functools import partial

import pandas as pd

from pipeline import paths, plots
from pipeline.fit_cache import StageCache
from pipeline.machines import MACHINE_COLUMN, axis_label
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
from pipeline.separation.features import separated_by_machine
from pipeline.settings.base import load_settings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.select import SelectSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


@dataclass
class MachineSelections:
    """One machine's selections and what they were made on, by axis.

    Attributes
    ----------
    selections : dict
        axis -> method -> unit -> Selection.
    units : dict
        axis -> its training units.
    inputs : dict
        axis -> the inputs offered.
    skipped : dict
        axis -> why nothing was selected on it.
    """

    selections: dict[str, dict[str, dict[str, Selection]]] = field(default_factory=dict)
    units: dict[str, list[TrainingUnit]] = field(default_factory=dict)
    inputs: dict[str, list[str]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)


def write_evidence(machines: dict[str, MachineSelections]) -> None:
    """``<method>_evidence.csv``: one block per machine, axis and unit."""
    methods = dict.fromkeys(
        method
        for chosen in machines.values()
        for by_method in chosen.selections.values()
        for method in by_method
    )
    first = [MACHINE_COLUMN, "axis", "unit"]
    for method in methods:
        evidence = pd.concat(
            [
                sel.evidence.assign(machine=machine, axis=axis, unit=unit)
                for machine, chosen in machines.items()
                for axis, by_method in chosen.selections.items()
                for unit, sel in by_method[method].items()
            ],
            ignore_index=True,
        )
        evidence = evidence[[*first, *[c for c in evidence.columns if c not in first]]]
        evidence.to_csv(
            paths.SELECTION / f"{method}_evidence.csv", index=False, float_format="%.6g"
        )


def write_outputs(features: str, machines: dict[str, MachineSelections], synthetic: bool) -> None:
    """Write every output declared for the stage in ``dvc.yaml``."""
    paths.SELECTION.mkdir(parents=True, exist_ok=True)
    for stale in [*paths.SELECTION.glob("*_evidence.csv"), *paths.SELECTION.glob("*.png")]:
        stale.unlink()
    record = {
        "features": features,
        "machines": {
            machine: selected_record(features, chosen.selections, chosen.skipped)
            for machine, chosen in machines.items()
        },
    }
    for by_machine_record in record["machines"].values():
        del by_machine_record["features"]
    paths.SELECTED.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")
    write_evidence(machines)
    label = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    first = [MACHINE_COLUMN, "axis"]
    tables = [pd.DataFrame(columns=[*first, *STABILITY_COLUMNS])]
    for machine, chosen in machines.items():
        for axis, by_method in chosen.selections.items():
            stability = stability_table(by_method, chosen.units[axis], chosen.inputs[axis])
            tables.append(stability.assign(machine=machine, axis=axis))
            title = (
                f"Machine {machine}, axis {axis}: how often each input is chosen, across the "
                "training campaigns"
            )
            figure = plots.selection_stability_figure(stability, f"{title} ({label})")
            name = f"stability_{axis_label(machine, axis)}.png"
            plots.save_figure(figure, paths.SELECTION / name)
    stability = pd.concat(tables, ignore_index=True)[[*first, *STABILITY_COLUMNS]]
    stability.to_csv(paths.SELECTION_STABILITY, index=False, float_format="%.4f")


def select_machine(
    machine: str, table: pd.DataFrame, features: str, entries: dict, protocol: ProtocolSettings
) -> MachineSelections:
    """Every method's choice on every training unit of each axis of one machine's table."""
    chosen = MachineSelections()
    for axis, series in series_by_axis(table, features).items():
        if not any(s.split == "train" for s in series):
            chosen.skipped[axis] = (
                f"no training campaign measured axis {axis} (only "
                f"{', '.join(s.campaign_id for s in series)}, split validation)"
            )
            LOGGER.warning(
                "machine %s, axis %s: %s; nothing selected", machine, axis, chosen.skipped[axis]
            )
            continue
        chosen.units[axis] = training_units(series, protocol)
        chosen.inputs[axis] = list(series[0].features.columns)
        chosen.selections[axis] = select_axis(series, chosen.units[axis], entries)
        for method, by_unit in chosen.selections[axis].items():
            LOGGER.info(
                "machine %s, axis %s, %s: all training campaigns -> %s",
                machine,
                axis,
                method,
                ", ".join(by_unit["all_training"].sensors),
            )
    return chosen


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
    cache = StageCache("select")
    machines = {
        machine: cache.result(
            machine,
            [("rows", rows), ("features", features), ("methods", entries), ("protocol", protocol)],
            partial(select_machine, machine, rows, features, entries, protocol),
        )
        for machine, rows in separated_by_machine(table)
    }
    cache.prune()
    if table.empty:
        LOGGER.warning("no spindle thermal error to select inputs for (see %s)", paths.SPINDLE_RUNS)
    write_outputs(features, machines, bool(table["synthetic"].any()))
    return 0

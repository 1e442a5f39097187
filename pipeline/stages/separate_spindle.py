"""DVC stage ``separate_spindle``: the thermal error of every spindle campaign, machine by machine.

``thermal separate-spindle`` reads ``data/validated/spindle/`` and, for each machine alone
(:mod:`pipeline.machines`: its campaigns, its sensors, its runs), separates the thermal error
with :func:`pipeline.separation.spindle.spindle_thermal_error`. Writes
``data/separated/spindle_thermal_error.parquet`` (one block of rows per machine and displacement
axis, a leading ``machine`` column; each machine's sensor columns, empty on the other machines'
rows) and ``data/separated/spindle_runs.json`` (``{"machines": {machine: runs, references,
speed responses}}``; with no spindle campaign at all, ``"note"`` says why). Parameters:
``params.yaml`` section ``separate``. A stage of its own, so that a new spindle campaign does
not rerun the axis separation.
"""

from __future__ import annotations

import argparse
import json
import logging

import pandas as pd

from pipeline import paths
from pipeline.machines import MACHINE_COLUMN, by_machine, machines_of, tag_rows, with_machine
from pipeline.separation.spindle import (
    SeparationSettings,
    empty_table,
    spindle_thermal_error,
)
from pipeline.settings.base import load_settings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings
from schemas import SpindleThermalErrorModel
from schemas.vocabulary import SAMPLE_BASE_COLUMNS

LOGGER = logging.getLogger(__name__)


def separate_machines(
    campaigns: pd.DataFrame, samples: pd.DataFrame, settings: SeparationSettings
) -> tuple[pd.DataFrame, dict]:
    """Each machine's thermal error on its own, side by side.

    Parameters
    ----------
    campaigns, samples : DataFrame
        ``data/validated/spindle/{campaigns,samples}.parquet`` (``machine`` resolved).
    settings : SeparationSettings

    Returns
    -------
    table : DataFrame
        The machines' tables of :func:`spindle_thermal_error` with a leading ``machine``.
    record : dict
        ``{"machines": {machine: record}}``; ``"note"`` when no machine has a thermal error.
    """
    tagged = tag_rows(samples, campaigns)
    tables, records = [with_machine(empty_table(), "")], {}
    for machine, rows in by_machine(tagged, SAMPLE_BASE_COLUMNS):
        own = campaigns.loc[campaigns[MACHINE_COLUMN] == machine].reset_index(drop=True)
        table, records[machine] = spindle_thermal_error(
            own, rows.drop(columns=MACHINE_COLUMN), settings
        )
        tables.append(with_machine(table, machine))
    document: dict = {"machines": records}
    notes = [r["note"] for r in records.values() if "note" in r]
    if len(notes) == len(records):
        document["note"] = (
            notes[0] if notes else spindle_thermal_error(campaigns, samples, settings)[1]["note"]
        )
    frames = [t for t in tables if not t.empty] or tables[:1]
    return pd.concat(frames, ignore_index=True), document


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``separate`` section of params.yaml; return 0."""
    argparse.ArgumentParser(
        prog="thermal separate-spindle", description=__doc__.splitlines()[0]
    ).parse_args(argv)
    settings = SeparationSettings.from_settings(load_settings(SeparateSettings, "separate"))
    folder = paths.VALIDATED_SPINDLE
    table, record = separate_machines(
        pd.read_parquet(folder / paths.CAMPAIGNS_FILE),
        pd.read_parquet(folder / paths.SAMPLES_FILE),
        settings,
    )
    SpindleThermalErrorModel.validate(table, lazy=True)
    paths.SEPARATED.mkdir(parents=True, exist_ok=True)
    table.to_parquet(paths.SPINDLE_THERMAL_ERROR, index=False)
    paths.SPINDLE_RUNS.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")
    if "note" in record:
        LOGGER.warning("%s; the model stages will say so and go on", record["note"])
    for (machine, axis), rows in table.groupby([MACHINE_COLUMN, "axis"], sort=True):
        LOGGER.info(
            "machine %s, axis %s: thermal error of %d spindle campaigns in %d runs: "
            "%.1f to %.1f um",
            machine,
            axis,
            rows["campaign_id"].nunique(),
            rows["run_id"].nunique(),
            rows["thermal_error_um"].min(),
            rows["thermal_error_um"].max(),
        )
    for machine in machines_of(table):
        campaigns = record["machines"][machine]["campaigns"]
        warm = [c for c, info in campaigns.items() if info["warm_start"]]
        if warm:
            LOGGER.info(
                "machine %s: warm starts (error counted from their run's reference): %s",
                machine,
                ", ".join(warm),
            )
    return 0

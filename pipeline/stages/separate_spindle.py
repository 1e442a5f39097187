"""DVC stage ``separate_spindle``: the thermal error of every spindle campaign.

``thermal separate-spindle`` reads ``data/validated/spindle/`` and writes
``data/separated/spindle_thermal_error.parquet`` (one block of rows per displacement axis) and
``data/separated/spindle_runs.json`` (runs, references, speed responses) with
:func:`pipeline.separation.spindle.spindle_thermal_error`. Parameters: ``params.yaml`` section
``separate``. A stage of its own, so that a new spindle campaign does not rerun the axis
separation.
"""

from __future__ import annotations

import argparse
import json
import logging

import pandas as pd

from pipeline import paths
from pipeline.separation.spindle import SeparationSettings, spindle_thermal_error
from pipeline.settings.base import load_settings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings
from schemas import SpindleThermalErrorModel

LOGGER = logging.getLogger(__name__)


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``separate`` section of params.yaml; return 0."""
    argparse.ArgumentParser(
        prog="thermal separate-spindle", description=__doc__.splitlines()[0]
    ).parse_args(argv)
    settings = SeparationSettings.from_settings(load_settings(SeparateSettings, "separate"))
    folder = paths.VALIDATED_SPINDLE
    table, record = spindle_thermal_error(
        pd.read_parquet(folder / paths.CAMPAIGNS_FILE),
        pd.read_parquet(folder / paths.SAMPLES_FILE),
        settings,
    )
    SpindleThermalErrorModel.validate(table, lazy=True)
    paths.SEPARATED.mkdir(parents=True, exist_ok=True)
    table.to_parquet(paths.SPINDLE_THERMAL_ERROR, index=False)
    paths.SPINDLE_RUNS.write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")
    if table.empty:
        LOGGER.warning("%s; the model stages will say so and go on", record["note"])
    for axis, rows in table.groupby("axis", sort=False):
        LOGGER.info(
            "axis %s: thermal error of %d spindle campaigns in %d runs: %.1f to %.1f um",
            axis,
            rows["campaign_id"].nunique(),
            rows["run_id"].nunique(),
            rows["thermal_error_um"].min(),
            rows["thermal_error_um"].max(),
        )
    warm = [c for c, info in record["campaigns"].items() if info["warm_start"]]
    if warm:
        LOGGER.info("warm starts (error counted from their run's reference): %s", ", ".join(warm))
    return 0

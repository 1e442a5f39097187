"""DVC stages ``separate_spindle`` and ``separate_axis``: geometric / thermal error separation.

``thermal separate spindle`` reads the validated spindle campaigns and writes the thermal error
(:mod:`pipeline.spindle_separation`); ``thermal separate axis`` reads the validated axis
campaigns and writes the geometric polynomial, the thermal part, the slope per pass and one plot
per campaign (:mod:`pipeline.axis_separation`). Two stages, so that a new spindle campaign does
not rerun the axis separation.
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np
import pandas as pd
from numpy.polynomial import Polynomial

from pipeline import paths, plots
from pipeline.axis_separation import separate_axis
from pipeline.config import load_section
from pipeline.spindle_separation import SeparationSettings, spindle_thermal_error
from schemas import AxisSlopesModel, SpindleThermalErrorModel

LOGGER = logging.getLogger(__name__)


def run_spindle(params: dict) -> None:
    """Write ``data/separated/spindle_thermal_error.parquet`` and ``spindle_runs.json``."""
    folder = paths.VALIDATED_SPINDLE
    table, record = spindle_thermal_error(
        pd.read_parquet(folder / paths.CAMPAIGNS_FILE),
        pd.read_parquet(folder / paths.SAMPLES_FILE),
        SeparationSettings.from_params(params),
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
            axis, rows["campaign_id"].nunique(), rows["run_id"].nunique(),
            rows["thermal_error_um"].min(), rows["thermal_error_um"].max(),
        )  # fmt: skip
    warm = [c for c, info in record["campaigns"].items() if info["warm_start"]]
    if warm:
        LOGGER.info("warm starts (error counted from their run's reference): %s", ", ".join(warm))


def run_axis(params: dict) -> None:
    """Write the axis separation tables and ``reports/separation/<campaign>.png``."""
    folder = paths.VALIDATED_AXIS
    campaigns = pd.read_parquet(folder / paths.CAMPAIGNS_FILE)
    paths.SEPARATED.mkdir(parents=True, exist_ok=True)
    paths.SEPARATION_PLOTS.mkdir(parents=True, exist_ok=True)
    if campaigns.empty:
        LOGGER.warning("no valid axis_positioning campaign: axis separation writes empty tables")
        for path in (paths.AXIS_GEOMETRIC, paths.AXIS_THERMAL_ERROR, paths.AXIS_SLOPES):
            pd.DataFrame().to_parquet(path)
        return
    tables = separate_axis(
        campaigns,
        pd.read_parquet(folder / paths.SAMPLES_FILE),
        pd.read_parquet(folder / paths.LASER_FILE),
        order=int(params["geometric_order"]),
    )
    AxisSlopesModel.validate(tables["slopes"], lazy=True)
    tables["geometric"].to_parquet(paths.AXIS_GEOMETRIC, index=False)
    tables["thermal"].to_parquet(paths.AXIS_THERMAL_ERROR, index=False)
    tables["slopes"].to_parquet(paths.AXIS_SLOPES, index=False)
    for meta in campaigns.itertuples(index=False):
        coefficients = tables["geometric"].query("campaign_id == @meta.campaign_id")["coefficient"]
        dense = np.linspace(*_stroke(tables["thermal"], meta.campaign_id), 200)
        plots.axis_separation(
            tables["thermal"][tables["thermal"]["campaign_id"] == meta.campaign_id],
            pd.DataFrame({"target_mm": dense,
                          "geometric_um": Polynomial(coefficients.to_numpy())(dense)}),
            meta.campaign_id,
            "SYNTHETIC data" if meta.synthetic else "measured data",
            paths.SEPARATION_PLOTS / f"{meta.campaign_id}.png",
        )  # fmt: skip
    slopes = tables["slopes"]
    LOGGER.info(
        "axis separation of %d campaigns: slopes %.4f to %.4f um/mm over %d passes",
        len(campaigns), slopes["slope_um_per_mm"].min(), slopes["slope_um_per_mm"].max(),
        len(slopes),
    )  # fmt: skip


def _stroke(thermal: pd.DataFrame, campaign_id: str) -> tuple[float, float]:
    targets = thermal.loc[thermal["campaign_id"] == campaign_id, "target_mm"]
    return float(targets.min()), float(targets.max())


def main(argv: list[str] | None = None) -> int:
    """Run ``thermal separate {spindle,axis}`` with the ``separate`` section of params.yaml."""
    parser = argparse.ArgumentParser(prog="thermal separate", description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["spindle", "axis"], help="which separation to run")
    args = parser.parse_args(argv)
    params = load_section("separate")
    (run_spindle if args.part == "spindle" else run_axis)(params)
    return 0

"""DVC stage ``separate_axis``: geometric / thermal separation of the linear-axis campaigns.

``thermal separate-axis`` reads ``data/validated/axis/`` and writes, with
:func:`pipeline.separation.axis.separate_axis` (the patent's method), the geometric polynomial
(``data/separated/axis_geometric.parquet``), the thermal part
(``axis_thermal_error.parquet``), the slope per pass (``axis_slopes.parquet``) and one plot per
campaign (``reports/separation/<campaign>.png``). Parameter: ``separate.geometric_order``.
"""

from __future__ import annotations

import argparse
import logging

import pandas as pd

from pipeline import paths, plots
from pipeline.separation.axis import geometric_curve, separate_axis
from pipeline.settings.base import load_settings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings
from schemas import AxisSlopesModel

LOGGER = logging.getLogger(__name__)


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``separate`` section of params.yaml; return 0."""
    argparse.ArgumentParser(
        prog="thermal separate-axis", description=__doc__.splitlines()[0]
    ).parse_args(argv)
    settings = load_settings(SeparateSettings, "separate")
    folder = paths.VALIDATED_AXIS
    campaigns = pd.read_parquet(folder / paths.CAMPAIGNS_FILE)
    paths.SEPARATED.mkdir(parents=True, exist_ok=True)
    paths.SEPARATION_PLOTS.mkdir(parents=True, exist_ok=True)
    if campaigns.empty:
        LOGGER.warning("no valid axis_positioning campaign: axis separation writes empty tables")
        for path in (paths.AXIS_GEOMETRIC, paths.AXIS_THERMAL_ERROR, paths.AXIS_SLOPES):
            pd.DataFrame().to_parquet(path)
        return 0
    tables = separate_axis(
        campaigns,
        pd.read_parquet(folder / paths.SAMPLES_FILE),
        pd.read_parquet(folder / paths.LASER_FILE),
        order=settings.geometric_order,
    )
    AxisSlopesModel.validate(tables["slopes"], lazy=True)
    tables["geometric"].to_parquet(paths.AXIS_GEOMETRIC, index=False)
    tables["thermal"].to_parquet(paths.AXIS_THERMAL_ERROR, index=False)
    tables["slopes"].to_parquet(paths.AXIS_SLOPES, index=False)
    for meta in campaigns.itertuples(index=False):
        figure = plots.axis_separation_figure(
            tables["thermal"][tables["thermal"]["campaign_id"] == meta.campaign_id],
            geometric_curve(tables, meta.campaign_id),
            meta.campaign_id,
            "SYNTHETIC data" if meta.synthetic else "measured data",
        )
        plots.save_figure(figure, paths.SEPARATION_PLOTS / f"{meta.campaign_id}.png")
    slopes = tables["slopes"]
    LOGGER.info(
        "axis separation of %d campaigns: slopes %.4f to %.4f um/mm over %d passes",
        len(campaigns),
        slopes["slope_um_per_mm"].min(),
        slopes["slope_um_per_mm"].max(),
        len(slopes),
    )
    return 0

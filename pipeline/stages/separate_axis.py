"""DVC stage ``separate_axis``: geometric / thermal separation of the linear-axis campaigns.

``thermal separate-axis`` reads ``data/validated/axis/`` and writes, for each machine on its own
(a leading ``machine`` column) with :func:`pipeline.separation.axis.separate_axis` (the patent's
method), the geometric polynomial
(``data/separated/axis_geometric.parquet``), the thermal part
(``axis_thermal_error.parquet``), the slope per pass (``axis_slopes.parquet``) and one plot per
campaign (``reports/separation/<campaign>.png``). Parameter: ``separate.geometric_order``.
"""

from __future__ import annotations

import argparse
import logging

import pandas as pd

from pipeline import paths, plots
from pipeline.machines import MACHINE_COLUMN, machine_rows, tag_rows, with_machine
from pipeline.separation.axis import geometric_curve, separate_axis
from pipeline.settings.base import load_settings
from pipeline.settings.separate import SeparateSettings
from pipeline.warnings_capture import summarise_warnings
from schemas import AxisSlopesModel
from schemas.vocabulary import SAMPLE_BASE_COLUMNS

LOGGER = logging.getLogger(__name__)


def separate_machines(
    campaigns: pd.DataFrame, samples: pd.DataFrame, laser: pd.DataFrame, order: int
) -> dict[str, pd.DataFrame]:
    """Each machine's axis campaigns separated on their own, the tables side by side.

    Returns
    -------
    dict of str to DataFrame
        The tables of :func:`pipeline.separation.axis.separate_axis` (``geometric``,
        ``thermal``, ``slopes``), each with a leading ``machine`` column; the slopes' sensor
        columns are each machine's own (empty on the other machines' rows).
    """
    parts: dict[str, list[pd.DataFrame]] = {"geometric": [], "thermal": [], "slopes": []}
    tagged = tag_rows(samples, campaigns)
    for machine in sorted(set(campaigns[MACHINE_COLUMN].astype(str))):
        own = campaigns.loc[campaigns[MACHINE_COLUMN] == machine].reset_index(drop=True)
        ids = set(own["campaign_id"])
        rows = machine_rows(tagged, machine, SAMPLE_BASE_COLUMNS).drop(columns=MACHINE_COLUMN)
        tables = separate_axis(own, rows, laser[laser["campaign_id"].isin(ids)], order=order)
        for name, table in tables.items():
            parts[name].append(with_machine(table, machine))
    return {name: pd.concat(frames, ignore_index=True) for name, frames in parts.items()}


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
    tables = separate_machines(
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
    for machine, slopes in tables["slopes"].groupby(MACHINE_COLUMN, sort=True):
        LOGGER.info(
            "machine %s: axis separation of %d campaigns: slopes %.4f to %.4f um/mm over %d passes",
            machine,
            slopes["campaign_id"].nunique(),
            slopes["slope_um_per_mm"].min(),
            slopes["slope_um_per_mm"].max(),
            len(slopes),
        )
    return 0

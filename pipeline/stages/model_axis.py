"""DVC stage ``model_axis``: the linear-axis composite thermal-error model of the patent.

``thermal model-axis`` reads the axis separation tables (``data/separated/axis_*.parquet``) and, for
each machine on its own, selects the slope's temperature sensitive points by best subset on the
training axis campaigns (adjusted R^2 and AICc, both winners reported, ``model_axis.selection_rule``
decides), fits k(T) by OLS, builds ``E(x, T) = P_geo(x) + (k(T) - k0) x``
(:mod:`pipeline.models.axis_composite`) and scores it on the training campaigns (fit) and the
validation campaigns against the patent's +-3.5 um. Writes ``reports/axis_model.json`` and
``metrics/axis_model.json`` (``{"machines": {machine: ...}}``) and
``reports/axis_model/<machine>.png``; without axis campaigns it writes the files saying so.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.machines import MACHINE_COLUMN, by_machine, machine_key
from pipeline.models.axis_fit import build
from pipeline.reporting.axis_model import plot
from pipeline.settings.base import load_settings
from pipeline.settings.model_axis import ModelAxisSettings
from pipeline.warnings_capture import summarise_warnings
from schemas import AxisSlopesModel

LOGGER = logging.getLogger(__name__)


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise MissingInputError(f"{path} not found; run the separate_axis stage first (dvc repro)")
    return pd.read_parquet(path)


def write(reports: dict, metrics: dict, points: dict[str, pd.DataFrame]) -> None:
    """Write the reports, the metrics and one figure per machine to their places.

    ``reports`` and ``metrics``: ``{"machines": {machine: ...}}``; ``points``: machine -> its
    scored points (:func:`pipeline.models.axis_fit.build`).
    """
    for path, content in ((paths.AXIS_MODEL_REPORT, reports), (paths.AXIS_MODEL_METRICS, metrics)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")
    if paths.AXIS_MODEL_PLOTS.is_dir():
        shutil.rmtree(paths.AXIS_MODEL_PLOTS)
    paths.AXIS_MODEL_PLOTS.mkdir(parents=True)
    for machine, report in reports["machines"].items():
        plot(points[machine], report, paths.AXIS_MODEL_PLOTS / f"{machine_key(machine)}.png")


def build_machines(
    params: ModelAxisSettings, slopes: pd.DataFrame, geometric: pd.DataFrame, thermal: pd.DataFrame
) -> tuple[dict, dict, dict[str, pd.DataFrame]]:
    """Build each machine's composite model on its own campaigns.

    Returns
    -------
    reports, metrics : dict
        ``{"machines": {machine: report}}`` and the same for the metrics; with no axis campaign
        at all, the reason (``status``, ``message``) beside an empty ``machines``.
    points : dict of str to DataFrame
        Each machine's scored points.
    """
    reports, metrics, points = {}, {}, {}
    fixed = [*AxisSlopesModel.to_schema().columns]
    for machine, rows in by_machine(slopes, fixed) if not slopes.empty else []:
        reports[machine], metrics[machine], points[machine] = build(
            params,
            rows.drop(columns=MACHINE_COLUMN),
            _rows(geometric, machine),
            _rows(thermal, machine),
        )
    report_doc, metric_doc = {"machines": reports}, {"machines": metrics}
    if not reports:
        report_doc |= build(params, slopes, geometric, thermal)[0]
    return report_doc, metric_doc, points


def _rows(table: pd.DataFrame, machine: str) -> pd.DataFrame:
    """Return the machine's rows of a table of fixed columns, without ``machine``."""
    rows = table.loc[table[MACHINE_COLUMN] == machine]
    return rows.drop(columns=MACHINE_COLUMN).reset_index(drop=True)


@summarise_warnings()
def main(argv: Sequence[str] | None = None) -> int:
    """Run ``thermal model-axis`` with the ``model_axis`` section of params.yaml."""
    parser = argparse.ArgumentParser(prog="thermal model-axis", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_settings(ModelAxisSettings, "model_axis")
    reports, metrics, points = build_machines(
        params,
        _read(paths.AXIS_SLOPES),
        _read(paths.AXIS_GEOMETRIC),
        _read(paths.AXIS_THERMAL_ERROR),
    )
    write(reports, metrics, points)
    for machine, report in reports["machines"].items():
        machine_metrics = metrics["machines"][machine]
        if not machine_metrics.get("n_validation_points"):
            continue
        LOGGER.info(
            "machine %s: axis model k on %s: validation residual %.2f to %.2f um (max |r| %.2f "
            "um, patent +-%g um), rmse %.2f um over %d points",
            machine,
            report["selection"]["selected"],
            machine_metrics["residual_min_um"],
            machine_metrics["residual_max_um"],
            machine_metrics["residual_max_abs_um"],
            report["patent_band_um"],
            machine_metrics["rmse_um"],
            machine_metrics["n_validation_points"],
        )
    return 0

"""DVC stage ``model_axis``: the linear-axis composite thermal-error model of the patent.

``thermal model-axis`` reads the axis separation tables (``data/separated/axis_*.parquet``),
selects the slope's temperature sensitive points by best subset on the training axis campaigns
(adjusted R^2 and AICc, both winners reported, ``model_axis.selection_rule`` decides), fits
k(T) by OLS, builds ``E(x, T) = P_geo(x) + (k(T) - k0) x`` (:mod:`pipeline.models.axis_composite`)
and scores it on the training campaigns (fit) and the validation campaigns against the patent's
+-3.5 um. Writes ``reports/axis_model.json``, ``metrics/axis_model.json`` and
``reports/axis_model.png``; without axis campaigns it writes the three files saying so.
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.models.axis_fit import build
from pipeline.reporting.axis_model import plot
from pipeline.settings.base import load_settings
from pipeline.settings.model_axis import ModelAxisSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise MissingInputError(f"{path} not found; run the separate_axis stage first (dvc repro)")
    return pd.read_parquet(path)


def write(report: dict, metrics: dict, points: pd.DataFrame) -> None:
    """Write the report, the metrics and the figure to their :mod:`pipeline.paths` places."""
    for path, content in ((paths.AXIS_MODEL_REPORT, report), (paths.AXIS_MODEL_METRICS, metrics)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")
    plot(points, report, paths.AXIS_MODEL_PLOT)


@summarise_warnings()
def main(argv: Sequence[str] | None = None) -> int:
    """Run ``thermal model-axis`` with the ``model_axis`` section of params.yaml."""
    parser = argparse.ArgumentParser(prog="thermal model-axis", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_settings(ModelAxisSettings, "model_axis")
    report, metrics, points = build(
        params,
        _read(paths.AXIS_SLOPES),
        _read(paths.AXIS_GEOMETRIC),
        _read(paths.AXIS_THERMAL_ERROR),
    )
    write(report, metrics, points)
    if metrics.get("n_validation_points"):
        LOGGER.info(
            "axis model k on %s: validation residual %.2f to %.2f um (max |r| %.2f um, patent "
            "+-%g um), rmse %.2f um over %d points",
            report["selection"]["selected"],
            metrics["residual_min_um"],
            metrics["residual_max_um"],
            metrics["residual_max_abs_um"],
            report["patent_band_um"],
            metrics["rmse_um"],
            metrics["n_validation_points"],
        )
    return 0

"""DVC stage ``select``: the temperature-sensitive points of every training unit, by every method.

Reads ``data/separated/spindle_thermal_error.parquet``. For each selection method of
``params.yaml`` ``select.methods`` (registry :mod:`pipeline.selection`) and each training unit
(each training campaign, each leave-one-season-out set, all training campaigns; see
:mod:`pipeline.training_units`) it chooses the sensors from the training data only, and writes

- ``reports/selection/selected.json``: ``{"features": ..., "methods": {method: {unit:
  {"sensors": [...], "details": {...}}}}}``, the input of ``evaluate``;
- ``reports/selection/<method>_evidence.csv``: the numbers each choice was made on, one block
  per unit (leading column ``unit``);
- ``reports/selection/stability.csv`` and ``stability.png``: how often each sensor is chosen
  across the training campaigns, per method (the PCDL paper's table 3: sensitive points vary
  from batch to batch).
"""

from __future__ import annotations

import argparse
import json
import logging
import re

import pandas as pd

from pipeline import paths, plots
from pipeline.config import load_section
from pipeline.selection import Selection, make_selector
from pipeline.training_units import (
    CampaignSeries,
    TrainingUnit,
    campaign_series,
    stack,
    training_units,
)

LOGGER = logging.getLogger(__name__)

FEATURE_PREFIX = {"temperature_rise": "rise_", "absolute": ""}


def sensor_columns(table: pd.DataFrame) -> list[str]:
    """Temperature sensor names in the separated table (columns with a ``rise_`` twin).

    In natural order: T2 before T10.
    """
    names = [c.removeprefix("rise_") for c in table.columns if c.startswith("rise_")]
    return sorted(names, key=lambda name: [int(p) if p.isdigit() else p
                                           for p in re.split(r"(\d+)", name)])  # fmt: skip


def feature_prefix(features: str) -> str:
    """Column prefix of a feature kind.

    Raises
    ------
    ValueError
        If ``features`` is neither ``temperature_rise`` nor ``absolute``.
    """
    if features not in FEATURE_PREFIX:
        raise ValueError(
            f"params.yaml select.features is '{features}'; use one of {sorted(FEATURE_PREFIX)}"
        )
    return FEATURE_PREFIX[features]


def select_unit(
    method: str, settings: dict, unit: TrainingUnit, series: list[CampaignSeries]
) -> Selection:
    """Run one selection method on the campaigns of one training unit.

    Only sensors with readings in every campaign of the unit are candidates.
    """
    training = [s for s in series if s.campaign_id in unit.campaigns]
    sensors = [
        column
        for column in training[0].features.columns
        if all(s.features[column].notna().any() for s in training)
    ]
    temperatures, error = stack(training, sensors)
    return make_selector(method, **(settings or {}))(temperatures, error)


def select_all(
    series: list[CampaignSeries], units: list[TrainingUnit], methods: dict[str, dict]
) -> dict[str, dict[str, Selection]]:
    """Every method on every training unit: ``{method: {unit name: Selection}}``."""
    return {
        method: {unit.name: select_unit(method, settings, unit, series) for unit in units}
        for method, settings in methods.items()
    }


def stability_table(
    selections: dict[str, dict[str, Selection]], units: list[TrainingUnit], sensors: list[str]
) -> pd.DataFrame:
    """How often each sensor is chosen across the training campaigns, per method.

    Parameters
    ----------
    selections : dict
        ``{method: {unit: Selection}}``.
    units : list of TrainingUnit
        The campaign-scheme units are counted.
    sensors : list of str
        Every sensor; one row each per method, chosen or not.

    Returns
    -------
    DataFrame
        ``method``, ``sensor``, ``times_chosen``, ``n_campaigns``, ``frequency`` (0-1); one row
        per method and sensor seen by it, most chosen first.
    """
    campaigns = [unit.name for unit in units if unit.scheme == "campaign"]
    rows = []
    for method, by_unit in selections.items():
        counts: dict[str, int] = {}
        for name in campaigns:
            for sensor in by_unit[name].sensors:
                counts[sensor] = counts.get(sensor, 0) + 1
        for sensor in sensors:
            chosen = counts.get(sensor, 0)
            rows.append({
                "method": method, "sensor": sensor, "times_chosen": chosen,
                "n_campaigns": len(campaigns), "frequency": chosen / max(len(campaigns), 1),
            })  # fmt: skip
    return pd.DataFrame(rows)


def selected_record(features: str, selections: dict[str, dict[str, Selection]]) -> dict:
    """JSON-ready record of the choices: sensors and decision details per method and unit."""
    return {
        "features": features,
        "methods": {
            method: {
                unit: {"sensors": list(sel.sensors), "details": _plain(sel.details)}
                for unit, sel in by_unit.items()
            }
            for method, by_unit in selections.items()
        },
    }


def _plain(details: dict) -> dict:
    return {str(k): (v.item() if hasattr(v, "item") else v) for k, v in details.items()}


def write_outputs(
    features: str,
    selections: dict[str, dict[str, Selection]],
    units: list[TrainingUnit],
    sensors: list[str],
    synthetic: bool,
) -> None:
    """Write every output declared for the stage in ``dvc.yaml``."""
    paths.SELECTION.mkdir(parents=True, exist_ok=True)
    for stale in paths.SELECTION.glob("*_evidence.csv"):
        stale.unlink()
    paths.SELECTED.write_text(
        json.dumps(selected_record(features, selections), indent=2, sort_keys=True) + "\n"
    )
    for method, by_unit in selections.items():
        evidence = pd.concat(
            [sel.evidence.assign(unit=unit) for unit, sel in by_unit.items()], ignore_index=True
        )
        evidence = evidence[["unit", *[c for c in evidence.columns if c != "unit"]]]
        evidence.to_csv(paths.SELECTION / f"{method}_evidence.csv", index=False,
                        float_format="%.6g")  # fmt: skip
    stability = stability_table(selections, units, sensors)
    stability.to_csv(paths.SELECTION_STABILITY, index=False, float_format="%.4f")
    label = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    plots.selection_stability(
        stability,
        f"How often each sensor is chosen, across the training campaigns ({label})",
        paths.SELECTION_STABILITY_PNG,
    )


def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``select`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal select", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("select")
    features = str(params.get("features", "temperature_rise"))
    methods = {str(name): dict(settings or {}) for name, settings in params["methods"].items()}
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    series = campaign_series(table, sensor_columns(table), feature_prefix(features))
    units = training_units(series)
    selections = select_all(series, units, methods)
    write_outputs(
        features, selections, units, sensor_columns(table), bool(table["synthetic"].any())
    )
    for method, by_unit in selections.items():
        LOGGER.info(
            "%s: all training campaigns -> %s", method, ", ".join(by_unit["all_training"].sensors)
        )
    return 0

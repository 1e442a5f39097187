"""Every selection method run on every training unit of an axis, and what the runs agree on.

For each method entry of ``params.yaml`` ``select.methods`` and each training unit (each training
campaign, each season or campaign left out, all training campaigns), the inputs are chosen on the
unit's training data only; the stability table counts how often each input is chosen across the
training campaigns (the PCDL paper's table 3). The ``select`` stage writes the results.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import pandas as pd

from pipeline.errors import ParamsError
from pipeline.protocol.units import (
    CampaignSeries,
    TrainingUnit,
    stack,
)
from pipeline.selection import Selection, make_selector
from pipeline.selection.registry import SELECTORS, parameters
from pipeline.separation.features import is_speed_feature
from pipeline.settings.base import unknown_name_error

LOGGER = logging.getLogger(__name__)

INPUT_SETS = ("temperatures", "temperatures_and_speed")
ENTRY_KEYS = ("method", "inputs")
"""Keys of a ``select.methods`` entry besides the method's parameters."""


STABILITY_COLUMNS = ["method", "sensor", "times_chosen", "n_campaigns", "frequency"]


def method_entries(methods: Mapping[str, Mapping | None]) -> dict[str, tuple[str, str, dict]]:
    """Parse ``select.methods``: name -> (registry method, input set, its parameters).

    Raises
    ------
    ParamsError
        If an entry names a method the registry does not have, a parameter that method does
        not take or an ``inputs`` not in :data:`INPUT_SETS`; the message names the key path
        (``select.methods.gra_top_k.kk``) and what is allowed there.
    """
    entries = {}
    for name, settings in methods.items():
        settings = dict(settings or {})
        path = ("select", "methods", str(name))
        method = str(settings.pop("method", name))
        inputs = str(settings.pop("inputs", "temperatures_and_speed"))
        if method not in SELECTORS:
            where = path if method == name else (*path, "method")
            raise unknown_name_error(
                where, method, sorted(SELECTORS), "selection method", "registered"
            )
        if inputs not in INPUT_SETS:
            raise ParamsError(
                f"params.yaml: select.methods.{name}.inputs = '{inputs}'; use one of "
                f"{', '.join(INPUT_SETS)}"
            )
        accepted = [*parameters(method), *ENTRY_KEYS]
        for key in settings:
            if key not in accepted:
                raise unknown_name_error((*path, key), key, accepted, "key", "allowed here")
        entries[str(name)] = (method, inputs, settings)
    return entries


def select_unit(
    entry: tuple[str, str, dict],
    unit: TrainingUnit,
    series: list[CampaignSeries],
    with_readings: Mapping[str, set[str]],
) -> Selection:
    """Run one selection method on the campaigns of one training unit.

    Only inputs with readings in every campaign of the unit are candidates
    (``with_readings``: campaign id -> its inputs with at least one reading); with the input
    set ``temperatures``, the speed responses are not offered. When the unit's campaigns share
    no input (a sensor renamed, the only common one dead), the selection is empty and says
    why; the models fed by it are not fitted on that unit.
    """
    method, inputs, settings = entry
    training = [s for s in series if s.campaign_id in unit.campaigns]
    offered = [
        column
        for column in training[0].features.columns
        if all(column in with_readings[s.campaign_id] for s in training)
        and (inputs == "temperatures_and_speed" or not is_speed_feature(column))
    ]
    if not offered:
        reason = f"no input has readings in every campaign of {unit.name}"
        LOGGER.warning("%s: %s; nothing selected", method, reason)
        return Selection(method, [], pd.DataFrame(columns=["sensor"]), {"empty": reason})
    temperatures, error = stack(training, offered)
    return make_selector(method, **settings)(temperatures, error)


def select_axis(
    series: list[CampaignSeries], units: list[TrainingUnit], entries: dict
) -> dict[str, dict[str, Selection]]:
    """Every method on every training unit of one axis: ``{method: {unit name: Selection}}``."""
    with_readings = {
        s.campaign_id: set(s.features.columns[s.features.notna().any().to_numpy()]) for s in series
    }
    return {
        name: {unit.name: select_unit(entry, unit, series, with_readings) for unit in units}
        for name, entry in entries.items()
    }


def stability_table(
    selections: dict[str, dict[str, Selection]], units: list[TrainingUnit], inputs: list[str]
) -> pd.DataFrame:
    """How often each input is chosen across the training campaigns, per method.

    Parameters
    ----------
    selections : dict
        ``{method: {unit: Selection}}`` of one axis.
    units : list of TrainingUnit
        The campaign-scheme units are counted.
    inputs : list of str
        Every input; one row each per method, chosen or not.

    Returns
    -------
    DataFrame
        ``method``, ``sensor``, ``times_chosen``, ``n_campaigns``, ``frequency`` (0-1); one row
        per method and input.
    """
    campaigns = [unit.name for unit in units if unit.scheme == "campaign"]
    rows = []
    for method, by_unit in selections.items():
        counts: dict[str, int] = {}
        for name in campaigns:
            for sensor in by_unit[name].sensors:
                counts[sensor] = counts.get(sensor, 0) + 1
        for sensor in inputs:
            chosen = counts.get(sensor, 0)
            rows.append(
                {
                    "method": method,
                    "sensor": sensor,
                    "times_chosen": chosen,
                    "n_campaigns": len(campaigns),
                    "frequency": chosen / max(len(campaigns), 1),
                }
            )
    return pd.DataFrame(rows)


def selected_record(
    features: str,
    selections: dict[str, dict[str, dict[str, Selection]]],
    skipped: dict[str, str] | None = None,
) -> dict:
    """JSON-ready record of the choices: inputs and decision details per axis, method and unit.

    ``skipped``: axis -> why nothing was selected on it (no training campaign).
    """
    return {
        "features": features,
        "skipped_axes": dict(skipped or {}),
        "axes": {
            axis: {
                method: {
                    unit: {"inputs": list(sel.sensors), "details": _plain(sel.details)}
                    for unit, sel in by_unit.items()
                }
                for method, by_unit in by_method.items()
            }
            for axis, by_method in selections.items()
        },
    }


def _plain(details: dict) -> dict:
    return {str(k): (v.item() if hasattr(v, "item") else v) for k, v in details.items()}

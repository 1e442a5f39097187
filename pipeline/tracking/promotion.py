"""The promotion gate on the model registry: score, decide, move the aliases, roll back.

Each axis' registered model ``<prefix>-<axis>`` carries three aliases:

- ``champion``: what the machine runs; moved only by the gate (:func:`run_gate`) or by
  :func:`rollback`;
- ``previous``: the champion before the last promotion (what :func:`rollback` returns to);
- ``challenger``: the latest version the gate kept out.

The rule is :mod:`pipeline.protocol.promotion`. The current champion is loaded as registered
(``mlflow.pyfunc``) and applied to each campaign it was not trained on, the whole record that
campaign belongs to fed from its cold start (``run_id`` as the run, ``run_elapsed_s`` as the
time), as a machine runs it; the challenger is scored by its held-out predictions
(``data/models/champion/<axis>/heldout.parquet``). Every decision is tagged on the
challenger's version (``gate``, ``gate_reason``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from mlflow.exceptions import MlflowException
from mlflow.tracking import MlflowClient

from pipeline.protocol.promotion import (
    ERROR,
    GateDecision,
    compare_campaigns,
    decide_promotion,
)
from pipeline.separation.features import is_speed_feature
from pipeline.tracking.champion_model import import_path_kept

logger = logging.getLogger(__name__)

CHAMPION, PREVIOUS, CHALLENGER = "champion", "previous", "challenger"
GATE_TAG, GATE_REASON_TAG = "gate", "gate_reason"
MAX_TAG_LENGTH = 5000


def version_by_alias(client: MlflowClient, name: str, alias: str):
    """Return the model version of ``name`` carrying ``alias``, or None."""
    try:
        return client.get_model_version_by_alias(name, alias)
    except MlflowException:
        return None


def label_of(version) -> str:
    """``model/selection/mode`` of a registered version, from its tags."""
    if version is None:
        return ""
    tags = version.tags or {}
    return "/".join(tags.get(k, "?") for k in ("model", "selection", "mode"))


def trained_on(version) -> set[str]:
    """Return the campaigns a registered version was fitted on (its ``trained_on`` tag)."""
    text = (version.tags or {}).get("trained_on", "-")
    return set() if text in ("", "-") else set(text.split(","))


def registered_predictions(model_uri: str, table: pd.DataFrame, inputs: Sequence[str]):
    """Return a registered champion's prediction of every row of one axis' separated table (um).

    Parameters
    ----------
    model_uri : str
        ``models:/<name>/<version>``.
    table : DataFrame
        One axis' rows of ``data/separated/spindle_thermal_error.parquet``.
    inputs : sequence of str
        The model's inputs (its version's ``inputs`` tag): the sensors are passed in degC, the
        speed responses are computed by the model from ``rpm``.

    Returns
    -------
    DataFrame
        ``campaign_id``, ``elapsed_s``, ``measured_um``, ``predicted_um``: each record fed
        from its cold start, as the machine runs the model.
    """
    import mlflow.pyfunc

    with import_path_kept():
        model = mlflow.pyfunc.load_model(model_uri)
    sensors = [name for name in inputs if not is_speed_feature(name)]  # speed: from rpm
    frames = []
    for run_id, rows in table.groupby("run_id", sort=False):
        rows = rows.sort_values("run_elapsed_s")
        machine_log = pd.DataFrame(
            {
                "campaign_id": str(run_id),
                "elapsed_s": rows["run_elapsed_s"].to_numpy(dtype=float),
                "rpm": rows["rpm"].to_numpy(dtype=float),
                **{s: rows[s].to_numpy(dtype=float) for s in sensors if s in rows},
            }
        )
        missing = [s for s in sensors if s not in rows]
        for sensor in missing:
            machine_log[sensor] = np.nan
        predicted = np.asarray(model.predict(machine_log), dtype=float)
        frames.append(
            pd.DataFrame(
                {
                    "campaign_id": rows["campaign_id"].to_numpy(dtype=str),
                    "elapsed_s": rows["elapsed_s"].to_numpy(dtype=float),
                    "measured_um": rows["thermal_error_um"].to_numpy(dtype=float),
                    "predicted_um": predicted,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def gate_axis(
    client: MlflowClient,
    name: str,
    axis: str,
    challenger_version: str | None,
    table: pd.DataFrame,
    heldout: pd.DataFrame,
    margin: float,
) -> GateDecision:
    """Decide one axis (see :mod:`pipeline.protocol.promotion`) and move its aliases.

    Parameters
    ----------
    client : MlflowClient
    name : str
        Registered model name, e.g. ``thermal-error-spindle-Z``.
    axis : str
    challenger_version : str or None
        The version this pipeline execution registered (or reused).
    table : DataFrame
        The axis' rows of the separated table.
    heldout : DataFrame
        The challenger's held-out predictions.
    margin : float
        ``track.promotion.min_improvement``.
    """
    current = version_by_alias(client, name, CHAMPION)
    challenger = (
        None if challenger_version is None else client.get_model_version(name, challenger_version)
    )
    versions = (None if current is None else str(current.version), challenger_version)
    labels = (label_of(current), label_of(challenger))
    comparisons, unscored = [], {}
    if current is not None and challenger is not None and versions[0] != versions[1]:
        seen = trained_on(current)
        new = [c for c in dict.fromkeys(table["campaign_id"].astype(str)) if c not in seen]
        inputs = [s for s in current.tags.get("inputs", "-").split(",") if s and s != "-"]
        try:
            now = registered_predictions(f"models:/{name}/{current.version}", table, inputs)
        except (MlflowException, OSError, ValueError, KeyError) as error:
            reason = f"champion version {current.version} could not be loaded and run: {error}"
            return GateDecision(axis, ERROR, reason, *versions, *labels, margin)
        comparisons, unscored = compare_campaigns(now, heldout, new)
    decision = decide_promotion(axis, comparisons, margin, versions, labels, unscored)
    apply_decision(client, name, decision)
    return decision


def apply_decision(client: MlflowClient, name: str, decision: GateDecision) -> None:
    """Move the aliases as decided and tag the challenger's version with the decision."""
    challenger = decision.challenger_version
    if challenger is None:
        return
    if decision.promoted:
        if decision.current_version is not None:
            client.set_registered_model_alias(name, PREVIOUS, decision.current_version)
        client.set_registered_model_alias(name, CHAMPION, challenger)
        _drop_alias(client, name, CHALLENGER)
    elif decision.current_version != challenger:
        client.set_registered_model_alias(name, CHALLENGER, challenger)
    client.set_model_version_tag(name, challenger, GATE_TAG, decision.action)
    client.set_model_version_tag(
        name, challenger, GATE_REASON_TAG, decision.reason[:MAX_TAG_LENGTH]
    )
    logger.info("%s: %s (%s)", name, decision.action, decision.reason)


def _drop_alias(client: MlflowClient, name: str, alias: str) -> None:
    if version_by_alias(client, name, alias) is not None:
        client.delete_registered_model_alias(name, alias)


def run_gate(
    client: MlflowClient,
    names: Mapping[str, str],
    challengers: Mapping[str, str | None],
    table: pd.DataFrame,
    heldout: Mapping[str, pd.DataFrame],
    margin: float,
) -> list[GateDecision]:
    """Run the gate on every axis.

    Parameters
    ----------
    client : MlflowClient
    names : mapping
        Axis -> registered model name.
    challengers : mapping
        Axis -> the version this execution registered.
    table : DataFrame
        The separated table (every axis).
    heldout : mapping
        Axis -> the challenger's held-out predictions.
    margin : float
    """
    return [
        gate_axis(
            client,
            name,
            axis,
            challengers.get(axis),
            table[table["axis"] == axis],
            heldout.get(axis, pd.DataFrame()),
            margin,
        )
        for axis, name in names.items()
    ]


def rollback(client: MlflowClient, name: str) -> tuple[str, str]:
    """Move ``champion`` back to the ``previous`` version; the two aliases swap.

    Returns
    -------
    tuple of str
        (version rolled back from, version now champion).

    Raises
    ------
    LookupError
        If ``name`` has no ``previous`` or no ``champion`` version.
    """
    previous = version_by_alias(client, name, PREVIOUS)
    current = version_by_alias(client, name, CHAMPION)
    if previous is None or current is None:
        raise LookupError(
            f"{name} has no @{PREVIOUS} version to roll back to (only a promotion by the gate "
            "sets one); set an alias by hand in the MLflow UI or with "
            "MlflowClient.set_registered_model_alias"
        )
    client.set_registered_model_alias(name, CHAMPION, str(previous.version))
    client.set_registered_model_alias(name, PREVIOUS, str(current.version))
    client.set_model_version_tag(name, str(current.version), GATE_TAG, "rolled_back")
    logger.info("%s: @champion v%s -> v%s", name, current.version, previous.version)
    return str(current.version), str(previous.version)

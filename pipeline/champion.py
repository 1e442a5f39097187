"""Choose the champion model and describe it for registration.

The champion is the candidate with the smallest validation Mn (mean residual standard deviation
on the validation campaigns, um) under the PCDL paper's protocol (scheme ``campaign``), among
the candidates a machine can run from its temperatures alone: mode ``static`` or ``free_run``.
One-step-ahead scores need the measured error online and are not eligible (they would win
trivially). Without validation campaigns the prediction Mn on the other training campaigns is
used instead, and the card says so. The registered model is the candidate's fit on all training
campaigns (unit ``all_training``).

The physical twin (model ``twin``, :mod:`pipeline.twin_candidate`) is scored and ranked in the
report but is not eligible: the champion is registered as an MLflow pyfunc that predicts from a
table of temperatures (:func:`temperature_features`), and the twin needs another input (the
spindle program, the sensor roles and each run's first readings).
"""

from __future__ import annotations

import math

import pandas as pd

from pipeline.cross_season import FREE_RUN, STATIC, UnitResult
from pipeline.training_units import POOLED_UNIT

DEPLOYABLE_MODES = (STATIC, FREE_RUN)
NOT_REGISTRABLE_MODELS = ("twin",)
"""Candidates never chosen as champion (see the module docstring)."""


def rank_candidates(summary: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """Deployable candidates ordered best first, and the score column used.

    Parameters
    ----------
    summary : DataFrame
        :func:`pipeline.scoring.candidate_summary` output.

    Returns
    -------
    ranked : DataFrame
        Rows of ``summary`` with a deployable mode and a finite score, best first; models of
        :data:`NOT_REGISTRABLE_MODELS` left out.
    column : str
        ``Mn_val_um`` or, without validation campaigns, ``Mn_um``.

    Raises
    ------
    ValueError
        If no deployable candidate has a finite score.
    """
    deployable = summary[
        summary["mode"].isin(DEPLOYABLE_MODES) & ~summary["model"].isin(NOT_REGISTRABLE_MODELS)
    ]
    column = "Mn_val_um"
    if column not in deployable or not deployable[column].notna().any():
        column = "Mn_um"
    ranked = deployable[deployable[column].notna()] if column in deployable else deployable[:0]
    if ranked.empty:
        raise ValueError(
            "no candidate running from temperatures alone (mode static or free_run) has a "
            "prediction score; add a training campaign or a validation campaign"
        )
    return ranked.sort_values([column, "model", "selection"]).reset_index(drop=True), column


def champion_card(best: pd.Series, column: str, result: UnitResult, features: str) -> dict:
    """JSON-ready description of the champion (``data/models/champion/champion.json``).

    Parameters
    ----------
    best : Series
        The champion's row of the candidate summary.
    column : str
        The score it was chosen on.
    result : UnitResult
        Its fit on all training campaigns.
    features : str
        ``temperature_rise`` or ``absolute``.
    """
    if result.unit.name != POOLED_UNIT:
        raise ValueError(f"the champion must be the fit on {POOLED_UNIT}, got {result.unit.name}")
    scores = {
        key: (None if not isinstance(value, float) or math.isnan(value) else round(value, 4))
        for key, value in best.items()
        if key.endswith("_um")
    }
    return {
        "model": best["model"],
        "selection": best["selection"],
        "mode": best["mode"],
        "chosen_on": column,
        "sensors": list(result.sensors),
        "features": features,
        "trained_on": list(result.unit.campaigns),
        "chosen_params": {k: _plain(v) for k, v in result.chosen_params.items()},
        "scores_um": scores,
    }


def _plain(value):
    return value.item() if hasattr(value, "item") else value


def temperature_features(table: pd.DataFrame, card: dict) -> pd.DataFrame:
    """Model input from a temperature table, as the champion was trained.

    Parameters
    ----------
    table : DataFrame
        One row per sample in time order; a column per chosen sensor (degC), named as in the
        card's ``sensors``; optional ``campaign_id`` (several runs in one table) and
        ``elapsed_s`` (s). With ``features: temperature_rise`` each run's first row is its cold
        reference: the model sees each sensor minus its first reading (K).

    Returns
    -------
    DataFrame of shape (n, len(sensors))
        Indexed by (``campaign_id``, ``elapsed_s``).

    Raises
    ------
    ValueError
        If a sensor column is missing, naming it and the columns found.
    """
    sensors = list(card["sensors"])
    missing = [s for s in sensors if s not in table.columns]
    if missing:
        raise ValueError(
            f"temperature table lacks sensor column(s) {missing} (found {list(table.columns)}); "
            f"the champion {card['model']}/{card['selection']} needs {sensors}, in degC"
        )
    runs = (
        table["campaign_id"].astype(str)
        if "campaign_id" in table
        else pd.Series("run", index=table.index)
    )
    elapsed = (
        table["elapsed_s"]
        if "elapsed_s" in table
        else pd.Series(range(len(table)), index=table.index, dtype=float)
    )
    values = table[sensors].astype(float)
    if card["features"] == "temperature_rise":
        values = values - values.groupby(runs.to_numpy()).transform("first")
    index = pd.MultiIndex.from_arrays(
        [runs.to_numpy(), elapsed.to_numpy(dtype=float)], names=["campaign_id", "elapsed_s"]
    )
    return pd.DataFrame(values.to_numpy(), columns=sensors, index=index)

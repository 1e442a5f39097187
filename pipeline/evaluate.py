"""DVC stage ``evaluate``: every model built on each training campaign, scored on every campaign.

Reads ``data/separated/spindle_thermal_error.parquet``; writes the long score table, the
train x test matrices (CSV + heat-map PNG), ``metrics/cross_season.json`` (a DVC metric), the
fitted-model record read by ``track`` and two DVC plot tables. Scores: :mod:`pipeline.scoring`.
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np
import pandas as pd

from pipeline import paths, plots
from pipeline.config import load_section
from pipeline.cross_season import (
    FittedOnCampaign,
    available_sensors,
    campaign_series,
    cross_season,
)
from pipeline.models import make_model
from pipeline.scoring import metrics_tree, score_matrix
from schemas import CrossSeasonScoresModel

LOGGER = logging.getLogger(__name__)

FEATURE_PREFIX = {"temperature_rise": "rise_", "absolute": ""}
SELECTION = "all"


def sensor_columns(table: pd.DataFrame) -> list[str]:
    """Temperature sensor names present in the separated table (columns with a ``rise_`` twin)."""
    return [c.removeprefix("rise_") for c in table.columns if c.startswith("rise_")]


def evaluate(
    table: pd.DataFrame, model: str, features: str, n_jobs: int
) -> tuple[pd.DataFrame, list[FittedOnCampaign]]:
    """Score ``model`` on all temperature sensors across campaigns.

    Parameters
    ----------
    table : DataFrame
        The separated spindle thermal-error table.
    model : str
        Registry name, e.g. ``"mlr"``.
    features : str
        ``temperature_rise`` (each sensor minus its value at the cold reference, K) or
        ``absolute`` (degC).
    n_jobs : int
        Parallel training campaigns.

    Returns
    -------
    scores : DataFrame
        Long score table (``model``, ``selection``, ``train_campaign``, ``test_campaign``,
        ``test_split``, ``role``, ``n_samples``, ``rmse_um``, ``resid_std_um``).
    fitted : list of FittedOnCampaign
    """
    if features not in FEATURE_PREFIX:
        raise ValueError(
            f"params.yaml evaluate.features is '{features}'; use one of {sorted(FEATURE_PREFIX)}"
        )
    series = campaign_series(table, sensor_columns(table), FEATURE_PREFIX[features])
    fitted = cross_season(series, lambda: make_model(model), available_sensors, n_jobs)
    scores = pd.concat([f.scores for f in fitted], ignore_index=True)
    scores.insert(0, "selection", SELECTION)
    scores.insert(0, "model", model)
    return CrossSeasonScoresModel.validate(scores, lazy=True), fitted


def fitted_record(model: str, features: str, fitted: list[FittedOnCampaign]) -> dict:
    """JSON-ready description of each fitted model (sensors, coefficients in um/K)."""
    record = {}
    for item in fitted:
        params: dict = {"features": features}
        estimator = item.estimator
        if hasattr(estimator, "coef_"):
            params["coefficients_um_per_K"] = dict(
                zip(item.sensors, np.round(estimator.coef_, 6).tolist(), strict=True)
            )
            params["intercept_um"] = round(float(estimator.intercept_), 6)
        record[f"{model}/{SELECTION}/{item.train_campaign}"] = {
            "model": model,
            "selection": SELECTION,
            "train_campaign": item.train_campaign,
            "sensors": item.sensors,
            "params": params,
        }
    return record


def prediction_plot_table(
    table: pd.DataFrame, scores: pd.DataFrame, fitted: list[FittedOnCampaign]
) -> pd.DataFrame:
    """Measured and predicted thermal error for the DVC plot.

    On the validation campaigns (or, without any, the other training campaigns), by the model
    built on the campaign with the best Mn_val (or Mn).
    """
    role = "validation" if (scores["role"] == "validation").any() else "prediction"
    mean = scores[scores["role"] == role].groupby("train_campaign")["resid_std_um"].mean()
    best = mean.idxmin() if mean.notna().any() else scores["train_campaign"].iloc[0]
    chosen = next(f for f in fitted if f.train_campaign == best)
    tests = scores.loc[(scores["train_campaign"] == best) & (scores["role"] == role),
                       "test_campaign"]  # fmt: skip
    frames = []
    for campaign in tests:
        rows = table[table["campaign_id"] == campaign].sort_values("elapsed_s")
        frames.append(pd.DataFrame({
            "campaign_id": campaign,
            "model_built_on": best,
            "elapsed_min": rows["elapsed_s"].to_numpy() / 60.0,
            "measured_um": rows["thermal_error_um"].to_numpy(),
            "predicted_um": np.round(chosen.predictions[campaign], 4),
        }))  # fmt: skip
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def write_outputs(table: pd.DataFrame, scores: pd.DataFrame, fitted: list, model: str,
                  features: str) -> None:  # fmt: skip
    """Write every output declared for the stage in ``dvc.yaml``."""
    for path in (paths.SCORES_LONG, paths.CROSS_SEASON_METRICS, paths.PLOT_PREDICTIONS):
        path.parent.mkdir(parents=True, exist_ok=True)
    scores.to_csv(paths.SCORES_LONG, index=False, float_format="%.6g")
    tree = metrics_tree(scores)
    paths.CROSS_SEASON_METRICS.write_text(json.dumps(_round(tree), indent=2, sort_keys=True))
    paths.FITTED_MODELS.write_text(
        json.dumps(fitted_record(model, features, fitted), indent=2, sort_keys=True)
    )
    matrices = {
        "resid_std_um": score_matrix(scores, "resid_std_um"),
        "rmse_um": score_matrix(scores, "rmse_um"),
    }
    pd.concat(matrices, names=["score", "train_campaign"]).to_csv(
        paths.MATRIX_CSV, float_format="%.4f"
    )
    synthetic = bool(table["synthetic"].any())
    label = "SYNTHETIC data from the physical twin" if synthetic else "measured data"
    plots.score_heatmaps(
        {
            "residual standard deviation S (um)": matrices["resid_std_um"],
            "RMS of the residual (um)": matrices["rmse_um"],
        },
        f"{model} on all sensors, built on one campaign, applied to every other ({label})",
        paths.MATRIX_PNG,
    )
    by_train = pd.DataFrame(tree[model][SELECTION]["by_train_campaign"]).T
    by_train.index.name = "train_campaign"
    by_train.reset_index().to_csv(paths.PLOT_SCORES_BY_TRAIN, index=False, float_format="%.4f")
    prediction_plot_table(table, scores, fitted).to_csv(paths.PLOT_PREDICTIONS, index=False)


def _round(tree):
    if isinstance(tree, dict):
        return {k: _round(v) for k, v in tree.items()}
    return None if not np.isfinite(tree) else round(float(tree), 4)


def main(argv: list[str] | None = None) -> int:
    """Run the stage with the ``evaluate`` section of ``params.yaml``."""
    parser = argparse.ArgumentParser(prog="thermal evaluate", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("evaluate")
    table = pd.read_parquet(paths.SPINDLE_THERMAL_ERROR)
    model, features = str(params["model"]), str(params["features"])
    scores, fitted = evaluate(table, model, features, int(params.get("n_jobs", 1)))
    write_outputs(table, scores, fitted, model, features)
    overall = metrics_tree(scores)[model][SELECTION]["overall"]
    LOGGER.info(
        "%s on %d training campaigns: S %.2f um, Mn %.2f um, Sd %.2f um, Mn_val %.2f um "
        "(residual std; RMS Mn %.2f um)", model, len(fitted), overall["S_um"], overall["Mn_um"],
        overall["Sd_um"], overall["Mn_val_um"], overall["Mn_rms_um"],
    )  # fmt: skip
    return 0

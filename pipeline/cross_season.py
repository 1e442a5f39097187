"""The cross-season protocol: build a model on each training campaign, apply it to every campaign.

From the PCDL paper (Miao et al. 2016, section 4.2): a model Mi built on batch Ki is applied to
every batch; its fit accuracy is scored on Ki, its prediction accuracy on the other training
batches and on the validation batches (section 5). Splits follow campaigns (and so seasons),
never random samples. Scores are defined in :mod:`pipeline.scoring`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from sklearn.base import RegressorMixin, clone

from pipeline.scoring import residual_std, root_mean_square

TARGET = "thermal_error_um"


@dataclass(frozen=True)
class CampaignSeries:
    """One campaign's time series, ordered by time.

    Attributes
    ----------
    campaign_id : str
    split : str
        ``train`` or ``validation``.
    elapsed_s : ndarray of shape (n,)
        Seconds since the campaign start.
    features : DataFrame of shape (n, m)
        Model inputs (temperature or temperature rise per sensor), degC or K.
    target : ndarray of shape (n,)
        Thermal error, um.
    """

    campaign_id: str
    split: str
    elapsed_s: np.ndarray
    features: pd.DataFrame
    target: np.ndarray


@dataclass(frozen=True)
class FittedOnCampaign:
    """A model fitted on one training campaign and its scores on every campaign."""

    train_campaign: str
    sensors: list[str]
    estimator: RegressorMixin
    scores: pd.DataFrame
    predictions: dict[str, np.ndarray]


def campaign_series(
    table: pd.DataFrame, sensors: list[str], feature_prefix: str
) -> list[CampaignSeries]:
    """Split the separated spindle table into per-campaign series.

    Parameters
    ----------
    table : DataFrame
        ``data/separated/spindle_thermal_error.parquet``.
    sensors : list of str
        Sensor names; the feature column of sensor ``s`` is ``feature_prefix + s``.
    feature_prefix : str
        ``"rise_"`` for temperature rises, ``""`` for absolute temperatures.
    """
    series = []
    for campaign_id, rows in table.groupby("campaign_id", sort=True):
        rows = rows.sort_values("elapsed_s")
        columns = {s: rows[feature_prefix + s] if feature_prefix + s in rows else np.nan
                   for s in sensors}  # fmt: skip
        series.append(
            CampaignSeries(
                campaign_id=str(campaign_id),
                split=str(rows["split"].iloc[0]),
                elapsed_s=rows["elapsed_s"].to_numpy(),
                features=pd.DataFrame(columns, index=rows.index).astype(float),
                target=rows[TARGET].to_numpy(dtype=float),
            )
        )
    return series


def available_sensors(series: CampaignSeries) -> list[str]:
    """Sensors with at least one reading in a campaign (selection ``all``)."""
    return [s for s in series.features.columns if series.features[s].notna().any()]


def fit_and_score(
    train: CampaignSeries,
    campaigns: list[CampaignSeries],
    estimator: RegressorMixin,
    sensors: list[str],
) -> FittedOnCampaign:
    """Fit ``estimator`` on ``train`` using ``sensors`` and score it on every campaign.

    Rows with a missing feature or target are left out of the fit; a prediction is NaN where a
    feature is missing, and the scores use the remaining samples. A campaign lacking one of the
    sensors gets NaN scores (``n_samples`` 0).

    Returns
    -------
    FittedOnCampaign
        ``scores`` has one row per campaign: ``test_campaign``, ``test_split``, ``role``,
        ``n_samples``, ``rmse_um``, ``resid_std_um``.
    """
    X = train.features[sensors].to_numpy()
    usable = np.isfinite(X).all(axis=1) & np.isfinite(train.target)
    model = clone(estimator).fit(X[usable], train.target[usable])
    rows, predictions = [], {}
    for test in campaigns:
        predicted = _predict(model, test.features.reindex(columns=sensors).to_numpy())
        residual = test.target - predicted
        predictions[test.campaign_id] = predicted
        role = ("fit" if test.campaign_id == train.campaign_id
                else "prediction" if test.split == "train" else "validation")  # fmt: skip
        rows.append({
            "train_campaign": train.campaign_id,
            "test_campaign": test.campaign_id,
            "test_split": test.split,
            "role": role,
            "n_samples": int(np.isfinite(residual).sum()),
            "rmse_um": root_mean_square(residual),
            "resid_std_um": residual_std(residual),
        })  # fmt: skip
    return FittedOnCampaign(train.campaign_id, sensors, model, pd.DataFrame(rows), predictions)


def _predict(model: RegressorMixin, X: np.ndarray) -> np.ndarray:
    predicted = np.full(X.shape[0], np.nan)
    complete = np.isfinite(X).all(axis=1)
    if complete.any():
        predicted[complete] = model.predict(X[complete])
    return predicted


def cross_season(
    campaigns: list[CampaignSeries],
    make_estimator: Callable[[], RegressorMixin],
    select: Callable[[CampaignSeries], list[str]],
    n_jobs: int = 1,
) -> list[FittedOnCampaign]:
    """Build one model per training campaign and score each on every campaign.

    Parameters
    ----------
    campaigns : list of CampaignSeries
        Training and validation campaigns.
    make_estimator : callable
        Returns a new unfitted scikit-learn estimator.
    select : callable
        Chooses the sensors from the training campaign (sees no other campaign).
    n_jobs : int
        Training campaigns processed in parallel (joblib threads).
    """
    training = [c for c in campaigns if c.split == "train"]
    if not training:
        raise ValueError(
            "no training campaign among the valid campaigns "
            f"({[c.campaign_id for c in campaigns]}); mark at least one campaign split: train"
        )
    estimator = make_estimator()
    jobs = (delayed(fit_and_score)(t, campaigns, estimator, select(t)) for t in training)
    return list(Parallel(n_jobs=n_jobs, prefer="threads")(jobs))

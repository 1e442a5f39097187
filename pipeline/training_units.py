"""Training units of the cross-season protocol and the model inputs built from them.

A *training unit* is the set of campaigns one model is built on:

- scheme ``campaign``: one training campaign (the PCDL paper, Miao et al. 2016, section 4.2: a
  model Mi built on batch Ki, applied to every batch);
- scheme ``season``: leave one season out, all training campaigns of the three other seasons
  (unit ``not_<season>``), applied to the held-out season and the validation campaigns;
- scheme ``pooled``: every training campaign (unit ``all_training``), the model a user deploys;
  it is the one registered as MLflow champion.

Splits follow campaigns and seasons, never random samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

TARGET = "thermal_error_um"
INDEX_NAMES = ("campaign_id", "elapsed_s")
POOLED_UNIT = "all_training"


@dataclass(frozen=True)
class CampaignSeries:
    """One campaign's time series, ordered by time.

    Attributes
    ----------
    campaign_id : str
    split : str
        ``train`` or ``validation``.
    season : str
    features : DataFrame of shape (n, m)
        Model inputs per sensor (temperature rise, K, or temperature, degC), indexed by
        (``campaign_id``, ``elapsed_s``).
    target : ndarray of shape (n,)
        Thermal error, um.
    """

    campaign_id: str
    split: str
    season: str
    features: pd.DataFrame
    target: np.ndarray


@dataclass(frozen=True)
class TrainingUnit:
    """The campaigns one model is built on.

    Attributes
    ----------
    name : str
        ``K01`` (a campaign), ``not_summer`` (leave-one-season-out) or ``all_training``.
    scheme : str
        ``campaign``, ``season`` or ``pooled``.
    campaigns : tuple of str
        Campaign ids, in time order of the table.
    """

    name: str
    scheme: str
    campaigns: tuple[str, ...]


def campaign_series(
    table: pd.DataFrame, sensors: list[str], feature_prefix: str
) -> list[CampaignSeries]:
    """Split the separated spindle table into per-campaign series.

    Parameters
    ----------
    table : DataFrame
        ``data/separated/spindle_thermal_error.parquet``.
    sensors : list of str
        Sensor names; the feature column of sensor ``s`` is ``feature_prefix + s`` (NaN when the
        table lacks it).
    feature_prefix : str
        ``"rise_"`` for temperature rises, ``""`` for absolute temperatures.
    """
    series = []
    for campaign_id, rows in table.groupby("campaign_id", sort=True):
        rows = rows.sort_values("elapsed_s")
        index = pd.MultiIndex.from_arrays(
            [np.full(len(rows), str(campaign_id)), rows["elapsed_s"].to_numpy(dtype=float)],
            names=INDEX_NAMES,
        )
        columns = {
            s: rows[feature_prefix + s].to_numpy(dtype=float)
            if feature_prefix + s in rows
            else np.full(len(rows), np.nan)
            for s in sensors
        }
        series.append(
            CampaignSeries(
                campaign_id=str(campaign_id),
                split=str(rows["split"].iloc[0]),
                season=str(rows["season"].iloc[0]),
                features=pd.DataFrame(columns, index=index),
                target=rows[TARGET].to_numpy(dtype=float),
            )
        )
    return series


def training_units(series: list[CampaignSeries]) -> list[TrainingUnit]:
    """Every training unit of the protocol: each campaign, each season left out, all pooled.

    Leave-one-season-out units exist only when the training campaigns span two seasons or more.

    Raises
    ------
    ValueError
        If no campaign has split ``train``.
    """
    training = [s for s in series if s.split == "train"]
    if not training:
        raise ValueError(
            "no training campaign among the valid campaigns "
            f"({[s.campaign_id for s in series]}); mark at least one campaign split: train"
        )
    units = [TrainingUnit(s.campaign_id, "campaign", (s.campaign_id,)) for s in training]
    seasons = list(dict.fromkeys(s.season for s in training))
    if len(seasons) >= 2:
        for season in seasons:
            kept = tuple(s.campaign_id for s in training if s.season != season)
            units.append(TrainingUnit(f"not_{season}", "season", kept))
    units.append(TrainingUnit(POOLED_UNIT, "pooled", tuple(s.campaign_id for s in training)))
    return units


def stack(series: list[CampaignSeries], sensors: list[str]) -> tuple[pd.DataFrame, np.ndarray]:
    """Concatenate campaigns into one model input, keeping only complete rows.

    Rows where a chosen sensor or the target is missing are left out; the remaining rows of a
    campaign stay in time order (the series models see the gap closed).

    Returns
    -------
    X : DataFrame of shape (n, len(sensors))
        Indexed by (``campaign_id``, ``elapsed_s``); campaigns are contiguous blocks.
    y : ndarray of shape (n,)
        Thermal error, um.
    """
    frames, targets = [], []
    for item in series:
        X = item.features[sensors]
        complete = X.notna().all(axis=1).to_numpy() & np.isfinite(item.target)
        frames.append(X[complete])
        targets.append(item.target[complete])
    return pd.concat(frames), np.concatenate(targets)

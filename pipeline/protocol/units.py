"""Training units of the cross-season protocol and the model inputs built from them.

A *training unit* is the set of campaigns one model is built on:

- scheme ``campaign``: one training campaign (the PCDL paper, Miao et al. 2016, section 4.2: a
  model Mi built on batch Ki, applied to every batch);
- scheme ``loso``: leave one season out, all training campaigns of the other seasons (unit
  ``not_<season>``), applied to the held-out season and the validation campaigns; when the
  training campaigns span a single season, scheme ``loco`` instead: leave one campaign out
  (unit ``not_<campaign>``). Either is the *selection protocol*: a fit on several campaigns,
  like the deployed one, scored on campaigns it has not seen; the champion is chosen on it;
- scheme ``pooled``: every training campaign (unit ``all_training``), the model a user deploys;
  it is the one registered as MLflow champion.

Splits follow campaigns and seasons, never random samples. Each displacement axis has its own
series (:func:`series_by_axis`); the units are the same for every axis that has the same
campaigns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.errors import InputDataError
from pipeline.separation.features import input_column, input_names

TARGET = "thermal_error_um"
INDEX_NAMES = ("campaign_id", "elapsed_s")
POOLED_UNIT = "all_training"
CAMPAIGN, LOSO, LOCO, POOLED = "campaign", "loso", "loco", "pooled"
SCHEMES = (CAMPAIGN, LOSO, LOCO, POOLED)
HELD_OUT_SCHEMES = (LOSO, LOCO)
PROTOCOL_NAMES = {LOSO: "leave-one-season-out", LOCO: "leave-one-campaign-out"}


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
        Model inputs (temperature rise, K, or temperature, degC, per sensor; speed responses),
        indexed by (``campaign_id``, ``elapsed_s``).
    target : ndarray of shape (n,)
        Thermal error, um.
    axis : str
        Displacement axis of the target.
    run_id : str
        The run the campaign belongs to (:mod:`pipeline.separation.runs`).
    warm_start : bool
        Whether the campaign starts away from its run's reference.
    """

    campaign_id: str
    split: str
    season: str
    features: pd.DataFrame
    target: np.ndarray
    axis: str = "Z"
    run_id: str = ""
    warm_start: bool = False


@dataclass(frozen=True)
class TrainingUnit:
    """The campaigns one model is built on.

    Attributes
    ----------
    name : str
        ``K01`` (a campaign), ``not_summer`` (leave-one-season-out), ``not_K03``
        (leave-one-campaign-out) or ``all_training``.
    scheme : str
        ``campaign``, ``loso``, ``loco`` or ``pooled``.
    campaigns : tuple of str
        Campaign ids, in time order of the table.
    """

    name: str
    scheme: str
    campaigns: tuple[str, ...]


def campaign_series(table: pd.DataFrame, inputs: list[str], features: str) -> list[CampaignSeries]:
    """Split one axis' rows of the separated spindle table into per-campaign series.

    Parameters
    ----------
    table : DataFrame
        Rows of ``data/separated/spindle_thermal_error.parquet`` for one axis.
    inputs : list of str
        Input names: sensors and speed responses (:func:`pipeline.separation.features.input_names`);
        NaN when the table lacks the column.
    features : str
        ``temperature_rise`` (sensor inputs from the ``rise_`` columns) or ``absolute``.
    """
    series = []
    for campaign_id, rows in table.groupby("campaign_id", sort=True):
        rows = rows.sort_values("elapsed_s")
        index = pd.MultiIndex.from_arrays(
            [np.full(len(rows), str(campaign_id)), rows["elapsed_s"].to_numpy(dtype=float)],
            names=INDEX_NAMES,
        )
        columns = {}
        for name in inputs:
            column = input_column(name, features)
            columns[name] = (
                rows[column].to_numpy(dtype=float) if column in rows else np.full(len(rows), np.nan)
            )
        series.append(
            CampaignSeries(
                campaign_id=str(campaign_id),
                split=str(rows["split"].iloc[0]),
                season=str(rows["season"].iloc[0]),
                features=pd.DataFrame(columns, index=index),
                target=rows[TARGET].to_numpy(dtype=float),
                axis=str(rows["axis"].iloc[0]) if "axis" in rows else "Z",
                run_id=str(rows["run_id"].iloc[0]) if "run_id" in rows else str(campaign_id),
                warm_start=bool(rows["warm_start"].iloc[0]) if "warm_start" in rows else False,
            )
        )
    return series


def series_by_axis(table: pd.DataFrame, features: str) -> dict[str, list[CampaignSeries]]:
    """Per-campaign series of every axis of the separated table, axes in table order."""
    inputs = input_names(list(table.columns), features)
    return {
        str(axis): campaign_series(rows, inputs, features)
        for axis, rows in table.groupby("axis", sort=False)
    }


def training_units(series: list[CampaignSeries]) -> list[TrainingUnit]:
    """Every training unit of the protocol: each campaign, each season or campaign left out, all.

    Leave-one-season-out units exist when the training campaigns span two seasons or more;
    otherwise leave-one-campaign-out units, when there are two training campaigns or more.

    Raises
    ------
    ValueError
        If no campaign has split ``train``.
    """
    training = [s for s in series if s.split == "train"]
    if not training:
        raise InputDataError(
            "no training campaign among the valid campaigns "
            f"({[s.campaign_id for s in series]}); mark at least one campaign split: train"
        )
    units = [TrainingUnit(s.campaign_id, CAMPAIGN, (s.campaign_id,)) for s in training]
    seasons = list(dict.fromkeys(s.season for s in training))
    if len(seasons) >= 2:
        for season in seasons:
            kept = tuple(s.campaign_id for s in training if s.season != season)
            units.append(TrainingUnit(f"not_{season}", LOSO, kept))
    elif len(training) >= 2:
        for left_out in training:
            kept = tuple(s.campaign_id for s in training if s is not left_out)
            units.append(TrainingUnit(f"not_{left_out.campaign_id}", LOCO, kept))
    units.append(TrainingUnit(POOLED_UNIT, POOLED, tuple(s.campaign_id for s in training)))
    return units


def protocol_scheme(units: list[TrainingUnit]) -> str | None:
    """Return the held-out scheme of these units (``loso`` or ``loco``); None if there is none."""
    return next((u.scheme for u in units if u.scheme in HELD_OUT_SCHEMES), None)


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

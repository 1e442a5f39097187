"""Training units of the cross-season protocol and the model inputs built from them.

A *training unit* is the set of campaigns one model is built on:

- scheme ``campaign``: one training campaign (the PCDL paper, Miao et al. 2016, section 4.2: a
  model Mi built on batch Ki, applied to every batch);
- scheme ``loso``: leave one season out, all training campaigns of the other seasons (unit
  ``not_<season>``), applied to the held-out season and the validation campaigns; when the
  training campaigns span a single season, scheme ``loco`` instead: leave one campaign out
  (unit ``not_<campaign>``);
- scheme ``forward``: rolling origin (Tashman 2000, "Out-of-sample tests of forecasting
  accuracy: an analysis and review", International Journal of Forecasting 16(4); Bergmeir and
  Benitez 2012, "On the use of cross-validation for time series predictor evaluation",
  Information Sciences 191): campaigns in the order of their start, each one predicted by a
  fit on the training campaigns that *ended before it started* (unit ``before_<campaign>``),
  and scored on the campaigns it forecasts: what a model trained up to now leaves on the next
  campaigns. Only forecasts whose fit has at least ``forward_min_share`` of the training
  campaigns (and at least ``forward_min_train``) count: the registered model is fitted on all
  of them, and a forecast from a fit on far fewer campaigns says more about learning from
  little data than about the model that will run (Tashman 2000, section 2, on the length of
  the fit period).
  Every such forecast counts, with at most ``forward_max_origins`` fits: the forecast
  campaigns, in time order, are split into that many consecutive blocks, each forecast by one
  fit on the campaigns that ended before the block's first campaign started, as scikit-learn's
  ``TimeSeriesSplit`` forecasts a block of samples per split with a fixed number of splits.
  One fit per forecast campaign would make the cost grow with the campaigns squared; a fixed
  number of fits, each on at most every campaign, keeps it linear. Deviation from Tashman
  (2000), who recommends recalibrating the model at every origin: only each block's first
  campaign is forecast from a fit recalibrated just before it; a later campaign of the block is
  forecast from a few campaigns further back than a model retrained on each new campaign would
  be, so its score errs on the pessimistic side. The earlier blocks are the larger ones: the
  latest forecasts are the closest to the retrained model;
- scheme ``pooled``: every training campaign (unit ``all_training``), the model a user deploys;
  it is the one registered as MLflow champion.

**Buffer (hv-block).** Campaigns cut from one continuous record (a *run*,
:mod:`pipeline.separation.runs`) are not independent: the hours just before and after a
held-out campaign carry its thermal state. Leave-one-out schemes (``loso``, ``loco``) therefore
also leave out of training the ``buffer_campaigns`` campaigns of the same run on either side of
each held-out campaign, as hv-block cross-validation leaves h observations on either side of the
validation block (Racine 2000, "Consistent cross-validatory model-selection for dependent data:
hv-block cross-validation", Journal of Econometrics 99(1)); a unit left with no campaign is
dropped. Here the block is a whole campaign, not h samples: a campaign is the unit a user adds
and the unit the deployed model is applied to.

**At most** ``max_folds`` **leave-out fits.** With more seasons (``loso``) or campaigns
(``loco``) than ``max_folds``, consecutive groups in time order are left out together in that
many blocks (unit ``not_<first>_to_<last>``): blocked K-fold cross-validation (Bergmeir and
Benitez 2012), with the ten folds Kohavi (1995, "A study of cross-validation and bootstrap for
accuracy estimation and model selection", IJCAI) recommends. Leaving each campaign out alone
would fit the campaigns n times on n - 1 of them, a cost that grows with the campaigns squared;
K blocks cost at most K fits on all of them. The hv-block buffer is left out on either side of
the whole block.

Splits follow campaigns, seasons and time, never random samples. Each displacement axis has its
own series (:func:`series_by_axis`); the units are the same for every axis that has the same
campaigns.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.errors import InputDataError
from pipeline.separation.features import input_column, input_names
from pipeline.settings.protocol import ProtocolSettings

LOGGER = logging.getLogger(__name__)

TARGET = "thermal_error_um"
HELD_OUT_PREFIX = "not_"
INDEX_NAMES = ("campaign_id", "elapsed_s")
POOLED_UNIT = "all_training"
FORWARD_PREFIX = "before_"
CAMPAIGN, LOSO, LOCO, FORWARD, POOLED = "campaign", "loso", "loco", "forward", "pooled"
SCHEMES = (CAMPAIGN, LOSO, LOCO, FORWARD, POOLED)
HELD_OUT_SCHEMES = (LOSO, LOCO, FORWARD)
PROTOCOL_NAMES = {
    LOSO: "leave-one-season-out",
    LOCO: "leave-one-campaign-out",
    FORWARD: "rolling origin (forward in time)",
}


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
    start : Timestamp or None
        Local time of ``elapsed_s`` = 0 (campaign.yaml ``start``); None when unknown.
    """

    campaign_id: str
    split: str
    season: str
    features: pd.DataFrame
    target: np.ndarray
    axis: str = "Z"
    run_id: str = ""
    warm_start: bool = False
    start: pd.Timestamp | None = None

    @property
    def first_time(self) -> pd.Timestamp | None:
        """Local time of the first sample; None when ``start`` is unknown."""
        return None if self.start is None else self.start + pd.Timedelta(seconds=self._elapsed(0))

    @property
    def last_time(self) -> pd.Timestamp | None:
        """Local time of the last sample; None when ``start`` is unknown."""
        return None if self.start is None else self.start + pd.Timedelta(seconds=self._elapsed(-1))

    def _elapsed(self, position: int) -> float:
        elapsed = self.features.index.get_level_values("elapsed_s")
        return float(elapsed[position]) if len(elapsed) else 0.0


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
    tests : tuple of str
        The campaigns a fit on this unit is scored on; empty: every campaign. A ``forward``
        unit is scored on the campaign it forecasts only.
    """

    name: str
    scheme: str
    campaigns: tuple[str, ...]
    tests: tuple[str, ...] = ()

    def scores(self, campaign_id: str) -> bool:
        """Whether a fit on this unit is scored on ``campaign_id``."""
        return not self.tests or campaign_id in self.tests


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
                start=_start_of(rows),
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


def training_units(
    series: list[CampaignSeries], settings: ProtocolSettings | None = None
) -> list[TrainingUnit]:
    """Every training unit of the protocol: each campaign, the held-out schemes, all.

    Leave-one-season-out units exist when the training campaigns span two seasons or more;
    otherwise leave-one-campaign-out units, when there are two training campaigns or more;
    both leave out the hv-block buffer (``protocol.buffer_campaigns``), in at most
    ``protocol.max_folds`` units (:func:`held_out_blocks`). Forward units forecast the training
    campaigns with enough training campaigns ended before them, in at most
    ``forward_max_origins`` fits (:func:`forward_units`; start times known).

    Raises
    ------
    InputDataError
        If no campaign has split ``train``.
    """
    settings = settings or ProtocolSettings()
    training = [s for s in series if s.split == "train"]
    if not training:
        raise InputDataError(
            "no training campaign among the valid campaigns "
            f"({[s.campaign_id for s in series]}); mark at least one campaign split: train"
        )
    units = [TrainingUnit(s.campaign_id, CAMPAIGN, (s.campaign_id,)) for s in training]
    seasons = list(dict.fromkeys(s.season for s in training))
    if len(seasons) >= 2:
        groups = [(season, [s for s in training if s.season == season]) for season in seasons]
        groups = held_out_blocks(groups, settings.max_folds)
        units += _leave_out_units(series, groups, LOSO, settings.buffer_campaigns)
    elif len(training) >= 2:
        groups = held_out_blocks([(s.campaign_id, [s]) for s in training], settings.max_folds)
        units += _leave_out_units(series, groups, LOCO, settings.buffer_campaigns)
    least = max(settings.forward_min_train, math.ceil(settings.forward_min_share * len(training)))
    units += forward_units(training, least, settings.forward_max_origins)
    units.append(TrainingUnit(POOLED_UNIT, POOLED, tuple(s.campaign_id for s in training)))
    return units


def buffer_of(
    training: list[CampaignSeries], held_out: list[CampaignSeries], buffer: int
) -> set[str]:
    """Campaigns of the held-out campaigns' runs within ``buffer`` places of one of them.

    Parameters
    ----------
    training : list of CampaignSeries
        Every training campaign.
    held_out : list of CampaignSeries
        The campaigns left out of a unit.
    buffer : int
        Places on either side, in the run's time order.
    """
    if buffer <= 0:
        return set()
    runs: dict[str, list[CampaignSeries]] = {}
    for item in training:
        runs.setdefault(item.run_id or item.campaign_id, []).append(item)
    for members in runs.values():
        members.sort(key=_time_key)
    near = set()
    for item in held_out:
        members = runs[item.run_id or item.campaign_id]
        place = [m.campaign_id for m in members].index(item.campaign_id)
        low, high = max(place - buffer, 0), place + buffer + 1
        near |= {m.campaign_id for m in members[low:high]}
    return near - {item.campaign_id for item in held_out}


def _leave_out_units(
    series: list[CampaignSeries],
    groups: list[tuple[str, list[CampaignSeries]]],
    scheme: str,
    buffer: int,
) -> list[TrainingUnit]:
    """One unit per held-out group; the buffer campaigns are neither fitted nor scored."""
    training = [s for s in series if s.split == "train"]
    units = []
    for name, held_out in groups:
        buffered = buffer_of(training, held_out, buffer)
        dropped = buffered | {s.campaign_id for s in held_out}
        kept = tuple(s.campaign_id for s in training if s.campaign_id not in dropped)
        if not kept:
            LOGGER.info(
                "unit not_%s dropped: with its buffer of %d campaign(s) on either side in its "
                "run, no training campaign is left",
                name,
                buffer,
            )
            continue
        tests = tuple(s.campaign_id for s in series if s.campaign_id not in buffered)
        units.append(
            TrainingUnit(f"{HELD_OUT_PREFIX}{name}", scheme, kept, tests if buffered else ())
        )
    return units


def held_out_blocks(
    groups: list[tuple[str, list[CampaignSeries]]], max_folds: int
) -> list[tuple[str, list[CampaignSeries]]]:
    """Return the groups to leave out one at a time, above ``max_folds`` in consecutive blocks.

    Parameters
    ----------
    groups : list of (str, list of CampaignSeries)
        Name (season or campaign id) and campaigns of each group.
    max_folds : int
        Units at most.

    Returns
    -------
    list of (str, list of CampaignSeries)
        ``groups`` unchanged when there are at most ``max_folds``; otherwise ``max_folds``
        blocks of groups consecutive in the time order of their first campaigns (sizes differing
        by one at most), named ``<first>_to_<last>``.
    """
    if len(groups) <= max_folds:
        return groups
    ordered = sorted(groups, key=lambda group: min(_time_key(s) for s in group[1]))
    return [
        (
            part[0][0] if len(part) == 1 else f"{part[0][0]}_to_{part[-1][0]}",
            [member for _, members in part for member in members],
        )
        for part in _consecutive_blocks(ordered, max_folds)
    ]


def forward_units(
    training: list[CampaignSeries], min_train: int, max_origins: int
) -> list[TrainingUnit]:
    """Rolling-origin units: the campaigns forecast by the campaigns that ended before them.

    Parameters
    ----------
    training : list of CampaignSeries
        The training campaigns; those without a start time take no part.
    min_train : int
        Campaigns a unit must be built on.
    max_origins : int
        Fits at most: above this many forecast campaigns, consecutive ones share the fit of the
        first of them (the earlier blocks the larger).

    Returns
    -------
    list of TrainingUnit
        ``before_<campaign>``, scheme ``forward``, built on the campaigns that ended before
        ``<campaign>`` started, ``tests`` that campaign and those of its block, in the order of
        the campaigns' first samples.
    """
    timed = sorted((s for s in training if s.start is not None), key=_time_key)
    forecasts = []
    for target in timed:
        before = tuple(s.campaign_id for s in timed if s.last_time < target.first_time)
        if len(before) >= min_train:
            forecasts.append((target.campaign_id, before))
    return [
        TrainingUnit(
            f"{FORWARD_PREFIX}{block[0][0]}",
            FORWARD,
            block[0][1],
            tuple(campaign for campaign, _ in block),
        )
        for block in _consecutive_blocks(forecasts, max_origins)
    ]


def _consecutive_blocks(items: list, most: int) -> list[list]:
    """Split ``items`` in order into at most ``most`` non-empty blocks, the earlier the larger.

    Block sizes differ by one at most.
    """
    return [
        [items[place] for place in places]
        for places in np.array_split(np.arange(len(items)), most)
        if len(places)
    ]


def _time_key(item: CampaignSeries) -> tuple:
    first = item.first_time
    return (first is None, first if first is not None else pd.Timestamp(0), item.campaign_id)


def _start_of(rows: pd.DataFrame) -> pd.Timestamp | None:
    if "campaign_start" not in rows or pd.isna(rows["campaign_start"].iloc[0]):
        return None
    return pd.Timestamp(rows["campaign_start"].iloc[0])


def held_out_schemes(units: list[TrainingUnit]) -> list[str]:
    """Return the held-out schemes these units have, in :data:`HELD_OUT_SCHEMES` order."""
    present = {u.scheme for u in units}
    return [scheme for scheme in HELD_OUT_SCHEMES if scheme in present]


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

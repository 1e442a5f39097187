"""Pandera models of the tables written by ``separate`` (``data/separated/``).

Sensor columns (degC, one per temperature sensor, named as in campaign.yaml) vary by campaign:
the models allow extra columns; add them explicitly with :func:`with_sensor_columns`.
"""

from __future__ import annotations

from collections.abc import Iterable

import pandas as pd
import pandera.pandas as pa
from pandera.typing import Series

from schemas import checks
from schemas.ingested import SamplesModel
from schemas.vocabulary import SEASONS, SPLITS


class SpindleThermalErrorModel(SamplesModel):
    """``spindle_thermal_error.parquet``: one row per (axis, aligned sample) of a spindle campaign.

    The samples columns plus ``machine`` (the machine of the campaign: each machine is
    separated on its own), ``axis`` (the displacement axis of the row), ``run_id`` (the first
    campaign of the run the campaign belongs to) and ``run_elapsed_s`` (s since that run's
    start), ``campaign_start`` (the campaign's ``start``: the time order of the forward
    scheme), the campaign's split and season, ``warm_start`` (the campaign does not start from
    its run's reference), ``reference`` (what the error is counted from, in words),
    ``displacement_um`` (stitched across re-zeroed cuts) and ``thermal_error_um`` =
    ``displacement_um`` minus its value at the run's reference (um); sensor columns (degC),
    their ``rise_<sensor>`` twins (K) and the speed responses vary by campaign. Time strictly
    increases within each (axis, campaign).
    """

    machine: Series[str] | None
    axis: Series[str]
    run_id: Series[str]
    run_elapsed_s: Series[float]
    campaign_start: Series[pd.Timestamp] | None = pa.Field(nullable=True)
    split: Series[str] = pa.Field(isin=SPLITS)
    season: Series[str] = pa.Field(isin=SEASONS)
    synthetic: Series[bool]
    warm_start: Series[bool]
    reference: Series[str]
    thermal_error_um: Series[float]
    displacement_um: Series[float]

    @pa.dataframe_check
    @classmethod
    def time_increasing(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that ``elapsed_s`` strictly increases within each axis and campaign."""
        return checks.increasing_within(df["elapsed_s"], df["axis"] + "/" + df["campaign_id"])


class AxisSlopesModel(pa.DataFrameModel):
    """``axis_slopes.parquet``: one row per pass (elapsed_min) of an axis campaign.

    After the geometric error (cold pass polynomial over position) is removed, the thermal
    positioning error of a pass is fitted by a line over position (the patent's slope method):
    ``e(x) = intercept_um + slope_um_per_mm * x``. Temperatures at the pass (degC) follow as
    extra columns, named as in campaign.yaml. ``machine``: each machine is separated on its own.
    """

    machine: Series[str] | None
    campaign_id: Series[str]
    axis_name: Series[str]
    split: Series[str] = pa.Field(isin=SPLITS)
    season: Series[str] = pa.Field(isin=SEASONS)
    synthetic: Series[bool]
    elapsed_min: Series[float] = pa.Field(ge=0)
    slope_um_per_mm: Series[float]
    intercept_um: Series[float]

    class Config:
        """Sensor columns vary by campaign."""

        strict = False

    @pa.dataframe_check
    @classmethod
    def one_row_per_pass(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that a pass (campaign, elapsed_min) has one slope."""
        return ~df.duplicated(["campaign_id", "elapsed_min"], keep=False)


def with_sensor_columns(
    schema: pa.DataFrameSchema, sensors: Iterable[str], nullable: bool = True
) -> pa.DataFrameSchema:
    """Return ``schema`` with one float64 temperature column (degC) per sensor name added.

    Parameters
    ----------
    schema : pandera DataFrameSchema
        E.g. ``SpindleThermalErrorModel.to_schema()``; not modified.
    sensors : iterable of str
        Sensor column names.
    nullable : bool
        Whether missing readings are allowed.

    Returns
    -------
    pandera DataFrameSchema
    """
    return schema.add_columns({str(s): pa.Column(float, nullable=nullable) for s in sensors})

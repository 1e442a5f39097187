"""Pandera models of every table that crosses a stage boundary.

- ingested / validated tables (:mod:`schemas.ingested`): campaigns, samples (spindle and axis
  variants, plus per-campaign sensor and displacement columns), laser runs, ingest problems;
- separated tables (:mod:`schemas.separated`): spindle thermal error, axis slopes;
- evaluated tables (:mod:`schemas.evaluated`): cross-season scores.

Check names are the problem ids ``validate`` reports (``reports/validation.json``).
"""

from schemas.evaluated import SCORE_ROLES, CrossSeasonScoresModel
from schemas.ingested import (
    DATAFRAME_CHECK_COLUMNS,
    AxisSamplesModel,
    CampaignsModel,
    LaserModel,
    ProblemsModel,
    SamplesModel,
    SensorsModel,
    SpindleSamplesModel,
    ValidationLimits,
    campaign_samples_schema,
    displacement_columns,
    laser_schema,
    parse_json,
    sensor_columns,
)
from schemas.separated import AxisSlopesModel, SpindleThermalErrorModel, with_sensor_columns

__all__ = [
    "DATAFRAME_CHECK_COLUMNS",
    "SCORE_ROLES",
    "AxisSamplesModel",
    "AxisSlopesModel",
    "CampaignsModel",
    "CrossSeasonScoresModel",
    "LaserModel",
    "ProblemsModel",
    "SamplesModel",
    "SensorsModel",
    "SpindleSamplesModel",
    "SpindleThermalErrorModel",
    "ValidationLimits",
    "campaign_samples_schema",
    "displacement_columns",
    "laser_schema",
    "parse_json",
    "sensor_columns",
    "with_sensor_columns",
]

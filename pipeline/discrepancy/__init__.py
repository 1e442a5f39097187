"""Where the twin and the measurements disagree: calibrate, localise, name the missing effect."""

from pipeline.discrepancy.calibrate import Calibration, NoiseFloor, calibrate, predict
from pipeline.discrepancy.data import MeasuredCampaign, campaigns_from_tables
from pipeline.discrepancy.model import (
    EFFECTS,
    ParamSpec,
    Simulation,
    TwinModel,
    build_model,
    missing_roles,
)

__all__ = [
    "EFFECTS",
    "Calibration",
    "MeasuredCampaign",
    "NoiseFloor",
    "ParamSpec",
    "Simulation",
    "TwinModel",
    "build_model",
    "calibrate",
    "campaigns_from_tables",
    "missing_roles",
    "predict",
]

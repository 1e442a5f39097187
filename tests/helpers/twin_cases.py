"""Calibrated twins on small campaigns of the twin, shared by the discrepancy tests.

The campaigns are the generator's baseline (no campaign-to-campaign heat scatter) plus sensor
noise, so what a test finds in them is the method's, not the scatter's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime

from pipeline.discrepancy import MeasuredCampaign, build_model, calibrate
from pipeline.discrepancy.identifiability import IdentifiabilitySettings
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.thermal.program import Program, Segment
from pipeline.twin.campaigns import SpindlePlan, simulate_spindle_campaign
from pipeline.twin.params import SpindleParams
from tests.helpers.twin_measured import measured_from_twin

SECTION = load_settings(DiscrepancySettings, "discrepancy")
SETTINGS = IdentifiabilitySettings.from_settings(SECTION.identifiability)
NO_SCATTER = replace(SpindleParams(), heat_scatter_rel=0.0)


@dataclass(frozen=True)
class ConstantPlan(SpindlePlan):
    """One speed from the first sample to the last: no step, no stop."""

    def program(self) -> Program:
        """The constant speed, open-ended."""
        return Program((Segment(0.0, None, float(self.rpm)),), key="rpm")


def measured(plan: SpindlePlan) -> MeasuredCampaign:
    campaign = simulate_spindle_campaign(plan, seed=5, params=NO_SCATTER, effects=frozenset())
    return measured_from_twin(campaign)


def calibrated(campaigns: list[MeasuredCampaign]):
    roles = {r for c in campaigns for r in c.roles.values()}
    model = build_model(roles)
    fit = calibrate(model, campaigns, max_nfev=60)
    return model, fit, roles


def constant_speed_campaigns() -> list[MeasuredCampaign]:
    """Three 4 h campaigns at one constant 4000 rpm, a month apart, no cool-down."""
    plans = [
        ConstantPlan(f"C{i}", datetime(2024, 3 + i, 5, 8), 4000.0, run_min=240.0, cooldown_min=0)
        for i in range(3)
    ]
    return [measured(p) for p in plans]


def report_entry(status: str, signal: float, index: float, shortfalls: list[str]) -> dict:
    return {
        "class": status,
        "shortfalls": shortfalls,
        "collinearity_index": index,
        "collinearity_index_all_parameters": 1e6,
        "signal_sigma": signal,
        "signal_Z_sigma": signal,
        "signal_T_sigma": signal,
        "signal_Z_um": 0.05,
        "signal_T_K": 0.012,
        "response_Z_um": 0.6,
        "response_T_K": 0.23,
        "plausible_values": {"sensor_lag_s": {"value": 600.0, "unit": "s"}},
        "thresholds": SETTINGS.thresholds(),
    }

"""Physical twin of a machining centre's thermal behaviour (synthetic demo data).

A fixed machine on top of the thermal-network kernel (:mod:`pipeline.thermal`): a vertical
machining centre (spindle Z drift) and a linear axis (positioning error), driven by the
operating program and the workshop air, with the kernel's named, switchable physical effects.
Modules:

``params``     every parameter of the fixed machine, as frozen dataclasses (units in docstrings)
``effects``    the fixed machine's law for each term of the kernel's effect registry
``simulate``   runs the machine's network under a program, an ambient and the model's terms
``spindle``    :func:`simulate_spindle`
``axis``       :func:`simulate_axis`, :class:`AxisTruth`
``conditions`` campaign-to-campaign machine state no sensor sees (bearings, convection, warm
               start, probe mounting), drawn per campaign by the demo plans
``campaigns``  plans, measurement chain (sensors, probe, laser), demo set
``lateral``    X and Y drift terms of the spindle nose (workshop preset)
``instruments``
               placed sensors, eddy-current probes and speed log (workshop preset)
``workshop``   the workshop preset: one two-day run cut into six back-to-back campaigns
``writer``     :func:`write_campaign` in the raw campaign contract
``cli``        ``thermal simulate``
"""

from pipeline.thermal.effects import EFFECTS
from pipeline.thermal.program import Program
from pipeline.twin.ambient import AmbientProfile, AmbientSeries, Climate
from pipeline.twin.axis import AxisTruth, simulate_axis
from pipeline.twin.campaigns import (
    AxisCampaign,
    AxisPlan,
    SpindleCampaign,
    SpindlePlan,
    demo_campaigns,
    demo_plans,
    simulate_axis_campaign,
    simulate_spindle_campaign,
)
from pipeline.twin.effects import DEMO_EFFECTS, model_terms
from pipeline.twin.params import AxisParams, SensorSpec, SpindleParams
from pipeline.twin.spindle import simulate_spindle
from pipeline.twin.writer import write_campaign

__all__ = [
    "DEMO_EFFECTS",
    "EFFECTS",
    "AmbientProfile",
    "AmbientSeries",
    "AxisCampaign",
    "AxisParams",
    "AxisPlan",
    "AxisTruth",
    "Climate",
    "Program",
    "SensorSpec",
    "SpindleCampaign",
    "SpindleParams",
    "SpindlePlan",
    "demo_campaigns",
    "demo_plans",
    "model_terms",
    "simulate_axis",
    "simulate_axis_campaign",
    "simulate_spindle",
    "simulate_spindle_campaign",
    "write_campaign",
]

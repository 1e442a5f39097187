"""Campaign-to-campaign variation of the spindle machine's state that no sensor sees.

Two drift tests on the same machine at the same speed never give the same temperature-to-drift
relation, even when every sensor reads the same: the machine is not in the same state. A
:class:`StateScatter` says how much that state varies; :func:`draw_state` draws one
campaign's :class:`CampaignState` from the campaign's own generator and :func:`apply_state`
turns it into the machine parameters and the test conditions actually used. The draws are
part of the demo *plan* (what was done to the machine, how it was set up), not switchable
physical effects: the model is the same, only its state differs. They are written nowhere in
the campaign files (the ``notes:`` line only says, in general words, that the state varies).

Mechanisms (each one named, with its physical cause):

``bearing_state``
    Preload and lubrication of the spindle bearings (grease distribution after a stop, oil-air
    flow, preload drift after a crash or re-adjustment). The preload sets the friction heat
    (gain ``g_b``, log-normal) and the contact area of the rolling elements, i.e. the
    conductance between the rotating shaft and the bearing housings (gain ``g_c``); the
    lubricant sets which share ``s`` of the friction heat enters the shaft through the inner
    rings, and the oil-air exhaust through the bearings and the labyrinth sets how well the
    shaft is cooled (gain ``g_s`` on its convection). The shaft carries no sensor, so its
    temperature relative to the housings (about 2/3 of the Z drift) changes in a way the
    temperatures cannot show.
``motor_state``
    Small scatter of the spindle-motor loss (drive tuning, load of the tool holder), gain
    ``g_m``.
``season_convection``
    Convection coefficient of every surface by season: doors closed and no fans in winter,
    doors open and floor fans in summer (a factor per season, times a day-to-day jitter).
``warm_start``
    With a given probability the machine ran a job before the test (a night- or early-shift job
    of a few hours at one of the usual speeds, stopped 2-4 h before the start): the test starts
    partially warm, the spindle and headstock still cooling while the column and bed keep
    the heat (the twin's ``history=``). A run the previous afternoon would not do: after a
    night the twin's structure is within 0.1 K of cold (its slowest time constants are ~4 h).
``probe_mounting``
    The eddy-current probe is re-mounted for every campaign: a constant offset of the raw Z
    reading, irrelevant once the displacement is zeroed at the cold state.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.thermal.program import Program, Segment
from pipeline.twin.params import SpindleParams

SHAFT_LINKS = (("front_bearing", "spindle_shaft"), ("rear_bearing", "spindle_shaft"))
"""Network links through the rolling elements, scaled by the bearing contact gain."""


@dataclass(frozen=True)
class StateScatter:
    """How much the machine's unmeasured state varies between campaigns.

    Attributes
    ----------
    bearing_heat_sd : float
        Log-normal standard deviation of the common bearing friction heat gain (preload and
        lubrication), e.g. 0.12 = about +-12 % (1 sd).
    bearing_contact_sd : float
        Log-normal standard deviation of the shaft-housing conductance through the rolling
        elements (contact area set by the preload).
    shaft_share_sd : float
        Standard deviation of the share of the friction heat entering the shaft (absolute,
        around ``SpindleParams.bearing_heat_to_shaft``), clipped to ``shaft_share_range``.
    shaft_share_range : tuple of (float, float)
        Physical limits of that share.
    shaft_cooling_sd : float
        Log-normal standard deviation of the shaft's convection conductance (oil-air exhaust).
    motor_heat_sd : float
        Log-normal standard deviation of the spindle-motor loss.
    convection_by_season : tuple of (str, float)
        Convection factor applied to every surface, per season (``winter``, ``spring``,
        ``summer``, ``autumn``).
    convection_sd : float
        Log-normal day-to-day jitter of that factor.
    warm_start_probability : float
        Probability that the machine ran a job before the test, 0..1.
    warm_start_rpm : tuple of float
        Speeds it may have run at then, rpm (drawn uniformly).
    warm_start_hours : tuple of (float, float)
        Range of the running time then, h (uniform).
    warm_start_gap_hours : tuple of (float, float)
        Range of the time between that run's stop and the campaign start, h (uniform).
    probe_offset_sd_um : float
        Standard deviation of the probe re-mounting offset of the raw Z reading, um.
    """

    bearing_heat_sd: float = 0.0
    bearing_contact_sd: float = 0.0
    shaft_share_sd: float = 0.0
    shaft_share_range: tuple[float, float] = (0.15, 0.7)
    shaft_cooling_sd: float = 0.0
    motor_heat_sd: float = 0.0
    convection_by_season: tuple[tuple[str, float], ...] = (
        ("winter", 1.0),
        ("spring", 1.0),
        ("summer", 1.0),
        ("autumn", 1.0),
    )
    convection_sd: float = 0.0
    warm_start_probability: float = 0.0
    warm_start_rpm: tuple[float, ...] = (2000.0, 4000.0, 6000.0)
    warm_start_hours: tuple[float, float] = (1.0, 3.0)
    warm_start_gap_hours: tuple[float, float] = (2.0, 4.0)
    probe_offset_sd_um: float = 0.0

    def convection_factor(self, season: str) -> float:
        """Season's convection factor (1.0 for a season not listed)."""
        return dict(self.convection_by_season).get(season, 1.0)


DEMO_SCATTER = StateScatter(
    bearing_heat_sd=0.15,
    bearing_contact_sd=0.25,
    shaft_share_sd=0.15,
    shaft_cooling_sd=0.3,
    motor_heat_sd=0.05,
    convection_by_season=(("winter", 0.85), ("spring", 1.0), ("summer", 1.3), ("autumn", 1.0)),
    convection_sd=0.08,
    warm_start_probability=1.0 / 3.0,
    probe_offset_sd_um=30.0,
)
"""State scatter of the demo campaigns (and of ``thermal simulate --preset single``)."""


@dataclass(frozen=True)
class CampaignState:
    """The machine state drawn for one campaign (truth; never written to the files).

    Attributes
    ----------
    bearing_heat_gain : float
        Factor on both bearings' friction heat.
    bearing_contact_gain : float
        Factor on the shaft-housing conductances (:data:`SHAFT_LINKS`).
    shaft_share : float or None
        Share of the bearing friction heat entering the shaft, 0..1 (None = nominal).
    shaft_cooling_gain : float
        Factor on the shaft's convection conductance.
    motor_heat_gain : float
        Factor on the spindle-motor loss.
    convection_gain : float
        Factor on every convection conductance (season times jitter).
    history : Program or None
        Spindle speed before the start (negative minutes), None = cold start.
    probe_offset_um : float
        Constant added to the raw Z reading, um.
    """

    bearing_heat_gain: float = 1.0
    bearing_contact_gain: float = 1.0
    shaft_share: float | None = None
    shaft_cooling_gain: float = 1.0
    motor_heat_gain: float = 1.0
    convection_gain: float = 1.0
    history: Program | None = None
    probe_offset_um: float = 0.0

    @property
    def warm_start(self) -> bool:
        """True if the machine ran before the start."""
        return self.history is not None


def draw_state(
    scatter: StateScatter,
    params: SpindleParams,
    season: str,
    rng: np.random.Generator,
) -> CampaignState:
    """Draw one campaign's machine state.

    Always consumes the same random numbers in the same order (6 normals, then 4 uniforms, then
    1 normal), whatever the outcome, so a campaign's other draws never shift.

    Parameters
    ----------
    scatter : StateScatter
    params : SpindleParams
        Nominal machine (supplies the nominal shaft share).
    season : str
        The campaign's season (convection factor).
    rng : numpy.random.Generator
        The campaign's generator.

    Returns
    -------
    CampaignState
    """
    z = rng.standard_normal(6)
    u = rng.random(4)
    lo, hi = scatter.shaft_share_range
    share = float(np.clip(params.bearing_heat_to_shaft + scatter.shaft_share_sd * z[2], lo, hi))
    history = None
    if u[0] < scatter.warm_start_probability:
        rpm = scatter.warm_start_rpm[int(u[1] * len(scatter.warm_start_rpm))]
        hours = scatter.warm_start_hours[0] + u[2] * np.diff(scatter.warm_start_hours)[0]
        gap_h = scatter.warm_start_gap_hours[0] + u[3] * np.diff(scatter.warm_start_gap_hours)[0]
        end_min = round(float(-60.0 * gap_h), 1)
        from_min = round(float(end_min - 60.0 * hours), 1)
        history = Program((Segment(from_min, end_min, float(rpm)),), key="rpm")
    offset = scatter.probe_offset_sd_um * float(rng.standard_normal())
    return CampaignState(
        bearing_heat_gain=float(np.exp(scatter.bearing_heat_sd * z[0])),
        bearing_contact_gain=float(np.exp(scatter.bearing_contact_sd * z[1])),
        shaft_share=share,
        shaft_cooling_gain=float(np.exp(scatter.shaft_cooling_sd * z[5])),
        motor_heat_gain=float(np.exp(scatter.motor_heat_sd * z[3])),
        convection_gain=float(
            scatter.convection_factor(season) * np.exp(scatter.convection_sd * z[4])
        ),
        history=history,
        probe_offset_um=offset,
    )


def apply_state(params: SpindleParams, state: CampaignState) -> SpindleParams:
    """Return the machine parameters of a campaign in ``state`` (``params`` is not changed)."""
    net = params.network
    shaft_links = [set(pair) for pair in SHAFT_LINKS]
    links = tuple(
        (a, b, g * state.bearing_contact_gain if {a, b} in shaft_links else g)
        for a, b, g in net.links
    )
    net = replace(net, links=links)
    conv = [h * state.convection_gain for h in net.convection_w_per_k]
    conv[net.index("spindle_shaft")] *= state.shaft_cooling_gain
    net = replace(net, convection_w_per_k=tuple(conv))
    return replace(
        params,
        network=net,
        front_bearing_heat_w=params.front_bearing_heat_w * state.bearing_heat_gain,
        rear_bearing_heat_w=params.rear_bearing_heat_w * state.bearing_heat_gain,
        bearing_heat_to_shaft=(
            params.bearing_heat_to_shaft if state.shaft_share is None else state.shaft_share
        ),
        motor_heat_w=params.motor_heat_w * state.motor_heat_gain,
    )

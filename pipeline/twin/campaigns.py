"""Synthetic measurement campaigns: the twin plus the measurement chain and a test protocol.

A *plan* says what was run (id, start, speed or warm-up feed, split) and how much the machine's
unmeasured state varies between campaigns (:mod:`pipeline.twin.conditions`); simulating it
draws the day's ambient from the :class:`~pipeline.twin.ambient.Climate`, the campaign's
machine state (bearing preload and lubrication, convection by season, a warm start after an
earlier job, the probe mounting) or, without a state scatter, a small scatter of the heat
sources, then runs the twin and passes the result through the sensors:

* spindle drift (the PCDL paper, Miao et al. 2016): constant speed 2000/4000/6000 rpm for 4.5 h,
  then 1 h stopped, a sample every 3 min; 10 DS18B20 (per-sensor offset within +-0.2 degC,
  noise, 0.0625 degC quantisation; with ``sensor_lag`` each through the lag of its mounting) and
  an eddy-current probe (+-0.5 um, re-mounted for every campaign: a constant offset);
* axis positioning (the linear-axis patent, 2022): Y axis warmed up by moving it (20 mm/s), laser
  passes over 0..280 mm every 10 mm in both directions at 0/20/50/110/190/340/390 min, 7 PT100
  read every 10 min.

Every random draw comes from the campaign's own generator, ``campaign_rng(seed, id)``, in a
fixed order, so a campaign is reproduced bit for bit from (seed, id, plan, parameters) and
adding campaigns does not change the others.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, replace
from datetime import datetime

import numpy as np
import pandas as pd

from pipeline.thermal.effects import check_effects
from pipeline.thermal.loads import HeatLoad
from pipeline.thermal.program import Program, Segment
from pipeline.twin.ambient import AmbientProfile, Climate, season_of
from pipeline.twin.axis import AxisTruth, axis_truth, laser_runs, simulate_axis
from pipeline.twin.conditions import (
    DEMO_SCATTER,
    CampaignState,
    StateScatter,
    apply_state,
    draw_state,
)
from pipeline.twin.effects import DEMO_EFFECTS
from pipeline.twin.params import (
    DS18B20,
    PT100_CLASS_A,
    AxisParams,
    SensorNoise,
    SensorSpec,
    SpindleParams,
)
from pipeline.twin.spindle import simulate_spindle

logger = logging.getLogger(__name__)

MACHINE = "vmc-450-twin"
"""Machine name written to every synthetic campaign (a Leaderway-V450-like VMC)."""

SEASON_START = {
    "winter": datetime(2024, 2, 20, 8, 30),
    "spring": datetime(2024, 5, 21, 8, 30),
    "summer": datetime(2024, 8, 20, 8, 30),
    "autumn": datetime(2024, 11, 20, 8, 30),
}
"""Default start of a single campaign of each season (outside the demo's dates)."""


@dataclass(frozen=True)
class SpindlePlan:
    """A spindle thermal-drift test (PCDL paper protocol).

    Attributes
    ----------
    campaign_id : str
    start : datetime
        Local time of the first sample.
    rpm : float
        Constant spindle speed while running, rpm.
    split : str
        ``"train"`` or ``"validation"``.
    run_min : float
        Running time, min (then the spindle stops).
    cooldown_min : float
        Stopped time recorded after the run, min.
    sample_min : float
        Sampling interval of temperatures and displacement, min.
    season : str or None
        Written season; derived from ``start`` when None.
    scatter : StateScatter or None
        Campaign-to-campaign variation of the machine's unmeasured state
        (:mod:`pipeline.twin.conditions`); None = only a small scatter of the heat sources
        (``SpindleParams.heat_scatter_rel``), cold start, no probe offset.
    heat_loads : tuple of HeatLoad
        External heat loads applied during the test (a heater mat, a lamp, a blower), W, each
        into the node read by the sensors of its role; written to campaign.yaml as
        ``heat_loads:``. Empty = none (the demo).
    """

    campaign_id: str
    start: datetime
    rpm: float
    split: str = "train"
    run_min: float = 270.0
    cooldown_min: float = 60.0
    sample_min: float = 3.0
    season: str | None = None
    scatter: StateScatter | None = None
    heat_loads: tuple[HeatLoad, ...] = ()

    def program(self) -> Program:
        """Speed program: ``rpm`` for ``run_min``, then 0 (open-ended)."""
        segments = [Segment(0.0, self.run_min, float(self.rpm))]
        if self.cooldown_min > 0:
            segments.append(Segment(self.run_min, None, 0.0))
        return Program(tuple(segments), key="rpm")

    def times_s(self) -> np.ndarray:
        """Sample instants, s."""
        end = self.run_min + self.cooldown_min
        return np.arange(0.0, end * 60.0 + 1e-6, self.sample_min * 60.0)


@dataclass(frozen=True)
class AxisPlan:
    """A linear-axis positioning test (patent protocol).

    Attributes
    ----------
    campaign_id : str
    start : datetime
    passes_min : tuple of float
        Instants of the bidirectional laser passes, min (0 = cold machine).
    feed_program : tuple of (from_min, to_min or None, feed_mm_s)
        Warm-up motion of the axis.
    split : str
    axis_name : str
    temperature_every_min : float
        Temperature sampling interval, min.
    season : str or None
    """

    campaign_id: str
    start: datetime
    passes_min: tuple[float, ...]
    feed_program: tuple[tuple[float, float | None, float], ...] = ((0.0, None, 20.0),)
    split: str = "train"
    axis_name: str = "Y"
    temperature_every_min: float = 10.0
    season: str | None = None

    def program(self) -> Program:
        """Feed program, mm/s."""
        return Program(tuple(Segment(a, b, v) for a, b, v in self.feed_program), key="feed_mm_s")

    def temperature_times_s(self) -> np.ndarray:
        """Temperature sample instants up to the last pass, s."""
        end = max(self.passes_min)
        return np.arange(0.0, end * 60.0 + 1e-6, self.temperature_every_min * 60.0)


@dataclass(frozen=True)
class CampaignInfo:
    """Metadata written to campaign.yaml.

    Attributes
    ----------
    campaign_id, kind, machine, season : str
    split : str or None
        ``"train"`` or ``"validation"``; None writes no ``split`` key (the contract's default,
        train).
    start : datetime
    notes : str
        Free text (provenance); never names the effects used.
    """

    campaign_id: str
    kind: str
    machine: str
    start: datetime
    season: str
    split: str | None
    notes: str


@dataclass(frozen=True)
class SpindleCampaign:
    """A synthetic spindle-drift campaign, as measured plus its truth.

    Attributes
    ----------
    info : CampaignInfo
    program : Program
        Spindle speed, rpm.
    sensors : tuple of SensorSpec
    temperature : pandas.DataFrame
        temperature.csv content: ``elapsed_s`` and T1..T10 as read (offset, noise, quantised).
    displacement : pandas.DataFrame
        displacement.csv content: ``elapsed_s``, ``Z`` (um, probe noise and mounting offset).
    simulation : pandas.DataFrame
        Noise-free twin output (:func:`~pipeline.twin.spindle.simulate_spindle`).
    ambient : AmbientProfile
    params : SpindleParams
        Parameters actually used (with this campaign's machine state or heat scatter).
    effects : frozenset of str
    state : CampaignState or None
        The machine state drawn for this campaign (None without a state scatter).
    heat_loads : tuple of HeatLoad
        External heat loads of the test, W (the plan's; empty for the demo).
    """

    info: CampaignInfo
    program: Program
    sensors: tuple[SensorSpec, ...]
    temperature: pd.DataFrame
    displacement: pd.DataFrame
    simulation: pd.DataFrame
    ambient: AmbientProfile
    params: SpindleParams
    effects: frozenset[str]
    state: CampaignState | None = None
    heat_loads: tuple[HeatLoad, ...] = ()


@dataclass(frozen=True)
class AxisCampaign:
    """A synthetic axis-positioning campaign, as measured plus its truth.

    Attributes
    ----------
    info : CampaignInfo
    program : Program
        Warm-up feed, mm/s.
    sensors : tuple of SensorSpec
    axis_name : str
    stroke_mm : float
    temperature : pandas.DataFrame
        ``elapsed_s`` and T1..T7 as read.
    laser : pandas.DataFrame
        laser.csv content.
    truth : AxisTruth
        Geometric coefficients, periodic error, reversal, true slope/offset per pass.
    simulation : pandas.DataFrame
        Noise-free twin output at the temperature and pass instants.
    ambient : AmbientProfile
    params : AxisParams
    effects : frozenset of str
    """

    info: CampaignInfo
    program: Program
    sensors: tuple[SensorSpec, ...]
    axis_name: str
    stroke_mm: float
    temperature: pd.DataFrame
    laser: pd.DataFrame
    truth: AxisTruth
    simulation: pd.DataFrame
    ambient: AmbientProfile
    params: AxisParams
    effects: frozenset[str]


def campaign_rng(seed: int, campaign_id: str) -> np.random.Generator:
    """Return the generator of one campaign: child ``crc32(id)`` of ``SeedSequence(seed)``."""
    child = np.random.SeedSequence(seed, spawn_key=(zlib.crc32(campaign_id.encode("utf-8")),))
    return np.random.default_rng(child)


def read_sensors(
    true_degC: np.ndarray,
    sensors: tuple[SensorSpec, ...],
    noise: SensorNoise,
    rng: np.random.Generator,
) -> np.ndarray:
    """Pass true temperatures through the sensors: offset + white noise, then quantisation.

    Parameters
    ----------
    true_degC : ndarray of shape (n_t, n_sensors)
    sensors : tuple of SensorSpec
        Supplies each column's fixed ``offset_degc``.
    noise : SensorNoise
    rng : numpy.random.Generator
        n_t * n_sensors normal draws, row-major.

    Returns
    -------
    ndarray of shape (n_t, n_sensors), degC, multiples of ``noise.resolution_degc``.
    """
    offsets = np.array([s.offset_degc for s in sensors])
    return read_temperatures(true_degC, offsets, noise, rng)


def read_temperatures(
    true_degC: np.ndarray,
    offsets_degC: np.ndarray,
    noise: SensorNoise,
    rng: np.random.Generator,
) -> np.ndarray:
    """Add each sensor's offset and white noise to true temperatures, then quantise.

    Parameters
    ----------
    true_degC : ndarray of shape (n_t, n_sensors)
        What the sensing elements see, degC.
    offsets_degC : ndarray of shape (n_sensors,)
        Fixed calibration offset of each sensor, degC.
    noise : SensorNoise
    rng : numpy.random.Generator
        n_t * n_sensors normal draws, row-major.

    Returns
    -------
    ndarray of shape (n_t, n_sensors), degC, multiples of ``noise.resolution_degc``.
    """
    value = true_degC + offsets_degC + noise.noise_sd_degc * rng.standard_normal(true_degC.shape)
    return np.round(value / noise.resolution_degc) * noise.resolution_degc


def _scatter(rng: np.random.Generator, rel: float, n: int) -> np.ndarray:
    return 1.0 + rel * rng.standard_normal(n)


def provenance_notes(seed: int, preset: str, varied: bool = False) -> str:
    """Return the ``notes:`` line of a synthetic campaign (never names the effects used)."""
    text = (
        "Synthetic campaign written by the physical twin (pipeline.twin, "
        f"thermal simulate --preset {preset} --seed {seed}); not a measurement."
    )
    if varied:
        text += (
            " The machine state no sensor sees (bearing preload and lubrication, convection, "
            "earlier use, probe mounting) varies from campaign to campaign."
        )
    return text


def _machine_of_the_day(
    plan: SpindlePlan, params: SpindleParams, season: str, rng: np.random.Generator
) -> tuple[SpindleParams, CampaignState | None]:
    """Return the parameters of the campaign's machine and its drawn state (None if not drawn).

    Without a state scatter only the heat sources scatter (3 draws); else the machine state is
    drawn (:func:`~pipeline.twin.conditions.draw_state`).
    """
    if plan.scatter is None:
        f_front, f_rear, f_motor = _scatter(rng, params.heat_scatter_rel, 3)
        used = replace(
            params,
            front_bearing_heat_w=params.front_bearing_heat_w * f_front,
            rear_bearing_heat_w=params.rear_bearing_heat_w * f_rear,
            motor_heat_w=params.motor_heat_w * f_motor,
        )
        return used, None
    state = draw_state(plan.scatter, params, season, rng)
    return apply_state(params, state), state


def simulate_spindle_campaign(
    plan: SpindlePlan,
    *,
    seed: int,
    params: SpindleParams | None = None,
    effects: Iterable[str] = DEMO_EFFECTS,
    climate: Climate | None = None,
    preset: str = "demo",
    machine: str = MACHINE,
) -> SpindleCampaign:
    """Simulate one spindle-drift campaign.

    Parameters
    ----------
    plan : SpindlePlan
    seed : int
        Master seed; the campaign uses ``campaign_rng(seed, plan.campaign_id)``.
    params : SpindleParams, optional
        Nominal machine parameters (default :class:`SpindleParams`).
    effects : iterable of str
        Effects switched on (default: the demo set).
    climate : Climate, optional
    preset : str
        Written in the notes only.
    machine : str

    Returns
    -------
    SpindleCampaign
    """
    params = params or SpindleParams()
    climate = climate or Climate()
    names = check_effects(effects)
    rng = campaign_rng(seed, plan.campaign_id)
    ambient = climate.profile(plan.start, rng)
    season = plan.season or season_of(plan.start)
    used, state = _machine_of_the_day(plan, params, season, rng)
    times = plan.times_s()
    history = None if state is None else state.history
    sim = simulate_spindle(
        used, names, plan.program(), ambient, times, history=history, heat_loads=plan.heat_loads
    )
    names_t = [s.name for s in used.sensors]
    read = read_sensors(sim[names_t].to_numpy(), used.sensors, DS18B20, rng)
    temperature = pd.DataFrame(read, columns=names_t)
    temperature.insert(0, "elapsed_s", times)
    offset = 0.0 if state is None else state.probe_offset_um
    z = sim["z_um"].to_numpy() + offset + used.probe_noise_um * rng.standard_normal(times.size)
    displacement = pd.DataFrame({"elapsed_s": times, "Z": z})
    info = CampaignInfo(
        campaign_id=plan.campaign_id,
        kind="spindle_drift",
        machine=machine,
        start=plan.start,
        season=season,
        split=plan.split,
        notes=provenance_notes(seed, preset, varied=state is not None),
    )
    logger.debug("simulated %s at %s rpm", plan.campaign_id, plan.rpm)
    return SpindleCampaign(
        info=info,
        program=plan.program(),
        sensors=used.sensors,
        temperature=temperature,
        displacement=displacement,
        simulation=sim,
        ambient=ambient,
        params=used,
        effects=names,
        state=state,
        heat_loads=plan.heat_loads,
    )


def simulate_axis_campaign(
    plan: AxisPlan,
    *,
    seed: int,
    params: AxisParams | None = None,
    effects: Iterable[str] = DEMO_EFFECTS,
    climate: Climate | None = None,
    preset: str = "demo",
    machine: str = MACHINE,
) -> AxisCampaign:
    """Simulate one axis-positioning campaign (temperatures, laser runs and truth).

    Parameters
    ----------
    plan : AxisPlan
    seed : int
        Master seed; the campaign uses ``campaign_rng(seed, plan.campaign_id)``.
    params : AxisParams, optional
    effects : iterable of str
        Only ``ambient_variation`` and ``sensor_lag`` act on the axis.
    climate : Climate, optional
    preset : str
    machine : str

    Returns
    -------
    AxisCampaign
        ``truth`` holds the geometric coefficients (um, x in mm), periodic error, reversal and
        the true slope (um/mm) and offset (um) of every pass.
    """
    params = params or AxisParams()
    climate = climate or Climate()
    names = check_effects(effects)
    rng = campaign_rng(seed, plan.campaign_id)
    ambient = climate.profile(plan.start, rng)
    f = _scatter(rng, params.heat_scatter_rel, 4)
    used = replace(
        params,
        nut_heat_w=params.nut_heat_w * f[0],
        bearing_heat_w=params.bearing_heat_w * f[1],
        motor_heat_w=params.motor_heat_w * f[2],
        guideway_heat_w=params.guideway_heat_w * f[3],
    )
    t_temp = plan.temperature_times_s()
    t_all = np.union1d(t_temp, np.asarray(plan.passes_min, dtype=float) * 60.0)
    sim = simulate_axis(used, names, plan.program(), ambient, t_all)
    truth = axis_truth(used, sim, plan.passes_min)
    names_t = [s.name for s in used.sensors]
    at_temp = sim.set_index("elapsed_s").loc[t_temp, names_t].to_numpy()
    read = read_sensors(at_temp, used.sensors, PT100_CLASS_A, rng)
    temperature = pd.DataFrame(read, columns=names_t)
    temperature.insert(0, "elapsed_s", t_temp)
    laser = laser_runs(used, truth, rng)
    info = CampaignInfo(
        campaign_id=plan.campaign_id,
        kind="axis_positioning",
        machine=machine,
        start=plan.start,
        season=plan.season or season_of(plan.start),
        split=plan.split,
        notes=provenance_notes(seed, preset),
    )
    return AxisCampaign(
        info=info,
        program=plan.program(),
        sensors=used.sensors,
        axis_name=plan.axis_name,
        stroke_mm=used.stroke_mm,
        temperature=temperature,
        laser=laser,
        truth=truth,
        simulation=sim,
        ambient=ambient,
        params=used,
        effects=names,
    )


PATENT_PASSES_MIN = (0.0, 20.0, 50.0, 110.0, 190.0, 340.0, 390.0)
"""Laser passes of the patent's modelling test, min after switching on."""


def demo_plans() -> tuple[SpindlePlan | AxisPlan, ...]:
    """Return the plans of the demo set.

    K01-K12 (3 per season at 2000/4000/6000 rpm), V01-V06 (October and December, validation),
    Y01 (patent protocol, spring) and Y02 (validation, autumn).
    """
    d = datetime
    speeds = (2000.0, 4000.0, 6000.0)
    train_starts = (
        d(2024, 1, 9, 8, 30),
        d(2024, 1, 16, 9, 0),
        d(2024, 1, 23, 8, 45),  # winter
        d(2024, 4, 9, 8, 15),
        d(2024, 4, 16, 8, 30),
        d(2024, 4, 23, 9, 0),  # spring
        d(2024, 7, 9, 8, 0),
        d(2024, 7, 16, 8, 30),
        d(2024, 7, 23, 8, 15),  # summer
        d(2024, 9, 10, 8, 30),
        d(2024, 9, 24, 9, 0),
        d(2024, 11, 5, 8, 45),  # autumn
    )
    validation_starts = (
        d(2024, 10, 15, 8, 30),
        d(2024, 10, 22, 8, 45),
        d(2024, 10, 29, 9, 0),  # October
        d(2024, 12, 3, 8, 30),
        d(2024, 12, 10, 9, 0),
        d(2024, 12, 17, 8, 45),  # December
    )
    plans: list[SpindlePlan | AxisPlan] = [
        SpindlePlan(f"K{i + 1:02d}", start, speeds[i % 3], scatter=DEMO_SCATTER)
        for i, start in enumerate(train_starts)
    ]
    plans += [
        SpindlePlan(f"V{i + 1:02d}", start, speeds[i % 3], split="validation", scatter=DEMO_SCATTER)
        for i, start in enumerate(validation_starts)
    ]
    plans.append(AxisPlan("Y01", d(2024, 5, 14, 8, 0), PATENT_PASSES_MIN))
    plans.append(
        AxisPlan(
            "Y02",
            d(2024, 11, 19, 8, 15),
            (0.0, 40.0, 100.0, 160.0, 220.0, 280.0),
            feed_program=((0.0, 120.0, 30.0), (120.0, None, 15.0)),
            split="validation",
        )
    )
    return tuple(plans)


def simulate_plan(
    plan: SpindlePlan | AxisPlan,
    *,
    seed: int,
    effects: Iterable[str] = DEMO_EFFECTS,
    preset: str = "demo",
) -> SpindleCampaign | AxisCampaign:
    """Simulate a spindle or axis plan with the default parameters."""
    if isinstance(plan, SpindlePlan):
        return simulate_spindle_campaign(plan, seed=seed, effects=effects, preset=preset)
    return simulate_axis_campaign(plan, seed=seed, effects=effects, preset=preset)


def demo_campaigns(
    seed: int, effects: Iterable[str] = DEMO_EFFECTS
) -> list[SpindleCampaign | AxisCampaign]:
    """Simulate the whole demo set in memory (about a second)."""
    names = check_effects(effects)
    return [simulate_plan(p, seed=seed, effects=names) for p in demo_plans()]

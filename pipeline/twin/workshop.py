"""The "workshop" preset: one two-day run of a machine, cut into six campaign folders.

It imitates a measurement a user brought from a real machine, to test the pipeline's
robustness (it is not a target to tune models to):

* one continuous run of ~46 h (six ~8-h campaigns back to back, ids W01..W06): each campaign
  runs the spindle 4 h (one speed, or 1-h steps in one of them) then stops it 4 h (the last
  one 2 h); the twin is simulated once over the whole run and then cut at sample instants, so
  every campaign but the first starts warm, where the previous one ended. Nothing in the files
  says so: the chain is only visible from ``start``, ``machine`` and the durations;
* one season, no ``split`` key (all training), ``synthetic: true``;
* 16 DS18B20 sensors T1..T16, all ``role: other`` without a location; their true places
  (:data:`WORKSHOP_SENSORS`) are spread over the twin's nodes, some between two parts, two in
  the air (near the floor, up high), each with its own mounting lag (2-30 min); none on the
  spindle shaft;
* three eddy-current probes X, Y, Z in one holder on the table, facing a test mandrel in the
  spindle from the -X, -Y and -Z sides, so that a reading grows when the tool moves in +X, +Y
  (ISO 841) or +Z, away from the probe (the contract's sign); mounted once for the whole run
  (one constant offset per probe, no re-zeroing at the cuts). X and Y physics:
  :mod:`pipeline.twin.lateral`; Z: the twin's own terms; probe chain:
  :class:`~pipeline.twin.instruments.EddyCurrentProbe`;
* the air follows the daily cycle and a slow weather wander
  (:func:`~pipeline.twin.ambient.draw_weather`);
* a measured speed log (spindle.csv) and the commanded program in campaign.yaml;
* temperatures, displacements and speed every ``interval_s`` (20 s, a data-logger export).

All random draws come from the run's own generator ``campaign_rng(seed, plan.run_id)`` in a
fixed order, so the six folders are reproduced bit for bit from the seed.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta

import numpy as np
import pandas as pd

from pipeline.thermal.effects import check_effects
from pipeline.thermal.program import Program, Segment
from pipeline.twin.ambient import Climate, WeatherAmbient, draw_weather, season_of
from pipeline.twin.campaigns import (
    CampaignInfo,
    campaign_rng,
    provenance_notes,
    read_temperatures,
)
from pipeline.twin.effects import DEMO_EFFECTS
from pipeline.twin.instruments import (
    AIR,
    EddyCurrentProbe,
    PlacedSensor,
    sensed_temperatures,
    speed_log,
)
from pipeline.twin.lateral import LateralParams, lateral_drift
from pipeline.twin.params import DS18B20, SpindleParams
from pipeline.twin.spindle import simulate_spindle

logger = logging.getLogger(__name__)

WORKSHOP_MACHINE = "vmc-workshop-twin"
"""Machine name written to every workshop campaign."""

WORKSHOP_EFFECTS = DEMO_EFFECTS | {"centrifugal_growth"}
"""Effects on by default: the demo's set plus the instant centrifugal growth at speed changes
(a real spindle has it; the speed steps make it visible)."""

WORKSHOP_CLIMATE = Climate(drift_sd_k_per_h=0.0)
"""The year's climate without the single-day linear drift: over two days the weather wander
of :func:`~pipeline.twin.ambient.draw_weather` takes its place."""

PREROLL_H = 72.0
"""Idle hours simulated before the run: the machine starts cold, in step with the air."""

SENSOR_OFFSET_DEGC = 0.2
"""Half-width of the uniform calibration offset of each DS18B20, degC (its +-0.2 degC class)."""


def _sensor(
    name: str, place: str, mix: dict[str, float], tau_min: float, bias_k: float = 0.0
) -> PlacedSensor:
    return PlacedSensor(name, tuple(mix.items()), tau_min * 60.0, bias_k, place)


WORKSHOP_SENSORS = (
    _sensor(
        "T1",
        "column front face, top of the Z guideways",
        {"column_front": 0.7, "headstock": 0.3},
        18,
    ),
    _sensor("T2", "front bearing housing", {"front_bearing": 1.0}, 4),
    _sensor(
        "T3",
        "air 0.3 m above the floor (cool layer, follows the floor slab)",
        {AIR: 0.85, "bed": 0.15},
        10,
        bias_k=-0.6,
    ),
    _sensor("T4", "spindle motor casing", {"motor": 1.0}, 8),
    _sensor("T5", "bed, under the column", {"bed": 1.0}, 30),
    _sensor("T6", "headstock side wall", {"headstock": 1.0}, 15),
    _sensor(
        "T7",
        "spindle nose flange, between front bearing and headstock",
        {"front_bearing": 0.6, "headstock": 0.4},
        6,
    ),
    _sensor("T8", "column rear face", {"column_rear": 1.0}, 20),
    _sensor("T9", "Z ball-screw nut housing", {"z_screw": 1.0}, 5),
    _sensor("T10", "rear bearing housing", {"rear_bearing": 1.0}, 5),
    _sensor(
        "T11",
        "air 2.5 m above the floor, in the machine's warm plume",
        {AIR: 0.95, "motor": 0.05},
        2,
        bias_k=0.5,
    ),
    _sensor("T12", "motor flange on the headstock", {"motor": 0.5, "headstock": 0.5}, 12),
    _sensor("T13", "spindle cartridge sleeve, near the nose", {"spindle_sleeve": 1.0}, 7),
    _sensor(
        "T14",
        "Z-screw upper support bearing on the column",
        {"z_screw": 0.5, "column_front": 0.5},
        10,
    ),
    _sensor("T15", "column foot on the bed, rear", {"column_rear": 0.4, "bed": 0.6}, 25),
    _sensor("T16", "column side wall, mid-depth", {"column_front": 0.5, "column_rear": 0.5}, 22),
)
"""The 16 sensors in logger channel order: true place, node mix, mounting lag (min), bias.

Engineering estimates, not measurements: mounting lags from 2 min (a bare probe in the air)
through 4-8 min (screwed into a housing) to 30 min (adhesive pad on the massive bed), as for
the demo's sensors; the air layer near the floor 0.6 K cooler and the air 2.5 m up 0.5 K warmer
than the air the machine sees (a vertical gradient of about 0.5 K/m, usual in a hall without
forced ventilation), the floor sensor damped by the slab, the high one catching a little of the
motor's plume.
"""

AXES = ("X", "Y", "Z")
"""Probe axes, in the order their random draws are made and their columns written."""


@dataclass(frozen=True)
class WorkshopSlot:
    """One campaign of the run: running steps, then the spindle stopped.

    Attributes
    ----------
    campaign_id : str
    steps : tuple of (float, float)
        Running steps in order, (duration min, speed rpm).
    stop_min : float
        Stopped time after the steps, min.
    """

    campaign_id: str
    steps: tuple[tuple[float, float], ...]
    stop_min: float = 240.0

    @property
    def duration_min(self) -> float:
        """Length of the campaign, min."""
        return sum(d for d, _ in self.steps) + self.stop_min

    def segments(self, offset_min: float = 0.0) -> list[Segment]:
        """Return the closed speed segments (rpm), shifted by ``offset_min`` minutes."""
        out, t = [], offset_min
        for duration, rpm in self.steps:
            out.append(Segment(t, t + duration, float(rpm)))
            t += duration
        if self.stop_min > 0:
            out.append(Segment(t, t + self.stop_min, 0.0))
        return out

    def program(self) -> Program:
        """Commanded speed from the campaign's start (minutes), closed at its end, rpm."""
        return Program(tuple(self.segments()), key="rpm")


@dataclass(frozen=True)
class WorkshopPlan:
    """The whole run: start, campaigns, sampling and the instruments' settings.

    Attributes
    ----------
    start : datetime
        Local time of the run's first sample (W01's ``start``).
    slots : tuple of WorkshopSlot
        The campaigns, back to back.
    interval_s : float
        Sampling interval of temperatures, displacements and speed, s; must divide every
        campaign's duration.
    run_id : str
        Names the run's random generator.
    machine : str
    season : str or None
        Written to every campaign; None = the season of ``start``.
    rpm_noise_rel : float
        Relative noise of the measured speed.
    """

    start: datetime
    slots: tuple[WorkshopSlot, ...]
    interval_s: float = 20.0
    run_id: str = "workshop"
    machine: str = WORKSHOP_MACHINE
    season: str | None = None
    rpm_noise_rel: float = 0.003

    def __post_init__(self) -> None:
        """Check the interval divides every campaign and the ids are unique."""
        if self.interval_s <= 0:
            raise ValueError("WorkshopPlan: interval_s must be > 0")
        for slot in self.slots:
            n = slot.duration_min * 60.0 / self.interval_s
            if slot.duration_min <= 0 or abs(n - round(n)) > 1e-9:
                raise ValueError(
                    f"WorkshopPlan: campaign {slot.campaign_id} lasts {slot.duration_min} min, "
                    f"not a whole number of {self.interval_s} s intervals"
                )
        ids = [s.campaign_id for s in self.slots]
        if len(set(ids)) != len(ids):
            raise ValueError(f"WorkshopPlan: duplicate campaign ids in {ids}")

    def sample_counts(self) -> list[int]:
        """Return the number of samples of each campaign (duration / interval)."""
        return [round(s.duration_min * 60.0 / self.interval_s) for s in self.slots]

    def times_s(self) -> np.ndarray:
        """Sample instants of the whole run, s since its start, shape (n,)."""
        return self.interval_s * np.arange(sum(self.sample_counts()))

    def program(self) -> Program:
        """Commanded speed of the whole run, minutes since its start, rpm."""
        segments, offset = [], 0.0
        for slot in self.slots:
            segments += slot.segments(offset)
            offset += slot.duration_min
        return Program(tuple(segments), key="rpm")


def workshop_plan(interval_s: float = 20.0) -> WorkshopPlan:
    """Return the preset's plan: six campaigns from Monday 7 April 2025, 07:00 (46 h).

    W01 2500 rpm, W02 1250/2500/3750/5000 rpm (1 h each), W03 5000, W04 1250, W05 3750 rpm,
    each 4 h running then 4 h stopped; W06 3000 rpm 4 h then 2 h stopped.
    """
    return WorkshopPlan(
        start=datetime(2025, 4, 7, 7, 0),
        slots=(
            WorkshopSlot("W01", ((240.0, 2500.0),)),
            WorkshopSlot("W02", ((60.0, 1250.0), (60.0, 2500.0), (60.0, 3750.0), (60.0, 5000.0))),
            WorkshopSlot("W03", ((240.0, 5000.0),)),
            WorkshopSlot("W04", ((240.0, 1250.0),)),
            WorkshopSlot("W05", ((240.0, 3750.0),)),
            WorkshopSlot("W06", ((240.0, 3000.0),), stop_min=120.0),
        ),
        interval_s=interval_s,
    )


@dataclass(frozen=True)
class WorkshopCampaign:
    """One campaign folder of the workshop run, as measured plus its truth.

    Attributes
    ----------
    info : CampaignInfo
        ``split`` is None (no key written).
    program : Program
        Commanded speed, minutes since the campaign's start, rpm.
    sensors : tuple of PlacedSensor
    temperature : pandas.DataFrame
        ``elapsed_s`` and T1..T16 as read (offset, noise, 0.0625 degC quantisation).
    displacement : pandas.DataFrame
        ``elapsed_s``, ``X``, ``Y``, ``Z`` as read, um.
    spindle : pandas.DataFrame
        ``elapsed_s``, ``rpm``: the measured speed.
    truth : pandas.DataFrame
        The run's noise-free rows of this campaign (see :class:`WorkshopRun`), ``elapsed_s``
        since the campaign's start.
    """

    info: CampaignInfo
    program: Program
    sensors: tuple[PlacedSensor, ...]
    temperature: pd.DataFrame
    displacement: pd.DataFrame
    spindle: pd.DataFrame
    truth: pd.DataFrame


@dataclass(frozen=True)
class WorkshopRun:
    """The simulated run and its campaigns.

    Attributes
    ----------
    plan : WorkshopPlan
    campaigns : tuple of WorkshopCampaign
    truth : pandas.DataFrame
        Noise-free run, one row per sample: ``elapsed_s`` (since the run's start), ``rpm``,
        ``ambient_degC``, ``node_<name>`` (degC), ``z_<term>_um`` and ``z_um``,
        ``x_<term>_um``/``y_<term>_um`` and ``x_um``/``y_um`` (true tool drift, um),
        ``holder_degC`` (probe holder) and T1..T16 (what each sensing element sees, degC).
    ambient : WeatherAmbient
    params : SpindleParams
    effects : frozenset of str
    sensor_offsets_degc : ndarray of shape (16,)
        Calibration offsets drawn for T1..T16, degC.
    """

    plan: WorkshopPlan
    campaigns: tuple[WorkshopCampaign, ...]
    truth: pd.DataFrame
    ambient: WeatherAmbient
    params: SpindleParams
    effects: frozenset[str]
    sensor_offsets_degc: np.ndarray = field(repr=False)


def _truth(
    plan: WorkshopPlan,
    params: SpindleParams,
    names: frozenset[str],
    ambient: WeatherAmbient,
    lateral: LateralParams,
    probe: EddyCurrentProbe,
) -> pd.DataFrame:
    """Simulate the run once and add the lateral drift, holder and sensed temperatures."""
    times = plan.times_s()
    sim = simulate_spindle(params, names, plan.program(), ambient, times, preroll_h=PREROLL_H)
    nodes = [f"node_{n}" for n in params.network.nodes]
    rise = sim[nodes].to_numpy() - sim[nodes].to_numpy()[0]
    columns = {**sim.to_dict("series"), **lateral_drift(params, lateral, rise, names)}
    columns["holder_degC"] = probe.holder_temperature(
        sim["node_bed"].to_numpy(), sim["ambient_degC"].to_numpy(), plan.interval_s
    )
    sensed = sensed_temperatures(
        columns, WORKSHOP_SENSORS, plan.interval_s, lagged="sensor_lag" in names
    )
    for j, sensor in enumerate(WORKSHOP_SENSORS):
        columns[sensor.name] = sensed[:, j]
    return pd.DataFrame(columns)


def _measure(
    plan: WorkshopPlan, truth: pd.DataFrame, probe: EddyCurrentProbe, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]]:
    """Pass the run's truth through sensors, probes and the speed log (fixed draw order).

    Returns the sensor offsets (degC) and the temperature, displacement and spindle readings.
    """
    n_sensors = len(WORKSHOP_SENSORS)
    offsets = rng.uniform(-SENSOR_OFFSET_DEGC, SENSOR_OFFSET_DEGC, n_sensors)
    names = [s.name for s in WORKSHOP_SENSORS]
    read = read_temperatures(truth[names].to_numpy(), offsets, DS18B20, rng)
    temperature = pd.DataFrame(read, columns=names)
    holder = truth["holder_degC"].to_numpy()
    displacement = pd.DataFrame(
        {
            axis: probe.read(truth[f"{axis.lower()}_um"].to_numpy(), holder, plan.interval_s, rng)
            for axis in AXES
        }
    )
    times = truth["elapsed_s"].to_numpy()
    rpm = speed_log(plan.program(), times, plan.rpm_noise_rel, rng)
    return offsets, (temperature, displacement, pd.DataFrame({"rpm": rpm}))


def _cut(frame: pd.DataFrame, times: np.ndarray, first: int, count: int) -> pd.DataFrame:
    """Rows ``first..first+count-1`` with ``elapsed_s`` since the campaign's first sample."""
    part = frame.iloc[first : first + count].reset_index(drop=True)
    part = part.drop(columns="elapsed_s", errors="ignore")
    part.insert(0, "elapsed_s", times[first : first + count] - times[first])
    return part


def cut_campaigns(
    plan: WorkshopPlan,
    truth: pd.DataFrame,
    measured: tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame],
    notes_text: str,
) -> tuple[WorkshopCampaign, ...]:
    """Cut the run into its campaigns at sample instants.

    Campaign k holds ``n_k = duration_k / interval`` samples; campaign k+1 starts at
    ``start_k + duration_k``, one interval after campaign k's last sample.

    Parameters
    ----------
    plan : WorkshopPlan
    truth : pandas.DataFrame
        The run's noise-free frame (``elapsed_s`` since the run's start).
    measured : tuple of (temperature, displacement, spindle) DataFrames
        The run's readings, one row per sample, without ``elapsed_s``.
    notes_text : str
        The ``notes:`` line.

    Returns
    -------
    tuple of WorkshopCampaign
    """
    temperature, displacement, spindle = measured
    times = truth["elapsed_s"].to_numpy()
    season = plan.season or season_of(plan.start)
    campaigns, first = [], 0
    for slot, count in zip(plan.slots, plan.sample_counts(), strict=True):
        info = CampaignInfo(
            campaign_id=slot.campaign_id,
            kind="spindle_drift",
            machine=plan.machine,
            start=plan.start + timedelta(seconds=float(times[first])),
            season=season,
            split=None,
            notes=notes_text,
        )
        campaigns.append(
            WorkshopCampaign(
                info=info,
                program=slot.program(),
                sensors=WORKSHOP_SENSORS,
                temperature=_cut(temperature, times, first, count),
                displacement=_cut(displacement, times, first, count),
                spindle=_cut(spindle, times, first, count),
                truth=_cut(truth, times, first, count),
            )
        )
        first += count
    return tuple(campaigns)


def simulate_workshop(
    plan: WorkshopPlan,
    *,
    seed: int,
    effects: Iterable[str] = WORKSHOP_EFFECTS,
    params: SpindleParams | None = None,
    lateral: LateralParams | None = None,
    probe: EddyCurrentProbe | None = None,
    climate: Climate = WORKSHOP_CLIMATE,
) -> WorkshopRun:
    """Simulate the workshop run once and cut it into its campaigns.

    Parameters
    ----------
    plan : WorkshopPlan
    seed : int
        Master seed; the run uses ``campaign_rng(seed, plan.run_id)``. Draws, in order: the
        day's ambient (4), the weather wander (one per 6-h knot), 16 sensor offsets, the
        temperature noise (n x 16), per probe X, Y, Z its offset, coefficient, walk and noise,
        and the speed noise (n).
    effects : iterable of str
        Effects on (default :data:`WORKSHOP_EFFECTS`); ``thermal_bending`` also switches the
        Y column-bending term, ``sensor_lag`` the mounting lags.
    params : SpindleParams, optional
        Machine (default :class:`SpindleParams`); its own sensors are not used.
    lateral : LateralParams, optional
    probe : EddyCurrentProbe, optional
        Settings of the three probes.
    climate : Climate

    Returns
    -------
    WorkshopRun
    """
    names = check_effects(effects)
    params = replace(params or SpindleParams(), sensors=())
    lateral = lateral or LateralParams()
    probe = probe or EddyCurrentProbe()
    rng = campaign_rng(seed, plan.run_id)
    times = plan.times_s()
    ambient = draw_weather(
        climate.profile(plan.start, rng), -PREROLL_H * 3600.0, float(times[-1]), rng
    )
    truth = _truth(plan, params, names, ambient, lateral, probe)
    offsets, measured = _measure(plan, truth, probe, rng)
    campaigns = cut_campaigns(plan, truth, measured, provenance_notes(seed, "workshop"))
    logger.debug("workshop run: %d samples, %d campaigns", times.size, len(campaigns))
    return WorkshopRun(plan, campaigns, truth, ambient, params, names, offsets)

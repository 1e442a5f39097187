"""A test plan that would make a not-identifiable effect visible.

For each candidate effect the campaigns cannot show
(:data:`~pipeline.discrepancy.identifiability.NOT_IDENTIFIABLE`), this module searches a small,
explicit grid of tests a user can run (:func:`candidate_plans`) and proposes the cheapest one
under which the effect would be identifiable (:func:`propose_tests`):

1. **The grid.** Spindle programs at the campaigns' top speed ``high`` and half of it (speed
   steps up and down every 20, 40 or 60 min, a stop-and-restart, one constant run), over 4 or
   8 h, each sampled at the campaigns' own interval and, when theirs is longer, at
   :data:`FAST_INTERVAL_S`; and, where the effect reads a structure role no campaign has
   (:data:`ADDED_SENSOR_ROLES`), the same programs with a sensor of that role added; and,
   where the effect reads a part a heater can load (:data:`HEAT_LOAD_ROLES`, roles the
   campaigns have a sensor on), an external heat load of :data:`HEATER_POWERS_W` on that part
   for a short pulse after a spindle run or for half the test, with the spindle stopped, or
   running in the other half (:func:`heater_plans`);
   and where the effect reads two such parts, the two loaded differently: one after the
   other, or both at once at different powers (:func:`paired_heater_plans`). A load the
   spindle does not drive separates what the spindle's heat ties together (a sensor's delay
   and its node's heat capacity); two loads whose ratio changes separate what one load ties
   together (the column's front-to-rear difference, which bends it, and its mean rise, which
   the baseline's expansion follows). A plan records what it is meant to separate. For an
   effect driven by the workshop air (:data:`AIR_CYCLE_EFFECTS`), no spindle program helps:
   the air of a test of a few hours barely moves, and the plans are simulated at a constant
   air. Its plans log the machine at rest (with or without a warm-up run first) through half
   or all of a day (:func:`daily_air_plans`), simulated with the air following a daily cycle
   of the largest range one campaign recorded (:func:`air_swing_k`; a day spans at least what
   a few hours did, so the signal is not overstated).
2. **The simulated test.** Each plan is one campaign simulated noise-free by the planning
   twin (:func:`~pipeline.discrepancy.plan_twin.plan_twin`: the baseline refitted with its
   priors, so that what the campaigns leave loose sits at typical values; a node the added
   sensor brings gets its parameters' initial values), starting cold at the campaigns'
   ambient with the campaigns' sensors (plus the added one) and the Z probe
   (:func:`simulate_plan`).
3. **The envelope** (:mod:`~pipeline.discrepancy.plan_envelope`). A plan that could heat a
   part beyond the campaigns' largest rise (at least
   :data:`~pipeline.discrepancy.plan_envelope.ENVELOPE_FLOOR_K`) is left out. What it could do
   is the :data:`~pipeline.discrepancy.plan_twin.RISE_QUANTILE` quantile of its peak rise over
   draws from the planning twin's posterior (:func:`plan_rises`) and, for a heater on a part
   no campaign heated, the rise if all the heater's energy stayed in the part's smallest
   plausible heat capacity, which no calibration error can exceed.
4. **Its signal.** The same figures as the identifiability of the campaigns
   (:func:`~pipeline.discrepancy.visibility.visibility`: the effect at its plausible size, the
   part the baseline cannot absorb by moving its parameters within their prior scales, RMS in
   noise sigmas), on the plan's campaign, with the noise floor of each sensor of the campaigns
   (an added one: their median). A plan makes the effect visible when it misses no threshold
   (:func:`~pipeline.discrepancy.identifiability.shortfalls`).
5. **Cost.** Test duration in hours plus :data:`SENSOR_COST_H` per added sensor and
   :data:`HEATER_COST_H` per heat load; ties go to the campaigns' own sampling interval. Plans
   are tried in order of cost. Of the visible ones in the envelope, the cheapest whose response
   would also pass the search's rule once its campaigns join the others
   (:func:`~pipeline.discrepancy.plan_naming.would_be_named`) is proposed, of equal cost the
   one with the largest signal; failing that, the cheapest visible one, flagged
   ``misfit_limited``. When none is visible, the report says so with the best signal
   the grid reached, and if a heater plan on a part no campaign heated would show the effect
   but is held back by the doubt about that part (its rise bound leaves the envelope, or it
   shows the effect only with the part at typical parameters), it proposes the cheapest safe
   heating of that part as a **calibration step** (:func:`propose_test`): a sequential
   design, as in the model-based design of experiments of Franceschini and Macchietto
   (2008, *Model-based design of experiments for parameter precision: state of the art*,
   Chem. Eng. Sci. 63(19), 4846-4872): a first, safe test pins the part's response down, and
   the rerun designs the test for the effect from it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from pipeline.discrepancy.calibrate import NoiseFloor
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.identifiability import (
    NOT_IDENTIFIABLE,
    EffectIdentifiability,
    IdentifiabilitySettings,
    shortfalls,
)
from pipeline.discrepancy.model import ROLE_NODES, TwinModel, build_model, loaded_roles
from pipeline.discrepancy.plan_envelope import (
    ENVELOPE_FLOOR_K,
    PlanRise,
    first_heating_bound_k,
    first_heating_values,
    rise_limit_k,
)
from pipeline.discrepancy.plan_naming import HeldOutFloor, counted_samples, would_be_named
from pipeline.discrepancy.plan_twin import RISE_QUANTILE, PlanTwin, peak_rises, plan_twin
from pipeline.discrepancy.visibility import (
    BaselinePoint,
    Visibility,
    baseline_point,
    json_figure,
    visibility,
)
from pipeline.thermal.loads import POWER_KEY, HeatLoad, loads_to_contract
from pipeline.thermal.program import Program, Segment

logger = logging.getLogger(__name__)

STEP_PERIODS_MIN = (20.0, 40.0, 60.0)
"""Period of the speed steps (high, low, high, ...) of the stepped programs, min."""

DURATIONS_H = (4.0, 8.0)
"""Durations of the tests in the grid, h."""

FAST_INTERVAL_S = 60.0
"""The sampling interval offered besides the campaigns' own, s."""

SENSOR_COST_H = 2.0
"""Fixed cost of adding a sensor (mounting, wiring, its role in campaign.yaml), in test hours."""

ADDED_SENSOR_ROLES = {
    "thermal_bending": ("column_rear", "column_front"),
    "sensor_lag": ("spindle_front_bearing", "headstock"),
    "motor_heat": ("spindle_motor",),
    "nonlinear_bearing_heat": ("spindle_front_bearing",),
    "centrifugal_growth": ("spindle_front_bearing",),
}
"""Structure roles a sensor may be added on, per effect (only those no campaign has are tried):
bending reads the column's front-to-rear difference, the lag and the bearing laws a fast-moving
node near the heat."""

HEATER_COST_H = 2.0
"""Fixed cost of an external heat load (mounting a heater, its supply, logging its power), in
test hours."""

HEATER_POWERS_W = (10.0, 25.0, 100.0, 250.0, 500.0)
"""Heater powers of the grid, W: heater pads and mats and a 500 W halogen lamp. A plan
that would heat a part beyond the campaigns' own largest rise is left out
(:func:`~pipeline.discrepancy.plan_envelope.largest_rise_k`). The 10 W pad is there for the
calibration step: on a light part no campaign heated (a motor casing of a few kJ/K whose heat
capacity the campaigns leave loose by a factor of a few), even a 25 W pulse can exceed the
envelope over the twin's uncertainty."""

HEAT_LOAD_ROLES = {
    "thermal_bending": ("column_rear", "column_front"),
    "sensor_lag": ("spindle_motor", "headstock", "spindle_front_bearing"),
}
"""Structure roles a heater may be put on, per effect (only roles the campaigns have a sensor
on), in order of preference: bending reads the difference of the column halves, which a load
on one half drives alone; a sensor's lag shows when its own part is heated directly and fast,
its reading rising later than the part's heat capacity allows, so the lightest part a heater
can be put on comes first (the motor casing; a bearing housing sits inside the headstock)."""

SEPARATES = {
    "thermal_bending": "the column's expansion, the baseline's law on the column's mean rise",
    "sensor_lag": "the heat capacity of the part the sensor reads, in the baseline",
    "ambient_variation": "the baseline's constant air",
}
"""What a heater plan, or a plan logging a day of air, is meant to tell each effect apart from
(the law of the baseline that shares its signature under the spindle's heat or a still air)."""

PAIRED_ROLES = {"thermal_bending": ("column_front", "column_rear")}
"""Parts loaded differently by the plans of :func:`paired_heater_plans`, per effect: one heater
on a column face drives its front-to-rear difference (bending) and its mean rise (expansion)
together, two loaded in turn or unequally make the difference change while the mean goes on."""

PAIRED_POWERS_W = (100.0, 250.0, 500.0)
"""Heater powers of the plans that load two parts (:func:`paired_heater_plans`), W: the pads
of a few tens of watts are for the calibration step on one part."""

PULSE_MIN = 15.0
"""Length of the short heat pulse of the grid, min: a fast rise that a sensor's lag delays,
while the part stays in the envelope; the smallest such pulse on a part the campaigns never
heated is the calibration step of :func:`propose_test`."""

AIR_CYCLE_EFFECTS = frozenset({"ambient_variation"})
"""Effects whose signal is the air's own variation: their plans span the daily cycle."""

AIR_CYCLE_DURATIONS_H = (12.0, 24.0)
"""Durations of the plans that log the daily cycle of the air, h: its rise, and all of it."""

AIR_CYCLE_WARMUP_MIN = 120.0
"""Spindle run at the top speed at the start of half of those plans, min (the machine at rest
after; the other half rest throughout)."""

DAY_H = 24.0
"""Period of the workshop air's cycle, h."""

AIR_SMOOTHING_S = 1800.0
"""Window over which the air's readings are averaged before its range is taken, s: the
reading noise averages out, a day's cycle (or an afternoon's rise) does not."""

MAX_PLANS = 150
"""Most plans tried per effect (the full grid has at most 18 program plans, nine programs at two
sampling intervals, 9 with an added sensor, 35 heater plans per heated role and 12 plans loading
two parts)."""

PLAN_REPEATS = 2
"""Campaigns of a proposed test: the test run on two days, so that one odd day does not decide
(:mod:`~pipeline.discrepancy.plan_naming` counts their samples)."""


@dataclass(frozen=True)
class TestPlan:
    """One test a user can run.

    Attributes
    ----------
    name : str
        Short label, e.g. ``"steps every 20 min, 4 h"``.
    program : Program
        The spindle program, rpm.
    duration_h : float
        Length of the test, h.
    sample_interval_s : float
        Sampling interval of the loggers, s.
    add_sensors : tuple of str
        Sensor roles to add (structure roles of the raw contract).
    own_interval : bool
        True when ``sample_interval_s`` is the campaigns' own.
    heat_loads : tuple of HeatLoad
        External heat loads to apply (W), as ``heat_loads:`` of campaign.yaml will record them.
    separates : str
        What the plan is meant to tell the effect apart from (:data:`SEPARATES`), "" for a
        plan that only makes the effect larger.
    air_swing_k : float
        Peak-to-peak range of the daily air cycle the plan is simulated with, K
        (:func:`daily_air`); 0: the air constant.
    """

    __test__ = False  # not a pytest class

    name: str
    program: Program
    duration_h: float
    sample_interval_s: float
    add_sensors: tuple[str, ...] = ()
    own_interval: bool = True
    heat_loads: tuple[HeatLoad, ...] = ()
    separates: str = ""
    air_swing_k: float = 0.0

    @property
    def cost(self) -> float:
        """Cost in test hours: the duration plus the fixed cost of each sensor and heat load."""
        return (
            self.duration_h
            + SENSOR_COST_H * len(self.add_sensors)
            + HEATER_COST_H * len(self.heat_loads)
        )

    def to_dict(self, signal_sigma: float) -> dict[str, Any]:
        """Return the plan in the raw contract's terms, with its expected signal (sigma)."""
        return {
            "spindle_program": self.program.to_contract(),
            "sample_interval_s": float(self.sample_interval_s),
            "add_sensors": [
                {"role": role, "location": f"a {role.replace('_', ' ')} sensor"}
                for role in self.add_sensors
            ],
            "heat_loads": loads_to_contract(self.heat_loads),
            "duration_h": float(self.duration_h),
            "campaigns": PLAN_REPEATS,
            "cost_h": float(self.cost),
            "name": self.name,
            "separates": self.separates,
            "air_swing_k": float(f"{self.air_swing_k:.3g}"),
            "expected_signal_sigma": float(f"{signal_sigma:.4g}"),
        }


def _order_key(plan: TestPlan) -> tuple[float, bool]:
    """Return the plan's place in the search: its cost, then the campaigns' own interval first."""
    return (plan.cost, not plan.own_interval)


def cheapest_order(plans: Sequence[TestPlan]) -> list[TestPlan]:
    """Return ``plans`` by cost, then the campaigns' own interval first, then grid order."""
    return sorted(plans, key=_order_key)


def stepped_program(high: float, low: float, period_min: float, duration_h: float) -> Program:
    """Speed steps ``high``, ``low``, ``high``... every ``period_min``, then a stop, rpm."""
    end = duration_h * 60.0
    edges = np.arange(0.0, end, period_min)
    return Program(
        tuple(
            Segment(float(a), float(min(a + period_min, end)), high if i % 2 == 0 else low)
            for i, a in enumerate(edges)
        ),
        key="rpm",
    )


def stop_restart_program(high: float, duration_h: float) -> Program:
    """Run at ``high`` a quarter of the test, stop a quarter, restart, stop: rpm."""
    q = duration_h * 60.0 / 4.0
    return Program((Segment(0.0, q, high), Segment(2 * q, 3 * q, high)), key="rpm")


def constant_program(high: float, duration_h: float) -> Program:
    """Run at ``high`` for the first half of the test, then cool down, rpm."""
    return Program((Segment(0.0, duration_h * 30.0, high),), key="rpm")


def _programs(high: float) -> list[tuple[str, Program, float]]:
    """Return the grid's spindle programs at ``high`` and half of it: (name, program, h)."""
    low = float(round(high / 2.0))
    out = []
    for duration in DURATIONS_H:
        for period in STEP_PERIODS_MIN:
            out.append(
                (
                    f"speed steps {high:.0f}/{low:.0f} rpm every {period:.0f} min, {duration:g} h",
                    stepped_program(high, low, period, duration),
                    duration,
                )
            )
        out.append(
            (
                f"stop and restart at {high:.0f} rpm, {duration:g} h",
                stop_restart_program(high, duration),
                duration,
            )
        )
    out.append((f"one run at {high:.0f} rpm then cool-down, 4 h", constant_program(high, 4.0), 4.0))
    return out


def heater(role: str, power_w: float, from_min: float, to_min: float) -> HeatLoad:
    """Return a ``power_w`` (W) heater on the part of ``role``, on ``from_min``-``to_min``."""
    program = Program((Segment(from_min, to_min, float(power_w)),), key=POWER_KEY)
    return HeatLoad(role, program, f"{power_w:g} W heater on the {role.replace('_', ' ')}")


def heater_plans(
    high: float, roles: Sequence[str], interval_s: float, separates: str = ""
) -> list[TestPlan]:
    """Return the grid's tests with a heater on one of ``roles`` (see the module docstring).

    For each duration of :data:`DURATIONS_H`, role and power of :data:`HEATER_POWERS_W`: the
    spindle at ``high`` (rpm) in the first half and the heater on for :data:`PULSE_MIN` at the
    start of the cool-down (shortest test only); the heater on in the first half with the
    spindle stopped; the spindle in the first half and the heater on in the second; the heater
    in the first half and the spindle in the second. Sampled every ``interval_s`` (s).

    The short pulse follows a spindle run rather than a cold machine: every sensor then moves
    (the machine cools), where after a pulse on a cold, stopped machine the far sensors read
    one quantised value for hours and validation quarantines the campaign for a stuck sensor.
    ``separates`` says what the plans are meant to tell the effect apart from.
    """
    plans = []
    for duration in DURATIONS_H:
        half = duration * 30.0
        run_first = constant_program(high, duration)
        run_second = Program((Segment(half, 2 * half, high),), key="rpm")
        stopped = Program((Segment(0.0, 2 * half, 0.0),), key="rpm")  # written, not left empty
        spindle = f"the spindle at {high:.0f} rpm for {half:g} min"
        patterns = [
            ("a {load} for {on:g} min with the spindle stopped", stopped, 0.0, half),
            (spindle + ", then a {load} for {on:g} min", run_first, half, half),
            ("a {load} for {on:g} min, then " + spindle, run_second, 0.0, half),
        ]
        if duration == min(DURATIONS_H):  # a short pulse at the start of the cool-down
            patterns.insert(0, (patterns[1][0], run_first, half, PULSE_MIN))
        for role in roles:
            for power in HEATER_POWERS_W:
                for words, program, on_min, length in patterns:
                    load = heater(role, power, on_min, on_min + length)
                    name = words.format(load=load.what, on=length) + f", {duration:g} h"
                    plans.append(
                        TestPlan(name, program, duration, interval_s, (), True, (load,), separates)
                    )
    return plans


def paired_heater_plans(effect: str, roles: Sequence[str], interval_s: float) -> list[TestPlan]:
    """Return the grid's tests that load the two parts of :data:`PAIRED_ROLES` differently.

    Only when both are among ``roles`` (the roles with a sensor); the spindle stays stopped.

    For each duration of :data:`DURATIONS_H` and power of :data:`PAIRED_POWERS_W`: the heater
    on the first part for half the test, then on the second for the other half; and both at
    once for the first half, the first at that power and the second at a quarter of it, then
    the cool-down. Where two effects (or an effect and a law of the baseline) share a signature
    under one load, loads whose ratio changes during the test separate them (e.g. a column's
    bending, which follows its front-to-rear difference, from its expansion, which follows its
    mean rise). Each plan records what it separates (:data:`SEPARATES`). Sampled every
    ``interval_s`` (s).
    """
    pair = PAIRED_ROLES.get(effect, ())
    if len(pair) < 2 or not set(pair) <= set(roles):
        return []
    first, second = pair
    plans = []
    for duration in DURATIONS_H:
        half = duration * 30.0
        stopped = Program((Segment(0.0, 2 * half, 0.0),), key="rpm")
        for power in PAIRED_POWERS_W:
            turns = (heater(first, power, 0.0, half), heater(second, power, half, 2 * half))
            both = (heater(first, power, 0.0, half), heater(second, power / 4.0, 0.0, half))
            turn_words = f"a {power:g} W heater on the {{a}} for {half:g} min, then on the {{b}}"
            both_words = (
                f"{power:g} W on the {{a}} and {power / 4:g} W on the {{b}} for {half:g} min"
            )
            for loads, words in ((turns, turn_words), (both, both_words)):
                name = words.format(a=first.replace("_", " "), b=second.replace("_", " "))
                plans.append(
                    TestPlan(
                        f"{name} with the spindle stopped, {duration:g} h",
                        stopped,
                        duration,
                        interval_s,
                        (),
                        True,
                        loads,
                        SEPARATES.get(effect, ""),
                    )
                )
    return plans


def air_swing_k(campaigns: Sequence[MeasuredCampaign]) -> float:
    """Return the largest range of the air within one campaign, K (0 without an air sensor).

    Each ambient sensor's readings are first averaged over :data:`AIR_SMOOTHING_S` (centred,
    by time), so that the range is the air's and not its reading noise's; the range then runs
    from the 1st to the 99th percentile, so a single spike does not set it. (Without the
    averaging, a constant air read with 0.02 K of noise spans about 0.1 K, and a day's plan at
    rest simulated with that swing showed it above the identifiability threshold: on a
    machine whose air never moved, the workflow proposed a day of logging, round after round.)
    """
    ranges = [0.0]
    for c in campaigns:
        for sensor in c.sensors_with_role("ambient"):
            values = pd.Series(
                c.temperatures[sensor].to_numpy(dtype=float), index=pd.to_timedelta(c.t_s, "s")
            ).dropna()
            if values.size:
                smooth = values.rolling(pd.Timedelta(seconds=AIR_SMOOTHING_S), center=True).mean()
                low, high = np.percentile(smooth.to_numpy(), [1.0, 99.0])
                ranges.append(float(high - low))
    return max(ranges)


def daily_air(t_s: np.ndarray, ambient_c: float, swing_k: float) -> np.ndarray:
    """Return the air of a plan: ``swing_k`` peak to peak over a day, from its low, degC.

    ``ambient_c + swing_k (1 - cos(2 pi t / day)) / 2``: the test starts at the cool of the
    morning, the air peaks after half a day.
    """
    phase = 2.0 * np.pi * np.asarray(t_s, dtype=float) / (DAY_H * 3600.0)
    return ambient_c + 0.5 * swing_k * (1.0 - np.cos(phase))


def daily_air_plans(
    high: float, swing_k: float, interval_s: float, separates: str = ""
) -> list[TestPlan]:
    """Return the plans that log the air's daily cycle (:data:`AIR_CYCLE_DURATIONS_H`).

    For each duration, two plans sampled every ``interval_s`` (s) and simulated with an air
    swing of ``swing_k`` (K): the machine at rest throughout, and a run of the spindle at
    ``high`` (rpm) for :data:`AIR_CYCLE_WARMUP_MIN` before the rest. At rest nothing but the
    air drives the machine, so the baseline (no heat, a constant air) expects it to stay as it
    started, and everything the test logs is the air's; after a warm-up run, the baseline's
    slow conduction of the spindle's heat follows much of what the air does. On an independent
    machine model (four campaigns, the air 1.1 K up through each) a 12 h test with the run
    left the held-out temperatures on its campaigns 6 % better with the measured air; the same
    12 h at rest, 82 % (:mod:`benchmarks.independent_machine`, seed 2). A rest plan is
    proposed only when its simulated air moves the sensors enough to be visible, so they do
    not read one quantised value for hours (which validation quarantines as a stuck sensor).
    ``separates`` as :func:`heater_plans`.
    """
    warm_up = Program((Segment(0.0, AIR_CYCLE_WARMUP_MIN, high),), key="rpm")
    plans = []
    for duration in AIR_CYCLE_DURATIONS_H:
        at_rest = Program((Segment(0.0, 60.0 * duration, 0.0),), key="rpm")  # written, not empty
        for name, program in (
            (f"the machine at rest through the day's air cycle, {duration:g} h", at_rest),
            (
                f"one run at {high:.0f} rpm for {AIR_CYCLE_WARMUP_MIN:g} min, then the machine at "
                f"rest through the day's air cycle, {duration:g} h",
                warm_up,
            ),
        ):
            plans.append(
                TestPlan(
                    name, program, duration, interval_s, separates=separates, air_swing_k=swing_k
                )
            )
    return plans


def own_interval_s(campaigns: Sequence[MeasuredCampaign]) -> float:
    """Return the campaigns' sampling interval: the median step of their instants, s."""
    return float(np.median(np.concatenate([np.diff(c.t_s) for c in campaigns])))


def candidate_plans(
    campaigns: Sequence[MeasuredCampaign], effect: str, roles: set[str] | frozenset[str]
) -> list[TestPlan]:
    """Return the grid of tests for ``effect`` (module docstring), at most :data:`MAX_PLANS`.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        The searched campaigns: their top speed and sampling interval set the grid's.
    effect : str
    roles : set of str
        Sensor roles the campaigns have.
    """
    high = float(max(np.max(np.abs(c.rpm)) for c in campaigns)) or 3000.0
    own = own_interval_s(campaigns)
    intervals = [(own, True)] + ([(FAST_INTERVAL_S, False)] if own > FAST_INTERVAL_S else [])
    plans = []
    programs = _programs(high)
    for name, program, duration in programs:
        for interval, is_own in intervals:
            plans.append(TestPlan(name, program, duration, interval, (), is_own))
    added = [r for r in ADDED_SENSOR_ROLES.get(effect, ()) if r not in roles]
    for role in added[:1]:
        for name, program, duration in programs:
            plans.append(TestPlan(name, program, duration, own, (role,), True))
    heated = [r for r in HEAT_LOAD_ROLES.get(effect, ()) if r in roles]
    plans += paired_heater_plans(effect, heated, own)
    plans += heater_plans(high, heated, own, SEPARATES.get(effect, ""))
    if effect in AIR_CYCLE_EFFECTS and (swing := air_swing_k(campaigns)) > 0.0:
        plans += daily_air_plans(high, swing, own, SEPARATES.get(effect, ""))
    return plans[:MAX_PLANS]


def _ambient(campaigns: Sequence[MeasuredCampaign]) -> float:
    """Mean first ambient reading of the campaigns (or first reading of any sensor), degC."""
    first = []
    for c in campaigns:
        cols = c.sensors_with_role("ambient") or list(c.temperatures.columns)
        values = c.temperatures[cols[0]].to_numpy(dtype=float)
        ok = np.isfinite(values)
        if ok.any():
            first.append(values[ok][0])
    return float(np.mean(first)) if first else 20.0


def simulate_plan(
    plan: TestPlan,
    values: Mapping[str, float],
    sensors: Mapping[str, str],
    ambient_c: float,
) -> tuple[MeasuredCampaign, frozenset[str], dict[str, float]]:
    """Simulate the plan's campaign with the calibrated baseline twin, noise-free.

    Parameters
    ----------
    plan : TestPlan
    values : mapping of str to float
        Calibrated baseline parameters by name (their units).
    sensors : mapping of str to str
        Sensor name -> role, the campaigns' (:func:`plan_sensors`); a sensor
        ``added_<role>`` joins them for each role the plan adds.
    ambient_c : float
        Workshop air at the start, degC; every node starts at it. It stays constant unless the
        plan has an ``air_swing_k`` (:func:`daily_air`).

    Returns
    -------
    campaign : MeasuredCampaign
        The sensors' readings, the Z drift, the plan's program.
    roles : frozenset of str
        The twin's roles.
    values : dict of str to float
        Every parameter of the twin: the baseline's, the initial value for a new node's.
    """
    blank, model = plan_campaign(plan, sensors, ambient_c)
    full = {p.name: float(values.get(p.name, p.initial)) for p in model.param_specs}
    sim = model.simulate(np.array([full[n] for n in model.names]), blank)
    temps = blank.temperatures.copy()
    for s in sim.temperatures.columns:
        temps[s] = sim.temperatures[s].to_numpy()
    campaign = MeasuredCampaign(
        campaign_id=blank.campaign_id,
        t_s=blank.t_s,
        rpm=blank.rpm,
        temperatures=temps,
        roles=blank.roles,
        z_um=np.asarray(sim.z_um, dtype=float) - float(sim.z_um[0]),
        program=plan.program,
        heat_loads=plan.heat_loads,
    )
    return campaign, model.roles, full


def plan_campaign(
    plan: TestPlan, sensors: Mapping[str, str], ambient_c: float
) -> tuple[MeasuredCampaign, TwinModel]:
    """Return the plan's campaign with every sensor at ``ambient_c`` (degC), and its twin.

    The sensors are ``sensors`` (name -> role) and one ``added_<role>`` per role the plan adds;
    the twin is built for their roles and the plan's heat loads. With the plan's
    ``air_swing_k``, the ambient sensors read :func:`daily_air` instead.
    """
    names = {**dict(sensors), **{f"added_{r}": r for r in plan.add_sensors}}
    t = np.arange(0.0, plan.duration_h * 3600.0 + 0.5, plan.sample_interval_s)
    air = daily_air(t, ambient_c, plan.air_swing_k)
    blank = MeasuredCampaign(
        campaign_id=f"plan {plan.name}",
        t_s=t,
        rpm=plan.program.value_at(t),
        temperatures=pd.DataFrame(
            {
                s: air if role == "ambient" else np.full(t.size, ambient_c)
                for s, role in names.items()
            }
        ),
        roles=names,
        z_um=np.zeros(t.size),
        program=plan.program,
        heat_loads=plan.heat_loads,
    )
    return blank, build_model(frozenset(names.values()), load_roles=loaded_roles([blank]))


def plan_rises(
    plan: TestPlan, twin: PlanTwin, sensors: Mapping[str, str], ambient_c: float
) -> tuple[float, float]:
    """Return the plan's peak rise at the planning point and its bound over the draws, K.

    Parameters
    ----------
    plan : TestPlan
    twin : PlanTwin
        The planning point and the posterior draws (:func:`~pipeline.discrepancy.plan_twin
        .plan_twin`); a parameter the plan's twin adds (a new node's) takes its initial value.
    sensors : mapping of str to str
    ambient_c : float

    Returns
    -------
    expected : float
        Largest rise of a sensed structure node over its first value, at ``twin.values``, K.
    bound : float
        Its :data:`~pipeline.discrepancy.plan_twin.RISE_QUANTILE` quantile over the draws
        (at least ``expected``), K.
    """
    blank, model = plan_campaign(plan, sensors, ambient_c)
    column = {name: i for i, name in enumerate(twin.names)}
    thetas = np.array(
        [
            [(draw[column[p.name]] if p.name in column else p.initial) for p in model.param_specs]
            for draw in twin.draws
        ]
    )
    point = np.array([twin.values.get(p.name, p.initial) for p in model.param_specs])
    rises = peak_rises(model, np.vstack([point, thetas]), blank)
    return float(rises[0]), float(max(rises[0], np.quantile(rises[1:], RISE_QUANTILE)))


@dataclass(frozen=True)
class ProposedTest:
    """The plan proposed for one effect, or the best the grid reached when none is visible.

    Attributes
    ----------
    effect : str
    plan : TestPlan or None
        The proposed plan (:func:`propose_test`: the cheapest visible one whose response would
        pass the search's rule, else the cheapest visible one); None when no plan of the grid
        makes the effect visible.
    figures : Visibility or None
        The effect's figures under ``plan`` (or under ``best`` when none is visible).
    best : TestPlan or None
        The plan with the largest signal when none is visible.
    current_sigma : float
        The effect's signal on the campaigns, noise sigmas.
    threshold_sigma : float
        ``min_signal_sigma``.
    n_plans : int
        Plans tried.
    sensors_tried : bool
        Whether the grid had plans with an added sensor.
    heaters_tried : bool
        Whether the grid had plans with a heat load.
    rise_limit_k : float
        The envelope: the largest rise any sensor showed in the campaigns
        (:func:`~pipeline.discrepancy.plan_envelope.rise_limit_k`), K; a plan whose rise bound
        exceeds it is not proposed.
    plan_rise : PlanRise or None
        Largest rise the twin expects at a sensor under the proposed (or best) plan, and its
        bound over the posterior draws, K.
    too_hot : int
        Plans left out because they would leave the envelope.
    calibration : TestPlan or None
        When no plan is visible within the envelope: a heater plan within it on a part the
        campaigns never heated, to run first (:func:`propose_test`).
    calibration_rise : PlanRise or None
        The calibration step's rises, K.
    misfit_limited : bool
        The proposed plan shows the effect above the identifiability thresholds, but too
        little against the twin's held-out misfit for the search's rule to name it from this
        test alone (:mod:`~pipeline.discrepancy.plan_naming`).
    unconfirmed : str
        Why the effect, visible on the campaigns, is not identifiable: the fit prefers it and
        the held-out campaigns do not confirm it
        (:func:`~pipeline.discrepancy.identifiability.unconfirmed_effects`); "" otherwise.
    """

    effect: str
    plan: TestPlan | None
    figures: Visibility | None
    best: TestPlan | None
    current_sigma: float
    threshold_sigma: float
    n_plans: int
    sensors_tried: bool = False
    heaters_tried: bool = False
    rise_limit_k: float = float("nan")
    plan_rise: PlanRise | None = None
    too_hot: int = 0
    calibration: TestPlan | None = None
    calibration_rise: PlanRise | None = None
    misfit_limited: bool = False
    unconfirmed: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready ``proposed_test``: the plan in the raw contract's terms and its text."""
        signal = self.figures.signal_sigma if self.figures is not None else float("nan")
        out: dict[str, Any] = {"visible": self.plan is not None, "plans_tried": self.n_plans}
        out["plans_too_hot"] = self.too_hot
        out["rise_limit_K"] = json_figure(self.rise_limit_k)
        shown = _signal_dict(self.figures)
        if self.plan is not None:
            out.update(self.plan.to_dict(signal), **shown, **_rise_dict(self.plan_rise))
        out["misfit_limited"] = self.misfit_limited
        if self.plan is None and self.best is not None:
            out["best_in_grid"] = {
                **self.best.to_dict(signal),
                **shown,
                **_rise_dict(self.plan_rise),
            }
        if self.calibration is not None:
            step = self.calibration.to_dict(float("nan"))
            step.pop("expected_signal_sigma")
            out["calibration_step"] = {**step, **_rise_dict(self.calibration_rise)}
        out["text"] = plan_text(self)
        return out


def _signal_dict(figures: Visibility | None) -> dict[str, float | None]:
    """Return the visible response under a plan, um (Z) and K (temperatures)."""
    if figures is None:
        return {}
    return {
        "expected_signal_Z_um": json_figure(figures.signal_z_um),
        "expected_signal_T_K": json_figure(figures.signal_t_k),
    }


def _rise_dict(rise: PlanRise | None) -> dict[str, float | None]:
    """Return a plan's rises as ``discrepancy.json`` writes them, K."""
    if rise is None:
        return {"expected_max_rise_K": None, "max_rise_bound_K": None}
    return {
        "expected_max_rise_K": json_figure(rise.expected),
        "max_rise_bound_K": json_figure(rise.bound),
    }


def _program_words(plan: TestPlan) -> str:
    """Return the plan's program, sampling and sensors in words."""
    words = (
        f"run a {plan.duration_h:g} h test from a cold machine on each of {PLAN_REPEATS} days, "
        f"{plan.name.rsplit(',', 1)[0]} (the `spindle_program` of `proposed_test`), logging "
        f"every {plan.sample_interval_s:g} s"
    )
    if plan.add_sensors:
        words += f", with a sensor added on role {', '.join(plan.add_sensors)}"
    if plan.heat_loads:
        loads = "; ".join(_load_words(load) for load in plan.heat_loads)
        words += f", and record the heat load under `heat_loads:` in campaign.yaml ({loads})"
    if plan.air_swing_k:
        words += (
            f"; start in the cool of the morning: the twin assumes the workshop air swings by "
            f"{plan.air_swing_k:.1f} K over the day (the largest range one campaign recorded)"
        )
    if plan.separates:
        words += f"; the test is meant to tell it apart from {plan.separates}"
    return words


def _load_words(load: HeatLoad) -> str:
    """Return a load in words: what, where, when."""
    spans = ", ".join(
        f"{s.from_min:g}-{s.to_min:g} min" if s.to_min is not None else f"from {s.from_min:g} min"
        for s in load.program.segments
    )
    powers = "/".join(f"{s.value:g}" for s in load.program.segments)
    return f"role {load.role}, {spans}, {powers} W"


def plan_text(proposed: ProposedTest) -> str:
    """One paragraph for the engineer: the test to run and what the twin expects it to show."""
    e = f"`{proposed.effect}`"
    now = f"{proposed.current_sigma:.2f} sigma on these campaigns"
    aim = (
        f"To show {e} on campaigns of its own ({now}; {proposed.unconfirmed})"
        if proposed.unconfirmed
        else f"To make {e} visible ({now}, threshold {proposed.threshold_sigma:g})"
    )
    if proposed.plan is not None and proposed.figures is not None:
        return (
            f"{aim}, "
            f"{_program_words(proposed.plan)}. The calibrated twin expects it to leave "
            f"{proposed.figures.signal_sigma:.2f} noise sigmas beyond what the baseline absorbs "
            f"(cost {proposed.plan.cost:g} test hours, the cheapest of {proposed.n_plans} plans "
            f"tried{_envelope_words(proposed)}).{_misfit_words(proposed)}"
            f"{_watch_words(proposed.plan, proposed)} Add the campaigns to the raw folder and "
            "rerun `thermal discrepancy`."
        )
    best = (
        f" The best, to {_program_words(proposed.best)}, reaches "
        f"{proposed.figures.signal_sigma:.2f} sigma."
        if proposed.best is not None and proposed.figures is not None
        else ""
    )
    tried = (
        "speed steps, stops, sampling interval"
        + (", added sensors" if proposed.sensors_tried else "")
        + (", heat loads" if proposed.heaters_tried else "")
        + (", a day's air cycle" if proposed.effect in AIR_CYCLE_EFFECTS else "")
    )
    head = (
        f"None of the {proposed.n_plans} test plans tried ({tried}) would make {e} visible "
        f"({now}, threshold {proposed.threshold_sigma:g}){_envelope_words(proposed)}.{best}"
    )
    if proposed.calibration is not None:
        return head + _calibration_words(proposed)
    return (
        f"{head} Its response at a plausible size stays within what the baseline absorbs; "
        f"{_what_else(proposed)} would be needed."
    )


def _misfit_words(proposed: ProposedTest) -> str:
    """Return the warning of a plan too weak for the search's rule ("" otherwise)."""
    if not proposed.misfit_limited:
        return ""
    return (
        " No plan in the envelope shows it enough against what the twin already misses on the "
        "held-out campaigns for the search to name it from this test alone; the rerun will "
        "propose the next."
    )


def _calibration_words(proposed: ProposedTest) -> str:
    """Return the paragraph's calibration step: why, what to run, what comes next."""
    plan, rise = proposed.calibration, proposed.calibration_rise
    assert plan is not None and rise is not None
    parts = ", ".join(sorted({load.role for load in plan.heat_loads}))
    return (
        f" The campaigns never heated the {parts.replace('_', ' ')} directly, so the twin "
        "can tell neither how far a heater warms it nor what a test heating it would show: "
        "the tests that could show the effect are held back by that doubt. First "
        f"{_program_words(plan)}: a calibration step (cost "
        f"{plan.cost:g} test hours; the twin expects a rise of {rise.expected:.1f} K, at most "
        f"{rise.bound:.1f} K).{_watch_words(plan, proposed)} Add the campaign to the raw folder "
        f"and rerun `thermal discrepancy`: it then proposes the test for {proposed.effect!r} "
        "from the part's measured response."
    )


def _watch_words(plan: TestPlan, proposed: ProposedTest) -> str:
    """Return the safety instruction of a plan with a heat load ("" without one)."""
    if not plan.heat_loads:
        return ""
    return (
        f" Watch the heated part's sensor and switch the heater off if any sensor rises more "
        f"than {proposed.rise_limit_k:.1f} K."
    )


def _envelope_words(proposed: ProposedTest) -> str:
    """Return how many plans were left out for heating a part beyond the envelope ("" if none)."""
    if not proposed.too_hot:
        return ""
    return (
        f"; {proposed.too_hot} plans left out because they could heat a part more than "
        f"{proposed.rise_limit_k:.1f} K (the largest rise in these campaigns, at least "
        f"{ENVELOPE_FLOOR_K:g} K; what a plan could do is the {RISE_QUANTILE:.0%} quantile over "
        "the twin's uncertainty, and for a heater on a part no campaign heated, its energy kept "
        "in the part's smallest plausible heat capacity)"
    )


def _what_else(proposed: ProposedTest) -> str:
    """Return what is left to try when no plan of the grid makes the effect visible."""
    left = ["a longer campaign series", "a different sensor mounting"]
    if not proposed.heaters_tried:
        left.append("an external heat load")
    return ", ".join(left[:-1]) + " or " + left[-1]


def _plan_point(
    plan: TestPlan,
    values: Mapping[str, float],
    sensors: Mapping[str, str],
    ambient_c: float,
    noise: NoiseFloor,
    prior_log_sd: float,
) -> BaselinePoint:
    """Return the baseline point on the plan's simulated campaign, with the campaigns' noise.

    An added sensor reads with the median noise floor of the campaigns' sensors.
    """
    campaign, all_roles, full = simulate_plan(plan, values, sensors, ambient_c)
    typical = float(np.median(list(noise.temperature_K.values()))) if noise.temperature_K else 0.0
    floors = {f"added_{r}": typical for r in plan.add_sensors}
    plan_noise = NoiseFloor({**noise.temperature_K, **floors}, noise.z_um)
    return baseline_point([campaign], full, set(all_roles), plan_noise, prior_log_sd)


def plan_sensors(campaigns: Sequence[MeasuredCampaign]) -> dict[str, str]:
    """Return the campaigns' sensors on a node of the twin or on the air: name -> role.

    The plan's campaign carries the same sensors, so each reads with its own noise floor.
    """
    out: dict[str, str] = {}
    for c in campaigns:
        for name, role in c.roles.items():
            if name not in out and (role in ROLE_NODES or role == "ambient"):
                out[name] = role
    return out


def _first_heating(plan: TestPlan, loaded: frozenset[str]) -> bool:
    """Whether ``plan`` heats only parts that no campaign of ``loaded`` heated (and heats some)."""
    return bool(plan.heat_loads) and all(load.role not in loaded for load in plan.heat_loads)


def propose_test(
    effect: str,
    current: EffectIdentifiability,
    plans: Sequence[TestPlan],
    point_of: Callable[[TestPlan], BaselinePoint],
    rise_of: Callable[[TestPlan], PlanRise],
    settings: IdentifiabilitySettings,
    rise_limit_k: float = float("inf"),
    loaded: frozenset[str] = frozenset(),
    named_if: Callable[[TestPlan, Visibility], bool] | None = None,
    first_heating_point_of: Callable[[TestPlan], BaselinePoint] | None = None,
) -> ProposedTest:
    """Try ``plans`` cheapest first; return the cheapest that makes ``effect`` visible.

    A plan is visible when the effect is visible under it at the planning point and its rise
    bound stays in the envelope. Of the visible plans whose response would also pass the
    search's rule (``named_if``), the cheapest is proposed (own sampling interval first; of
    equal cost the one with the largest signal, so that a plan that shows the effect more
    clearly is not passed over for its place in the grid). When no visible plan would pass the
    rule, the cheapest visible one is proposed all the same, flagged ``misfit_limited``: the
    rerun may need the next test.

    When none is visible, the calibration step (:func:`_calibration_step`) heats a part no
    campaign heated (``loaded``) that is *held back*: a plan heating it leaves the effect
    above the identifiability thresholds (the naming rule is not asked: its response is scored
    with the very parameters the step is there to measure) and the twin expects it within the
    envelope, but its bound, the doubt about a part never heated, is not; or one shows the
    effect only with the part at typical parameters (the same doubt about what it would show).

    Parameters
    ----------
    effect : str
    current : EffectIdentifiability
        Its class and figures on the campaigns.
    plans : sequence of TestPlan
    point_of : callable
        ``TestPlan -> BaselinePoint`` at the planning point (cached by the caller: one point
        serves every effect).
    rise_of : callable
        ``TestPlan -> PlanRise`` (cached by the caller).
    settings : IdentifiabilitySettings
    rise_limit_k : float
        Plans whose rise bound exceeds it, K, are left out (:func:`rise_limit_k` of the
        campaigns).
    loaded : frozenset of str
        Roles some campaign put an external heat load on.
    named_if : callable, optional
        ``(TestPlan, Visibility) -> bool``: whether the search would name the effect with the
        plan's campaigns added (:func:`~pipeline.discrepancy.plan_naming.would_be_named`);
        default: visible is enough.
    first_heating_point_of : callable, optional
        ``point_of`` with the parts heated for the first time at typical parameters
        (:func:`~pipeline.discrepancy.plan_envelope.first_heating_values`); default: none.
    """
    ordered = cheapest_order(plans)
    scan = _scan(
        effect,
        ordered,
        point_of,
        rise_of,
        settings,
        rise_limit_k,
        loaded,
        named_if,
        first_heating_point_of,
    )
    common = (ordered, settings, rise_limit_k, scan.too_hot, scan.tried)
    found = scan.chosen or scan.fallback
    if found is not None:
        return _proposed(effect, current, found, *common, misfit_limited=scan.chosen is None)
    step = _calibration_step(scan.safe_first, scan.held_back)
    return _proposed(effect, current, scan.best, *common, step, visible=False)


def _scan(
    effect: str,
    ordered: Sequence[TestPlan],
    point_of: Callable[[TestPlan], BaselinePoint],
    rise_of: Callable[[TestPlan], PlanRise],
    settings: IdentifiabilitySettings,
    rise_limit_k: float,
    loaded: frozenset[str],
    named_if: Callable[[TestPlan, Visibility], bool] | None,
    first_heating_point_of: Callable[[TestPlan], BaselinePoint] | None,
) -> _Scan:
    """Try the plans of :func:`propose_test` (its parameters), cheapest first; return the pass."""
    scan = _Scan()
    for plan in ordered:
        if scan.done(plan):
            break  # every plan as cheap as the first visible one was tried
        scan.tried += 1
        rise = rise_of(plan)
        first = _first_heating(plan, loaded)
        too_hot = rise.bound > rise_limit_k
        scan.too_hot += too_hot
        if too_hot and not (first and rise.expected <= rise_limit_k):
            continue
        figures = visibility(effect, point_of(plan), settings.plausible)
        clear = not shortfalls(figures, settings)
        if first and (too_hot or not clear):  # held back by the doubt about a part never heated?
            held = (
                figures.signal_sigma
                if clear
                else _typical_signal(effect, plan, first_heating_point_of, settings)
            )
            scan.hold_back(plan, held, clear)
        if too_hot:
            continue
        if first:
            scan.safe_first.append((plan, rise))
        signal = figures.signal_sigma if np.isfinite(figures.signal_sigma) else -1.0
        entry = (signal, plan, figures, rise)
        if clear:
            scan.visible(entry, named_if is None or named_if(plan, figures))
        if scan.best is None or signal > scan.best[0]:
            scan.best = entry
    return scan


_Entry = tuple[float, TestPlan, Visibility, PlanRise]
"""A plan tried: its signal (sigma), the plan, its figures and its rises."""


@dataclass
class _Scan:
    """What the cheapest-first pass of :func:`propose_test` found.

    Attributes
    ----------
    best : _Entry or None
        The largest signal of the plans in the envelope.
    chosen : _Entry or None
        The visible plan the search's rule would name (the clearest of the lowest cost).
    fallback : _Entry or None
        The cheapest visible plan the rule would not name (the clearest of its cost).
    safe_first : list of (TestPlan, PlanRise)
        Plans within the envelope that heat parts no campaign heated.
    held_back : dict of str to (bool, float)
        Parts whose doubt alone keeps a visible plan back, each with the clearest plan it holds
        back: whether that plan is visible at the planning point (rather than only with the part
        at typical parameters), and its signal, sigma; the first ranks before the second.
    too_hot, tried : int
        Plans left out by the envelope; plans tried.
    """

    best: _Entry | None = None
    chosen: _Entry | None = None
    fallback: _Entry | None = None
    safe_first: list[tuple[TestPlan, PlanRise]] = field(default_factory=list)
    held_back: dict[str, tuple[bool, float]] = field(default_factory=dict)
    too_hot: int = 0
    tried: int = 0

    def done(self, plan: TestPlan) -> bool:
        """Whether ``plan`` costs more than the chosen one (the pass can stop)."""
        return self.chosen is not None and _order_key(plan) != _order_key(self.chosen[1])

    def hold_back(self, plan: TestPlan, signal: float | None, at_planning_point: bool) -> None:
        """Record a visible plan that only the doubt about the parts it heats holds back.

        ``signal`` (sigma) is None when the plan would not show the effect even so;
        ``at_planning_point``: visible with the planning twin's values, not only with the parts
        at typical parameters.
        """
        if signal is None:
            return
        entry = (at_planning_point, signal)
        for load in plan.heat_loads:
            self.held_back[load.role] = max(entry, self.held_back.get(load.role, entry))

    def visible(self, entry: _Entry, named: bool) -> None:
        """Record a visible plan; ``named``: the search's rule would name the effect."""
        signal, plan = entry[0], entry[1]
        if named:
            if self.chosen is None or signal > self.chosen[0]:
                self.chosen = entry
        elif self.fallback is None or (
            _order_key(plan) == _order_key(self.fallback[1]) and signal > self.fallback[0]
        ):
            self.fallback = entry


def _typical_signal(
    effect: str,
    plan: TestPlan,
    first_heating_point_of: Callable[[TestPlan], BaselinePoint] | None,
    settings: IdentifiabilitySettings,
) -> float | None:
    """Return the signal of ``effect`` (sigma) under a first heating at typical parameters.

    The plan's parts heated for the first time take their typical parameters; None when the
    effect misses a threshold there (or ``first_heating_point_of`` is None).
    """
    if first_heating_point_of is None:
        return None
    figures = visibility(effect, first_heating_point_of(plan), settings.plausible)
    return None if shortfalls(figures, settings) else figures.signal_sigma


def _calibration_step(
    safe_first: Sequence[tuple[TestPlan, PlanRise]],
    held_back: Mapping[str, tuple[bool, float]],
) -> tuple[TestPlan, PlanRise] | None:
    """Return the calibration step: the cheapest safe first heating of a held-back part.

    Of equal cost, the one on the part that holds back the clearest test (``held_back``: a
    test visible at the planning point before one visible only with the part at typical
    parameters, then the larger signal; a calibration step measures one part, so the part
    behind the most promising test first); on that part, the one that drives it hardest
    (the largest adiabatic bound: the heater's energy over the part's smallest plausible heat
    capacity), for the clearest reading of its response; then the one the twin expects to
    heat most. The twin's expected rise alone would favour whatever runs the spindle longest:
    on the demo it picked a 10 W heater on the headstock for 2 h before a spindle run (at most
    5.3 K from the heater) over a 25 W pulse on the motor (at most 8.3 K), because the spindle
    run dominated both peak rises. None when no part's doubt holds a visible plan back.
    """
    useful = [
        (plan, rise, min(held_back[load.role] for load in plan.heat_loads))
        for plan, rise in safe_first
        if all(load.role in held_back for load in plan.heat_loads)
    ]
    step = min(
        useful,
        key=lambda entry: (
            entry[0].cost,
            not entry[2][0],
            -entry[2][1],
            -entry[1].first_heating,
            -entry[1].expected,
        ),
        default=None,
    )
    return None if step is None else step[:2]


def _proposed(
    effect: str,
    current: EffectIdentifiability,
    chosen: tuple[float, TestPlan, Visibility, PlanRise] | None,
    ordered: Sequence[TestPlan],
    settings: IdentifiabilitySettings,
    rise_limit_k: float,
    too_hot: int,
    tried: int,
    calibration: tuple[TestPlan, PlanRise] | None = None,
    visible: bool = True,
    misfit_limited: bool = False,
) -> ProposedTest:
    """Build the :class:`ProposedTest` from the chosen ``(signal, plan, figures, rise)``; log it.

    ``visible``: the chosen plan makes the effect visible (else it is the grid's best, and
    ``calibration`` the calibration step, if any).
    """
    now = current.figures.signal_sigma if current.figures is not None else float("nan")
    _, plan, figures, rise = chosen if chosen is not None else (None, None, None, None)
    step, step_rise = calibration if calibration is not None else (None, None)
    proposed = ProposedTest(
        effect,
        plan if visible else None,
        figures,
        None if visible else plan,
        now,
        settings.min_signal_sigma,
        tried,
        sensors_tried=any(p.add_sensors for p in ordered),
        heaters_tried=any(p.heat_loads for p in ordered),
        rise_limit_k=rise_limit_k,
        plan_rise=rise,
        too_hot=too_hot,
        calibration=step,
        calibration_rise=step_rise,
        misfit_limited=misfit_limited,
        unconfirmed=current.unconfirmed,
    )
    logger.info("test plan for %s: %s", effect, plan_text(proposed))
    return proposed


def _log_planning_twin(twin: PlanTwin, point: BaselinePoint) -> None:
    """Log the refit's SSE ratio and the parameters it moved by more than a factor 2."""
    moved = twin.moved(point.values)
    logger.info(
        "test plans are scored with the baseline refitted with its priors (SSE x %.3f)%s",
        twin.sse_ratio,
        "; moved by more than 2x: "
        + ", ".join(f"{k} {a:.3g} -> {b:.3g}" for k, (a, b) in moved.items())
        if moved
        else "",
    )


def propose_tests(
    point: BaselinePoint,
    classes: Mapping[str, EffectIdentifiability],
    settings: IdentifiabilitySettings,
    floor: HeldOutFloor | None = None,
) -> dict[str, ProposedTest]:
    """Propose a test plan for every effect classed not identifiable.

    The plans are scored with the planning twin of ``point``
    (:func:`~pipeline.discrepancy.plan_twin.plan_twin`: the baseline refitted with its priors,
    and draws from its posterior), not with the search's values as they are.

    Parameters
    ----------
    point : BaselinePoint
        The calibrated baseline on the searched campaigns (its values, roles, noise floors).
    classes : mapping of str to EffectIdentifiability
        The class of every candidate effect.
    settings : IdentifiabilitySettings
    floor : HeldOutFloor, optional
        The search's held-out floor: a plan must leave a response that passes its rule with
        :data:`PLAN_REPEATS` campaigns of the plan added
        (:func:`~pipeline.discrepancy.plan_naming.would_be_named`). Default: visible is enough.

    Returns
    -------
    dict of str to ProposedTest
        Effect -> its proposed test, for the not-identifiable effects, in ``classes`` order.
    """
    wanted = [effect for effect, entry in classes.items() if entry.status == NOT_IDENTIFIABLE]
    if not wanted:
        return {}
    twin = plan_twin(point)
    _log_planning_twin(twin, point)
    scores = _PlanScores(point, twin, plan_sensors(point.campaigns), _ambient(point.campaigns))
    limit = rise_limit_k(point.campaigns)

    def named_if(effect: str) -> Callable[[TestPlan, Visibility], bool] | None:
        if floor is None:
            return None

        def check(plan: TestPlan, figures: Visibility) -> bool:
            n_z, n_t = counted_samples(scores.point(plan).campaigns)
            return would_be_named(effect, figures, floor, PLAN_REPEATS * n_z, PLAN_REPEATS * n_t)

        return check

    return {
        effect: propose_test(
            effect,
            classes[effect],
            candidate_plans(point.campaigns, effect, point.roles),
            scores.point,
            scores.rise,
            settings,
            limit,
            point.load_roles,
            named_if(effect),
            scores.first_heating_point,
        )
        for effect in wanted
    }


@dataclass
class _PlanScores:
    """The simulated campaigns and rises of the plans, each computed once for every effect.

    Attributes
    ----------
    searched : BaselinePoint
        The calibrated baseline on the searched campaigns.
    twin : PlanTwin
        Its planning twin.
    sensors : dict of str to str
        The campaigns' sensors (:func:`plan_sensors`).
    ambient_c : float
        The plans' air, degC.
    """

    searched: BaselinePoint
    twin: PlanTwin
    sensors: dict[str, str]
    ambient_c: float
    points: dict[TestPlan, BaselinePoint] = field(default_factory=dict)
    typical_points: dict[TestPlan, BaselinePoint] = field(default_factory=dict)
    rises: dict[TestPlan, PlanRise] = field(default_factory=dict)

    def point(self, plan: TestPlan) -> BaselinePoint:
        """Return the baseline point on the plan's campaign simulated by the planning twin."""
        if plan not in self.points:
            self.points[plan] = self._simulated(plan, self.twin.values)
        return self.points[plan]

    def first_heating_point(self, plan: TestPlan) -> BaselinePoint:
        """Return :meth:`point` with the parts heated for the first time at typical values."""
        if plan not in self.typical_points:
            first = {load.role for load in plan.heat_loads} - set(self.searched.load_roles)
            model = plan_campaign(plan, self.sensors, self.ambient_c)[1]
            values = first_heating_values(self.twin.values, model, first)
            self.typical_points[plan] = self._simulated(plan, values)
        return self.typical_points[plan]

    def rise(self, plan: TestPlan) -> PlanRise:
        """Return how far the plan heats the machine: the twin's expectation and the bounds."""
        if plan not in self.rises:
            expected, bound = plan_rises(plan, self.twin, self.sensors, self.ambient_c)
            searched = self.searched
            first = first_heating_bound_k(
                plan.heat_loads, searched.load_roles, searched.prior_log_sd
            )
            self.rises[plan] = PlanRise(expected, max(bound, first), first)
        return self.rises[plan]

    def _simulated(self, plan: TestPlan, values: Mapping[str, float]) -> BaselinePoint:
        searched = self.searched
        return _plan_point(
            plan, values, self.sensors, self.ambient_c, searched.noise, searched.prior_log_sd
        )

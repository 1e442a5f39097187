"""Hidden-effect trials: does the discrepancy workflow name what was hidden in the data.

For each case (no effect, each of the six effects alone, pairs), a machine with exactly those
effects switched on, random plausible parameters and realistic sensor and probe noise writes
"measured" campaigns with speed steps and cool-downs in the raw contract. Two machines
(:data:`GENERATORS`): the project's twin
(:func:`pipeline.twin.campaigns.simulate_spindle_campaign`), whose effects have exactly the forms
the search fits, and a machine model written without it
(:mod:`benchmarks.independent_machine`: its own discretisation, effect forms and instruments),
on which a rule that holds only because the forms match fails. The workflow
(:mod:`pipeline.discrepancy.workflow`) runs on the folder like on any measurements. The truth is
used only to score the result: a trial is *correct* when the named effects equal the hidden
ones and, when something was hidden, the held-out displacement RMS after adding them is at most
half the baseline's; the *gap halved* when the held-out displacement or temperature RMS at
least halved (an effect such as ``motor_heat`` shows in the temperatures far more than in Z).

Each trial also records the identifiability class of every hidden effect and which
candidates were classed not identifiable. For a hidden effect classed not identifiable with a
visible proposed test (or, without one, a calibration step), the trial runs that test on the
same machine (:func:`follow_plan`: the same drawn parameters, the effect still hidden, the
proposal's ``campaigns`` of the proposed ``spindle_program``, ``sample_interval_s`` and
``heat_loads``), adds them to the campaigns, reruns the workflow and records whether the
effect is named and how the held-out Z and temperature gaps moved; when the rerun proposes
another test, that one is run too, up to :data:`PLAN_ROUNDS`. With nothing hidden, the tests
proposed for the effects classed not identifiable are run on the clean machine: naming
anything then is a false alarm.

``python -m benchmarks.discrepancy_trials --seeds 1 2 3 4 5 --out reports/discrepancy_trials`` runs
every case over the seeds on both machines (``--generators`` to choose) and writes
``trials.csv`` (one row per machine, case and seed) as each trial ends and ``rates.md`` (rate of
correct naming per machine and case) at the end; ``--resume`` keeps the trials an interrupted run of
the same setting and code left there (:mod:`benchmarks.trial_resume`) and runs the others.
The trials run seed by seed, so an interrupted run holds whole seeds of every case. The slow
tests run the same trials with one seed per case.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import norm
from statsmodels.stats.proportion import proportion_confint

from benchmarks import independent_machine, trial_resume
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.followup import FollowUp
from pipeline.discrepancy.identifiability import NOT_IDENTIFIABLE
from pipeline.discrepancy.search import CANDIDATE_EFFECTS
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.validate import ValidateSettings
from pipeline.thermal.loads import loads_from_contract
from pipeline.thermal.program import Program, Segment
from pipeline.twin.campaigns import SpindlePlan, simulate_spindle_campaign
from pipeline.twin.params import SpindleParams
from pipeline.twin.writer import write_campaign

logger = logging.getLogger(__name__)

PAIRS = (("ambient_variation", "motor_heat"), ("centrifugal_growth", "nonlinear_bearing_heat"))
"""Two-effect cases of the trials."""

CASES: tuple[frozenset, ...] = (
    frozenset(),
    *(frozenset({e}) for e in CANDIDATE_EFFECTS),
    *(frozenset(p) for p in PAIRS),
)
"""Every trial case: nothing hidden, each effect alone, the pairs."""

PROGRAMS = (
    ((0.0, 2000.0), (120.0, 6000.0)),
    ((0.0, 4000.0), (90.0, 2000.0), (180.0, 6000.0)),
    ((0.0, 6000.0), (150.0, 3000.0)),
    ((0.0, 3000.0), (100.0, 5000.0)),
    ((0.0, 5000.0), (120.0, 2000.0), (200.0, 4000.0)),
    ((0.0, 2500.0), (80.0, 4500.0), (160.0, 6000.0)),
    ((0.0, 6000.0), (60.0, 4000.0)),
    ((0.0, 4000.0), (140.0, 6000.0)),
)
"""Speed steps ((from_min, rpm), ...) of the trial campaigns, 270 min running each."""

QUICK_CAMPAIGNS = 4
"""Campaigns per trial in ``--quick`` mode (with 2 folds)."""

PLAN_CAMPAIGNS = 2
"""Campaigns of a proposed test run per follow-up when the proposal gives no ``campaigns``
count (the search holds campaigns out)."""

PLAN_ROUNDS = 3
"""Proposed tests run one after the other at most: when the first test's campaigns still do
not show the effect, the rerun (whose twin now knows the part the test heated) proposes the
next, as an engineer would go on."""

HEAT_SCATTER_REL = 0.02
"""Campaign-to-campaign relative scatter of the bearing and motor heat in the trials (2 %): an
unmeasured state no twin can know, which sets the floor of the held-out residual."""


@dataclass(frozen=True)
class SteppedPlan(SpindlePlan):
    """A spindle test with speed steps, then a cool-down.

    Attributes
    ----------
    steps : tuple of (float, float)
        ``(from_min, rpm)`` of each step; the last one lasts until ``run_min``.
    """

    steps: tuple[tuple[float, float], ...] = ((0.0, 4000.0),)

    def program(self) -> Program:
        """Return the steps up to ``run_min``, then 0 rpm (open-ended)."""
        ends = [s[0] for s in self.steps[1:]] + [self.run_min]
        segments = [Segment(a, b, v) for (a, v), b in zip(self.steps, ends, strict=True)]
        segments.append(Segment(self.run_min, None, 0.0))
        return Program(tuple(segments), key="rpm")


@dataclass(frozen=True)
class ContractPlan(SpindlePlan):
    """A spindle test whose program is a contract ``spindle_program`` list.

    Attributes
    ----------
    entries : tuple of dict
        ``{from_min, to_min, rpm}`` entries (minutes, rpm).
    """

    entries: tuple[dict, ...] = ()

    def program(self) -> Program:
        """Return the contract program."""
        return Program.from_contract(self.entries, key="rpm")


def hidden_params(rng: np.random.Generator, heat_scatter_rel: float = HEAT_SCATTER_REL):
    """Random plausible machine parameters; every effect's own parameter is drawn.

    Ranges: bearing heat x0.8-1.2 of the nominal; exponent 1.5-1.9; motor loss into the
    housing 60-120 W at 4000 rpm (about 1 % of an 11 kW spindle motor; at the twin's nominal
    35 W the part of its Z drift the baseline cannot absorb is below the noise floor: held-out
    0.83 against 0.76 um with nothing hidden, seed 1); centrifugal shift -2 to -4 um at 4000
    rpm; spindle overhang 300-450 mm (bending gain); sensor mounting time constants x1-3 of the
    nominal 4-20 min (4 min to an hour: with the nominal values alone the baseline absorbs the
    lag into the node heat capacities and fits the readings to their noise); probe noise
    0.2-0.4 um.

    Returns
    -------
    SpindleParams
    """
    base = SpindleParams()
    tau = rng.uniform(1.0, 3.0)
    sensors = tuple(
        replace(s, tau_s=None if s.tau_s is None else s.tau_s * tau) for s in base.sensors
    )
    return replace(
        base,
        front_bearing_heat_w=base.front_bearing_heat_w * rng.uniform(0.8, 1.2),
        rear_bearing_heat_w=base.rear_bearing_heat_w * rng.uniform(0.8, 1.2),
        bearing_heat_exponent=rng.uniform(1.5, 1.9),
        motor_heat_w=rng.uniform(60.0, 120.0),
        centrifugal_um=-rng.uniform(2.0, 4.0),
        spindle_overhang_mm=rng.uniform(300.0, 450.0),
        sensors=sensors,
        probe_noise_um=rng.uniform(0.2, 0.4),
        heat_scatter_rel=heat_scatter_rel,
    )


def write_hidden_campaigns(
    folder: Path,
    effects: Iterable[str],
    seed: int,
    n: int = 8,
    heat_scatter_rel: float = HEAT_SCATTER_REL,
) -> None:
    """Write ``n`` stepped campaigns, 45 days apart from January, with ``effects`` on.

    Parameters
    ----------
    folder : Path
        Raw folder to write into (one sub-folder per campaign, the raw contract).
    effects : iterable of str
        Effects of the generating twin.
    seed : int
        Seed of the parameters and of every campaign's noise.
    n : int
        Number of campaigns (each 270 min running in steps, then 60 min stopped, 3 min
        sampling).
    heat_scatter_rel : float
        Relative campaign-to-campaign scatter of the heat sources.
    """
    rng = np.random.default_rng(seed)
    params = hidden_params(rng, heat_scatter_rel)
    start = datetime(2024, 1, 10, 8, 30)
    for i in range(n):
        plan = SteppedPlan(
            f"H{i + 1:02d}",
            start + timedelta(days=int(45 * i)),
            rpm=0.0,
            steps=PROGRAMS[i % len(PROGRAMS)],
            run_min=270.0,
            cooldown_min=60.0,
        )
        campaign = simulate_spindle_campaign(
            plan, seed=seed, params=params, effects=frozenset(effects), preset="hidden-effect trial"
        )
        write_campaign(campaign, folder)


def write_plan_campaigns(
    folder: Path,
    proposed: dict[str, Any],
    effects: Iterable[str],
    seed: int,
    n: int,
    round_: int = 1,
) -> list[str]:
    """Write ``n`` campaigns of a proposed test, same machine as the trial's ``seed``.

    Parameters
    ----------
    folder : Path
        Raw folder to add them to.
    proposed : dict
        A visible ``proposed_test`` entry of ``discrepancy.json``, or its ``calibration_step``:
        ``spindle_program``, ``sample_interval_s`` (s), ``duration_h`` (h), ``heat_loads``.
    effects : iterable of str
        The hidden effects, on in the generating twin.
    seed : int
        The trial's seed (its machine parameters).
    n : int
        Number of campaigns, 20 days apart from March.
    round_ : int
        Round of proposed tests (1 = the first): the campaigns are ``P<round>_<nn>``, each
        round 60 days after the previous one.

    Returns
    -------
    list of str
        The campaign ids written.
    """
    params = hidden_params(np.random.default_rng(seed))
    start = datetime(2025, 3, 10, 8, 30) + timedelta(days=60 * (round_ - 1))
    ids = []
    for i in range(n):
        ids.append(f"P{round_}_{i + 1:02d}")
        plan = ContractPlan(
            ids[-1],
            start + timedelta(days=int(20 * i)),
            rpm=0.0,
            run_min=float(proposed["duration_h"]) * 60.0,
            cooldown_min=0.0,
            sample_min=float(proposed["sample_interval_s"]) / 60.0,
            heat_loads=loads_from_contract(proposed.get("heat_loads") or []),
            entries=tuple(proposed["spindle_program"]),
        )
        campaign = simulate_spindle_campaign(
            plan, seed=seed, params=params, effects=frozenset(effects), preset="test-plan run"
        )
        write_campaign(campaign, folder)
    return ids


@dataclass(frozen=True)
class Generator:
    """A machine that writes the trials' campaigns in the raw contract.

    Attributes
    ----------
    name : str
        ``twin`` or ``independent``.
    write_hidden : callable
        ``(folder, effects, seed, n)``: the trial's ``n`` stepped campaigns with ``effects``.
    write_plan : callable
        ``(folder, proposed, effects, seed, n, round_) -> ids``: ``n`` campaigns of a proposed
        test on the same machine (the same ``seed``).
    """

    name: str
    write_hidden: Callable[[Path, Iterable[str], int, int], None]
    write_plan: Callable[[Path, Mapping[str, Any], Iterable[str], int, int, int], list[str]]


GENERATORS = {
    "twin": Generator("twin", write_hidden_campaigns, write_plan_campaigns),
    "independent": Generator(
        "independent",
        independent_machine.write_hidden_campaigns,
        independent_machine.write_plan_campaigns,
    ),
}
"""The project's twin, and a machine model written without it
(:mod:`benchmarks.independent_machine`): the rules of the search must hold on both."""


@dataclass(frozen=True)
class PlanFollowUp:
    """The proposed test of a not-identifiable hidden effect, run on the same machine.

    Attributes
    ----------
    effect : str
    plan : str
        The proposed plans' names, in the order they were run.
    expected_sigma : float
        The signal the calibrated twin expected under the last plan, noise sigmas.
    named : tuple of str
        Effects the rerun named.
    class_after : str
        The effect's identifiability class in the rerun.
    signal_after : float
        Its visible signal in the rerun, noise sigmas.
    rmse_um_before, rmse_um_after : float
        Held-out Z RMS of the rerun's baseline and final twin, um.
    rmse_t_k_before, rmse_t_k_after : float
        Held-out temperature RMS of the rerun's baseline and final twin, K.
    rounds : int
        Proposed tests run one after the other (:data:`PLAN_ROUNDS` at most).
    quarantined : tuple of str
        Campaigns of the tests that the workflow did not get (quarantined by validation); the
        follow-up stops at the first such round.
    suspects : tuple of str
        Effects the last rerun held back as suspects.
    """

    effect: str
    plan: str
    expected_sigma: float
    named: tuple[str, ...]
    class_after: str
    signal_after: float
    rmse_um_before: float
    rmse_um_after: float
    rmse_t_k_before: float
    rmse_t_k_after: float
    rounds: int = 1
    quarantined: tuple[str, ...] = ()
    suspects: tuple[str, ...] = ()

    @property
    def effect_named(self) -> bool:
        """The hidden effect is among the rerun's named effects."""
        return self.effect in self.named


def follow_plan(
    raw: Path,
    doc: dict,
    effects: Sequence[str],
    hidden: Sequence[str],
    seed: int,
    section: DiscrepancySettings,
    workdir: Path,
    generator: str = "twin",
) -> list[PlanFollowUp]:
    """Run the proposed test of each of ``effects`` classed not identifiable, then rerun.

    Parameters
    ----------
    raw : Path
        The trial's raw folder (left as it is: the plan campaigns go into a copy).
    doc : dict
        The trial's ``discrepancy.json``.
    effects : sequence of str
        Effects whose proposed test to run: the hidden ones, or with nothing hidden every
        effect classed not identifiable (a test must not make an absent effect appear).
    hidden : sequence of str
        Effects of the generating twin (on in the test's campaigns too).
    seed : int
    section : DiscrepancySettings
        The ``discrepancy`` params section.
    workdir : Path
        Folder for the copies and the reports.
    generator : str
        The machine of :data:`GENERATORS` that wrote the trial (and writes the tests).

    Returns
    -------
    list of PlanFollowUp
        One per effect of ``effects`` classed not identifiable with a visible proposed test or
        a calibration step.
    """
    out = []
    for effect in effects:
        folder = workdir / f"raw_plan_{effect}"
        shutil.copytree(raw, folder)
        after, names, lost, expected = doc, [], [], float("nan")
        for round_ in range(1, PLAN_ROUNDS + 1):
            entry = after["identifiability"].get(effect) or {}
            test = _test_to_run(entry)
            if test is None:
                break
            n = int(test.get("campaigns", PLAN_CAMPAIGNS))
            ids = GENERATORS[generator].write_plan(folder, test, hidden, seed, n, round_)
            report = workdir / f"out_plan_{effect}_{round_}"
            after = run_workflow(folder, report, section, follow=FollowUp.from_document(after))
            visible = "expected_signal_sigma" in test
            names.append(str(test["name"]) if visible else f"calibration: {test['name']}")
            expected = float(test["expected_signal_sigma"]) if visible else expected
            lost += _not_reached(ids, after, test)
            if effect in after["named_effects"] or lost:
                break
        if names:
            out.append(_follow_up(effect, names, expected, after, tuple(lost)))
    return out


def _test_to_run(entry: dict) -> dict | None:
    """Return the test to run for an identifiability entry, or None.

    The visible proposed test of an effect classed not identifiable; without one, its
    calibration step (a heater pulse on a part the campaigns never heated,
    :func:`pipeline.discrepancy.plan_proposal.propose_test`).
    """
    proposed = entry.get("proposed_test") or {}
    if entry.get("class") != NOT_IDENTIFIABLE:
        return None
    if proposed.get("visible"):
        return proposed
    return proposed.get("calibration_step")


def _not_reached(ids: Sequence[str], doc: dict, proposed: dict) -> list[str]:
    """Return the campaigns of the proposed test that the workflow did not get, with a warning.

    A plan's campaign can be quarantined like any measurement, e.g. a quiet sensor during a
    heater test with the spindle stopped reads as stuck (validation's ``stuck_sensor``).
    """
    missing = sorted(set(ids) - set(doc["campaigns"]))
    if missing:
        logger.warning(
            "the proposed test %r: campaigns %s did not reach the workflow (quarantined or "
            "skipped; see the log); the follow-up stops here",
            proposed["name"],
            missing,
        )
    return missing


def _follow_up(
    effect: str, names: list[str], expected: float, after: dict, lost: tuple[str, ...]
) -> PlanFollowUp:
    """Return the follow-up of ``effect`` from the last rerun's ``discrepancy.json``."""
    again = after["identifiability"][effect]
    return PlanFollowUp(
        effect=effect,
        plan=" ; then ".join(names),
        expected_sigma=expected,
        named=tuple(after["named_effects"]),
        class_after=str(again["class"]),
        signal_after=float(again.get("signal_sigma") or float("nan")),
        rmse_um_before=float(after["rmse_um_before"]),
        rmse_um_after=float(after["rmse_um_after"]),
        rmse_t_k_before=float(after["rmse_T_K_before"]),
        rmse_t_k_after=float(after["rmse_T_K_after"]),
        rounds=len(names),
        quarantined=lost,
        suspects=tuple(s["effect"] for s in after.get("suspects") or ()),
    )


def run_workflow(
    raw: Path,
    out: Path,
    section: DiscrepancySettings,
    params_file: Path = DEFAULT_PARAMS,
    follow: FollowUp | None = None,
) -> dict:
    """Run the discrepancy workflow (no MLflow) on a raw folder; return ``discrepancy.json``.

    The ingest and validation limits come from ``params_file`` as in the stage; ``follow`` is
    the earlier run's outcome, as the stage keeps it (a rerun after a proposed test).
    """
    from pipeline.discrepancy.workflow import read_raw, run

    gap = load_settings(IngestSettings, "ingest", params_file).max_alignment_gap_s
    limits = load_settings(ValidateSettings, "validate", params_file).limits()
    campaigns, quarantined, synthetic = read_raw(raw, gap, limits)
    _, doc, _ = run(
        campaigns, section, out, quarantined=quarantined, synthetic=synthetic, follow=follow
    )
    return doc


def case_name(case: Iterable[str]) -> str:
    """Return a case as ``trials.csv`` names it: the hidden effects joined by '+', or none."""
    return "+".join(sorted(case)) or "none"


@dataclass(frozen=True)
class TrialResult:
    """Outcome of one trial.

    Attributes
    ----------
    hidden : tuple of str
        Effects of the generating twin (sorted).
    seed : int
    named : tuple of str
        Effects the workflow named, in order.
    rmse_um_before, rmse_um_after : float
        Held-out displacement RMS of the baseline and of the final twin, um.
    rmse_t_k_before, rmse_t_k_after : float
        Held-out temperature RMS of the baseline and of the final twin, K.
    seconds : float
        Wall time of the workflow (and of its follow-ups), s.
    classes : tuple of str
        Identifiability class of each hidden effect, in ``hidden`` order.
    not_identifiable : tuple of str
        Every candidate classed not identifiable.
    follow_ups : tuple of PlanFollowUp
        The proposed tests of the hidden effects classed not identifiable (with nothing
        hidden: of every effect classed not identifiable), run and rerun.
    generator : str
        The machine of :data:`GENERATORS` that wrote the campaigns.
    suspects : tuple of str
        Effects that passed the search's rule but were held back as suspects.
    """

    hidden: tuple[str, ...]
    seed: int
    named: tuple[str, ...]
    rmse_um_before: float
    rmse_um_after: float
    rmse_t_k_before: float
    rmse_t_k_after: float
    seconds: float
    classes: tuple[str, ...] = ()
    not_identifiable: tuple[str, ...] = ()
    follow_ups: tuple[PlanFollowUp, ...] = field(default=())
    generator: str = "twin"
    suspects: tuple[str, ...] = ()

    @property
    def named_correctly(self) -> bool:
        """The named set equals the hidden set."""
        return set(self.named) == set(self.hidden)

    @property
    def z_halved(self) -> bool:
        """Held-out Z RMS after <= half the baseline's (True when nothing was hidden)."""
        return not self.hidden or self.rmse_um_after <= 0.5 * self.rmse_um_before

    @property
    def gap_halved(self) -> bool:
        """The held-out Z or temperature RMS at least halved (True when nothing was hidden)."""
        return self.z_halved or self.rmse_t_k_after <= 0.5 * self.rmse_t_k_before

    @property
    def correct(self) -> bool:
        """Named correctly and, if something was hidden, the held-out Z RMS at least halved."""
        return self.named_correctly and self.z_halved

    @property
    def plan_named(self) -> bool | None:
        """Every followed-up effect named after its test; None without a follow-up.

        With nothing hidden, True when any rerun named its (absent) effect: a false alarm.
        """
        if not self.follow_ups:
            return None
        if not self.hidden:
            return any(f.effect_named for f in self.follow_ups)
        return all(f.effect_named for f in self.follow_ups)

    def row(self) -> dict:
        """One row of ``trials.csv`` (follow-up columns empty without a follow-up)."""
        follow = self.follow_ups
        return {
            "generator": self.generator,
            "hidden": case_name(self.hidden),
            "seed": self.seed,
            "named": "+".join(self.named) or "none",
            "suspects": "+".join(self.suspects) or "none",
            "rmse_um_before": round(self.rmse_um_before, 3),
            "rmse_um_after": round(self.rmse_um_after, 3),
            "rmse_T_K_before": round(self.rmse_t_k_before, 4),
            "rmse_T_K_after": round(self.rmse_t_k_after, 4),
            "named_correctly": self.named_correctly,
            "z_halved": self.z_halved,
            "gap_halved": self.gap_halved,
            "correct": self.correct,
            "class": "+".join(self.classes),
            "not_identifiable": "+".join(self.not_identifiable),
            "plan": " | ".join(f.plan for f in follow),
            "plan_expected_sigma": "+".join(f"{f.expected_sigma:.2f}" for f in follow),
            "plan_named": "+".join("+".join(f.named) or "none" for f in follow),
            "plan_suspects": "+".join("+".join(f.suspects) or "none" for f in follow),
            "plan_effect_named": self.plan_named,
            "plan_rounds": "+".join(str(f.rounds) for f in follow),
            "plan_quarantined": "+".join(" ".join(f.quarantined) or "none" for f in follow),
            "plan_rmse_um_before": "+".join(f"{f.rmse_um_before:.3f}" for f in follow),
            "plan_rmse_um_after": "+".join(f"{f.rmse_um_after:.3f}" for f in follow),
            "plan_signal_after": "+".join(f"{f.signal_after:.2f}" for f in follow),
            "plan_rmse_T_K_before": "+".join(f"{f.rmse_t_k_before:.4f}" for f in follow),
            "plan_rmse_T_K_after": "+".join(f"{f.rmse_t_k_after:.4f}" for f in follow),
            "seconds": round(self.seconds, 1),
        }


def run_trial(
    hidden: Iterable[str],
    seed: int,
    section: DiscrepancySettings,
    workdir: Path,
    n_campaigns: int = 8,
    follow_up: bool = True,
    generator: str = "twin",
) -> TrialResult:
    """Generate campaigns with ``hidden`` effects, run the workflow, score it.

    Parameters
    ----------
    hidden : iterable of str
    seed : int
    section : DiscrepancySettings
        The ``discrepancy`` params section.
    workdir : Path
        Empty folder for the raw campaigns and the report.
    n_campaigns : int
    follow_up : bool
        Run the proposed test of each hidden effect classed not identifiable, or with nothing
        hidden of every effect classed not identifiable (:func:`follow_plan`).
    generator : str
        The machine of :data:`GENERATORS` that writes the campaigns.

    Returns
    -------
    TrialResult
    """
    hidden = tuple(sorted(hidden))
    GENERATORS[generator].write_hidden(workdir / "raw", hidden, seed, n_campaigns)
    t0 = time.perf_counter()
    doc = run_workflow(workdir / "raw", workdir / "out", section)
    ident = doc["identifiability"]
    unidentifiable = tuple(e for e, v in ident.items() if v["class"] == NOT_IDENTIFIABLE)
    targets = hidden or unidentifiable
    follow_ups = (
        follow_plan(workdir / "raw", doc, targets, hidden, seed, section, workdir, generator)
        if follow_up
        else []
    )
    return TrialResult(
        hidden=hidden,
        seed=seed,
        named=tuple(doc["named_effects"]),
        rmse_um_before=float(doc["rmse_um_before"]),
        rmse_um_after=float(doc["rmse_um_after"]),
        rmse_t_k_before=float(doc["rmse_T_K_before"]),
        rmse_t_k_after=float(doc["rmse_T_K_after"]),
        seconds=time.perf_counter() - t0,
        classes=tuple(ident[e]["class"] for e in hidden),
        not_identifiable=unidentifiable,
        follow_ups=tuple(follow_ups),
        generator=generator,
        suspects=tuple(s["effect"] for s in doc.get("suspects") or ()),
    )


def rates_table(trials: pd.DataFrame) -> pd.DataFrame:
    """Rates per generator and case.

    Columns ``generator`` (``twin`` where ``trials`` has no such column), ``hidden``, ``n``;
    the fractions ``named_correctly``, ``z_halved``, ``gap_halved`` and ``correct`` (see
    :class:`TrialResult`); ``rmse_um_before``, ``rmse_um_after`` (medians over the seeds, um)
    and their ranges ``rmse_um_before_range``, ``rmse_um_after_range`` (min, max), um;
    ``classes`` (the hidden effects' identifiability classes and how many trials ended in
    each); ``plans_run`` (trials whose proposed test was run), ``plan_named`` (of those, the
    fraction in which the effect was then named, NaN without any; ``plan_n`` trials it counts)
    and ``plan_rmse`` and ``plan_rmse_t`` (the rerun's held-out Z, um, and temperature, K, RMS
    before -> after, medians); ``exact_with_tests`` (the fraction whose names, the first run's
    and every rerun's after a proposed test together, are exactly the hidden effects) and
    ``false_names`` (trials that named an effect not hidden, in any run). *With tests* is what
    the workflow promises a user who runs the tests its report proposes (up to
    :data:`PLAN_ROUNDS` of them): every hidden effect named, at once or after the tests, and
    nothing else named in any run.
    """
    named = [(_names_with_tests(r), _hidden_set(r)) for r in trials.itertuples()]
    trials = trials.assign(
        generator=trials["generator"] if "generator" in trials else "twin",
        plan=trials["plan"].fillna("").astype(str),
        plan_effect_named=trials["plan_effect_named"].map(_as_bool),
        exact_with_tests=[names == hidden for names, hidden in named],
        false_name=[bool(names - hidden) for names, hidden in named],
    )
    grouped = trials.groupby(["generator", "hidden"], sort=False)
    return pd.DataFrame(
        {
            "exact_with_tests": grouped["exact_with_tests"].mean(),
            "false_names": grouped["false_name"].sum().astype(int),
            "classes": grouped["class"].agg(_counts),
            "plans_run": grouped["plan"].agg(lambda s: int((s != "").sum())),
            "plan_named": grouped["plan_effect_named"].agg(
                lambda s: s.dropna().astype(float).mean()
            ),
            "plan_n": grouped["plan_effect_named"].agg(lambda s: int(s.notna().sum())),
            "plan_rmse": grouped[["plan_rmse_um_before", "plan_rmse_um_after"]].apply(_plan_rmse),
            "plan_rmse_t": grouped[["plan_rmse_T_K_before", "plan_rmse_T_K_after"]].apply(
                _plan_rmse
            ),
            "n": grouped.size(),
            "named_correctly": grouped["named_correctly"].mean(),
            "z_halved": grouped["z_halved"].mean(),
            "gap_halved": grouped["gap_halved"].mean(),
            "correct": grouped["correct"].mean(),
            "rmse_um_before": grouped["rmse_um_before"].median(),
            "rmse_um_after": grouped["rmse_um_after"].median(),
            "rmse_um_before_range": grouped["rmse_um_before"].agg(lambda s: (s.min(), s.max())),
            "rmse_um_after_range": grouped["rmse_um_after"].agg(lambda s: (s.min(), s.max())),
        }
    ).reset_index()


def _hidden_set(row: Any) -> set[str]:
    """Return the hidden effects of a ``trials.csv`` row."""
    return set() if row.hidden == "none" else set(str(row.hidden).split("+"))


def _names_with_tests(row: Any) -> set[str]:
    """Return every effect a ``trials.csv`` row named, in the first run or a rerun."""
    cells = (row.named, getattr(row, "plan_named", ""))
    words = (w for cell in cells if isinstance(cell, str) for w in cell.split("+"))
    return {w for w in words if w and w != "none"}


def wilson_interval(rate: float, n: int, z: float = 1.96) -> tuple[float, float]:
    """Return the Wilson score interval of a rate observed over ``n`` trials (95 % at z 1.96).

    Wilson (1927, *Probable inference, the law of succession, and statistical inference*,
    J. Am. Stat. Assoc. 22(158), 209-212), as statsmodels computes it: unlike the normal
    approximation it stays within [0, 1] and does not collapse to a point at 0 or 100 %,
    which five seeds per case give.
    """
    if n <= 0:
        return (float("nan"), float("nan"))
    low, high = proportion_confint(rate * n, n, alpha=2.0 * norm.sf(z), method="wilson")
    return (float(low), float(high))


def _rate(rate: float, n: int) -> str:
    """Return a rate with its 95 % Wilson interval, e.g. ``"80% (38-96)"``."""
    low, high = wilson_interval(rate, n)
    return f"{rate:.0%} ({100 * low:.0f}-{100 * high:.0f})"


def _spread(median: float, span: tuple[float, float]) -> str:
    """Return a median with the range over the seeds, e.g. ``"0.57 (0.36-0.75)"``."""
    return f"{median:.2f} ({span[0]:.2f}-{span[1]:.2f})"


def _as_bool(value: Any) -> bool | None:
    """Return a ``plan_effect_named`` cell (as read back from ``trials.csv``) as a bool or None."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    text = str(value).strip().lower()
    return {"true": True, "false": False}.get(text)


def _counts(values: pd.Series) -> str:
    """``"<value> <count>, ..."`` of a column, most frequent first (empty values as none)."""
    counts = values.astype("string").fillna("").replace("", "none").value_counts()
    return ", ".join(f"{k} {v}" for k, v in counts.items())


def _plan_rmse(rows: pd.DataFrame) -> str:
    """Median held-out RMS before -> after of the follow-up reruns ("" without one)."""
    pairs = rows.dropna().astype(str)
    pairs = pairs[(pairs.iloc[:, 0] != "") & (pairs.iloc[:, 0] != "nan")]
    if pairs.empty:
        return ""
    before = pairs.iloc[:, 0].str.split("+").explode().astype(float)
    after = pairs.iloc[:, 1].str.split("+").explode().astype(float)
    return f"{before.median():.2f} -> {after.median():.2f}"


GENERATOR_TITLES = {
    "twin": "The project's twin",
    "independent": "The independent machine (benchmarks.independent_machine)",
}


def rates_markdown(rates: pd.DataFrame, trials: pd.DataFrame, seeds: Sequence[int]) -> str:
    """Return the rates as a Markdown report, one section per generator."""
    if "generator" not in trials:
        trials = trials.assign(generator="twin")
    lines = [
        "# Hidden-effect trials of the discrepancy workflow",
        "",
        f"Seeds {', '.join(map(str, seeds))}. Rates with their 95 % Wilson interval "
        f"({_trials_per_case(len(seeds))}); RMS columns: medians over the seeds "
        "(range), um. *Named correctly*: the first run named exactly the hidden effects. "
        "*With tests*: the first run and the reruns after the proposed tests together named "
        "exactly the hidden effects (every hidden effect named, at once or after at most "
        f"{PLAN_ROUNDS} rounds of tests, and nothing else in any run). *False names*: trials that "
        "named an effect not hidden, in the first run or a rerun. *Correct*: named exactly the "
        "hidden effects at once and, when something was hidden, at least halved the held-out "
        "displacement RMS. *Gap halved*: the held-out displacement or temperature RMS at least "
        "halved.",
        "",
        "*Class*: the identifiability class each hidden effect ended in (trials per class). "
        "*Plan run*: trials whose hidden effect was classed not identifiable with a visible "
        "proposed test or a calibration step, which was then run on the same machine (each "
        f"rerun's next proposal too, up to {PLAN_ROUNDS} rounds) and the workflow rerun (with "
        "nothing hidden: every effect classed not identifiable, its test run on the clean "
        "machine); *named after plan*: of those, the share that named the effect (with "
        "nothing hidden: that named an absent effect, a false alarm); *Z after plan*: the rerun's "
        "held-out Z RMS (um) and temperature RMS (K), baseline -> augmented twin (medians).",
    ]
    for generator in dict.fromkeys(trials["generator"]):
        lines += _generator_section(
            rates[rates["generator"] == generator], trials[trials["generator"] == generator]
        )
    return "\n".join(lines) + "\n"


def _trials_per_case(n_seeds: int) -> str:
    """Return how many trials a case has and how far one of them moves its rate, in words."""
    trials = "one trial" if n_seeds == 1 else f"{n_seeds} trials"
    return f"{trials} per case: one trial moves a rate by {100 / max(n_seeds, 1):.0f} points"


def _generator_section(rates: pd.DataFrame, trials: pd.DataFrame) -> list[str]:
    """Return the Markdown lines of one generator's rates and its trials not correct."""
    generator = str(trials["generator"].iloc[0])
    exact = round(float((rates["exact_with_tests"] * rates["n"]).sum()))
    lines = [
        "",
        f"## {GENERATOR_TITLES.get(generator, generator)}",
        "",
        f"{int(trials['named_correctly'].sum())} of {len(trials)} trials named exactly the "
        f"hidden effects at once; {exact} counting the reruns after the proposed tests (*with "
        f"tests*); {int(rates['false_names'].sum())} named an effect not hidden, in any run "
        f"(*false names*); {int(trials['correct'].sum())} were correct.",
        "",
        "| hidden | trials | named correctly | with tests | false names | Z halved | gap halved "
        "| correct | held-out Z RMS before | after | class | plan run | named after plan "
        "| Z after plan | T after plan |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rates.itertuples():
        named_after = "" if not r.plan_n else _rate(r.plan_named, r.plan_n)
        lines.append(
            f"| {r.hidden} | {r.n} | {_rate(r.named_correctly, r.n)} | "
            f"{_rate(r.exact_with_tests, r.n)} | {r.false_names} | {r.z_halved:.0%} | "
            f"{r.gap_halved:.0%} | {_rate(r.correct, r.n)} | "
            f"{_spread(r.rmse_um_before, r.rmse_um_before_range)} | "
            f"{_spread(r.rmse_um_after, r.rmse_um_after_range)} | {r.classes} | "
            f"{r.plans_run} | {named_after} | {r.plan_rmse} | {r.plan_rmse_t} |"
        )
    wrong = trials[~trials["correct"].astype(bool)]
    if len(wrong):
        lines += ["", "Trials not correct (not named exactly, or Z not halved):", ""]
        lines += [
            f"- hidden {r.hidden}, seed {r.seed}: named {r.named}; held-out Z RMS "
            f"{r.rmse_um_before:.2f} -> {r.rmse_um_after:.2f} um, T RMS "
            f"{r.rmse_T_K_before:.3f} -> {r.rmse_T_K_after:.3f} K"
            for r in wrong.itertuples()
        ]
    return lines


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.discrepancy_trials``: every case over the seeds; write the rates."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.discrepancy_trials", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument(
        "--generators",
        nargs="+",
        choices=list(GENERATORS),
        default=list(GENERATORS),
        help="machines that write the campaigns; default both",
    )
    parser.add_argument(
        "--cases",
        nargs="+",
        choices=[case_name(c) for c in CASES],
        help="only these cases (hidden effects joined by '+', or none); default every case",
    )
    parser.add_argument("--out", type=Path, default=Path("reports/discrepancy_trials"))
    parser.add_argument("--campaigns", type=int, default=8, help="campaigns per trial")
    parser.add_argument("--params", type=Path, default=DEFAULT_PARAMS)
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"{QUICK_CAMPAIGNS} campaigns per trial and 2 folds (about a third of the time)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="keep the trials OUT/trials.csv holds from an interrupted run of the same setting "
        "and code; run the others",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    section = load_settings(DiscrepancySettings, "discrepancy", args.params)
    if args.quick:
        section = section.model_copy(update={"n_folds": 2})
        args.campaigns = QUICK_CAMPAIGNS
    kept = trial_resume.start(
        args.out,
        trial_resume.trial_setting(section, args.campaigns, trial_resume.code_version()),
        args.resume,
    )
    done = trial_resume.finished(kept)
    if done:
        logger.info("resuming: %d trials already in %s", len(done), args.out)
    rows: list[dict] = []
    trials = kept
    cases = [c for c in CASES if not args.cases or case_name(c) in args.cases]
    for seed in args.seeds:
        for generator in args.generators:
            for case in cases:
                if (generator, case_name(case), seed) in done:
                    continue
                with tempfile.TemporaryDirectory() as tmp:
                    result = run_trial(
                        case, seed, section, Path(tmp), args.campaigns, generator=generator
                    )
                logger.info("trial %s", result.row())
                rows.append(result.row())
                trials = trial_resume.save(args.out, kept, rows)
    rates = rates_table(trials)
    (args.out / "rates.md").write_text(rates_markdown(rates, trials, args.seeds), encoding="utf-8")
    logger.info("rates written to %s", args.out / "rates.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Check that the proposed test plan makes a hidden, not-identifiable effect visible (issue 14).

On the hidden-effect trial campaigns (:func:`benchmarks.discrepancy_trials
.write_hidden_campaigns`) with one effect hidden, the workflow classes it not identifiable and
proposes a test (:mod:`pipeline.discrepancy.test_plan`). This check simulates the proposed test
for the same machine (same seed: the same drawn parameters) with the effect still hidden, adds
those campaigns to the raw folder, reruns the workflow and records whether the effect is named
and how its identifiability figure moved.

``python -m benchmarks.test_plan_check --effect sensor_lag --seed 1``
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.discrepancy_trials import hidden_params, run_workflow, write_hidden_campaigns
from pipeline.config import load_section
from pipeline.thermal.program import Program
from pipeline.twin.campaigns import SpindlePlan, simulate_spindle_campaign
from pipeline.twin.writer import write_campaign


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


def write_plan_campaigns(
    folder: Path, proposed: dict[str, Any], effect: str, seed: int, n: int = 2
) -> None:
    """Write ``n`` campaigns of the proposed test, same machine as the trial's ``seed``.

    Parameters
    ----------
    folder : Path
        Raw folder to add them to.
    proposed : dict
        The ``proposed_test`` entry of ``discrepancy.json`` (visible).
    effect : str
        The hidden effect, on in the generating twin.
    seed : int
        The trial's seed (its machine parameters).
    n : int
        Number of plan campaigns (the search holds campaigns out, so more than one).
    """
    params = hidden_params(np.random.default_rng(seed))
    start = datetime(2025, 3, 10, 8, 30)
    for i in range(n):
        plan = ContractPlan(
            f"P{i + 1:02d}",
            start + timedelta(days=int(20 * i)),
            rpm=0.0,
            run_min=float(proposed["duration_h"]) * 60.0,
            cooldown_min=0.0,
            sample_min=float(proposed["sample_interval_s"]) / 60.0,
            entries=tuple(proposed["spindle_program"]),
        )
        campaign = simulate_spindle_campaign(
            plan, seed=seed, params=params, effects=frozenset({effect}), preset="test-plan check"
        )
        write_campaign(campaign, folder)


def check(effect: str, seed: int, workdir: Path, n: int = 4, n_plan: int = 2) -> dict[str, Any]:
    """Run the trial, the proposed test and the workflow again; return the figures.

    Returns
    -------
    dict
        ``class_before``, ``signal_before`` (sigma), ``proposed_test``, and when a test was
        proposed ``named_after``, ``class_after``, ``signal_after`` (sigma), held-out Z RMS
        before and after (um).
    """
    section = {**load_section("discrepancy"), "n_folds": 2, "mlflow": False}
    raw = workdir / "raw"
    write_hidden_campaigns(raw, frozenset({effect}), seed=seed, n=n)
    doc = run_workflow(raw, workdir / "out_before", section)
    entry = doc["identifiability"][effect]
    out: dict[str, Any] = {
        "effect": effect,
        "seed": seed,
        "class_before": entry["class"],
        "signal_before": entry.get("signal_sigma"),
        "proposed_test": entry.get("proposed_test"),
    }
    proposed = entry.get("proposed_test")
    if not proposed or not proposed.get("visible"):
        return out
    write_plan_campaigns(raw, proposed, effect, seed, n_plan)
    after = run_workflow(raw, workdir / "out_after", section)
    out.update(
        named_after=effect in after["named_effects"],
        class_after=after["identifiability"][effect]["class"],
        signal_after=after["identifiability"][effect].get("signal_sigma"),
        named_effects_after=after["named_effects"],
    )
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: one effect, one seed; print the figures as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effect", default="sensor_lag")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        result = check(args.effect, args.seed, Path(tmp))
    sys.stdout.write(json.dumps(result, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

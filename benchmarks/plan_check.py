"""Check that the proposed test plan makes a hidden, not-identifiable effect visible.

On the hidden-effect trial campaigns (:func:`benchmarks.discrepancy_trials
.write_hidden_campaigns`) with one effect hidden, the workflow classes it not identifiable and
proposes a test (:mod:`pipeline.discrepancy.plan_proposal`). This check runs the proposed test on
the same machine (same seed: the same drawn parameters) with the effect still hidden
(:func:`benchmarks.discrepancy_trials.follow_plan`), adds those campaigns to the raw folder,
reruns the workflow and records whether the effect is named and how its identifiability figure
and the held-out Z gap moved.

``python -m benchmarks.plan_check --effect thermal_bending --seed 1``
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from benchmarks.discrepancy_trials import follow_plan, run_workflow, write_hidden_campaigns
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings


def check(effect: str, seed: int, workdir: Path, n: int = 4) -> dict[str, Any]:
    """Run the trial on ``n`` campaigns, the proposed test and the workflow again.

    Returns
    -------
    dict
        ``class_before``, ``signal_before`` (sigma), ``proposed_test``, and when a visible test
        or a calibration step was proposed ``named_after``, ``class_after``, ``signal_after``
        (sigma), the rerun's held-out Z (um) and temperature (K) RMS before and after, its named
        effects and the test's campaigns quarantined.
    """
    section = load_settings(DiscrepancySettings, "discrepancy")
    section = section.model_copy(update={"n_folds": 2, "mlflow": False})
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
    for follow in follow_plan(raw, doc, (effect,), (effect,), seed, section, workdir):
        out.update(
            named_after=follow.effect_named,
            class_after=follow.class_after,
            signal_after=follow.signal_after,
            named_effects_after=list(follow.named),
            plans_run=follow.plan,
            rounds=follow.rounds,
            expected_sigma_last_plan=follow.expected_sigma,
            rmse_um_before_after_plan=follow.rmse_um_before,
            rmse_um_after_after_plan=follow.rmse_um_after,
            rmse_T_K_before_after_plan=follow.rmse_t_k_before,
            rmse_T_K_after_after_plan=follow.rmse_t_k_after,
            plan_quarantined=list(follow.quarantined),
        )
    return out


def main(argv: list[str] | None = None) -> int:
    """Command line: one effect, one seed; print the figures as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effect", default="thermal_bending")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--campaigns", type=int, default=4, help="trial campaigns")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        result = check(args.effect, args.seed, Path(tmp), args.campaigns)
    sys.stdout.write(json.dumps(result, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""What the discrepancy workflow can name on the demo, with and without its unseen machine state.

The demo campaigns (``thermal simulate --preset demo``) come from the project's twin with the
effects :data:`pipeline.twin.effects.DEMO_EFFECTS` switched on, one constant speed per campaign,
and a per-campaign machine state no sensor sees (:data:`pipeline.twin.conditions.DEMO_SCATTER`:
bearing preload and lubrication, the share of the friction heat entering the shaft, the
shaft's cooling, the season's convection, warm starts). ``python -m
benchmarks.discrepancy_demo_check`` simulates the same demo spindle plans with the same seed three
ways:

* ``shipped``: as shipped in ``data/raw`` (the same files ``thermal simulate`` writes);
* ``without_state``: the same plans with the state scatter off (``SpindlePlan(scatter=None)``:
  cold starts, only the twin's 5 % heat scatter between campaigns);
* ``speed_steps``: the same plans with their state, but each run in speed steps (the programs
  of the hidden-effect trials, :data:`benchmarks.discrepancy_trials.PROGRAMS`) instead of one
  constant speed: within a campaign the state is fixed, so the steps contrast the heat at
  several speeds under the same state;

runs the workflow on each like on measurements (:func:`benchmarks.discrepancy_trials.
run_workflow`, the ``discrepancy`` params) and writes ``demo_check.json`` and ``demo_check.md``:
the effects named, the held-out and validation residuals before and after, and which of the
demo twin's effects were named. The difference between the two runs is what the unseen state
hides.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from benchmarks.discrepancy_trials import PROGRAMS, SteppedPlan, run_workflow
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.followup import signed_percent
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.twin.campaigns import SpindlePlan, demo_plans, simulate_spindle_campaign
from pipeline.twin.cli import DEFAULT_SEED
from pipeline.twin.effects import DEMO_EFFECTS
from pipeline.twin.writer import write_campaign

logger = logging.getLogger(__name__)

VARIANTS = ("shipped", "without_state", "speed_steps")
"""The two simulations of the demo plans (see the module docstring)."""


def write_demo(raw: Path, variant: str, seed: int = DEFAULT_SEED) -> list[str]:
    """Simulate the demo's spindle plans into ``raw``; return the campaign ids.

    Parameters
    ----------
    raw : Path
        Folder to write the campaigns to (one sub-folder each, raw contract).
    variant : str
        One of :data:`VARIANTS`.
    seed : int
        Seed of the demo (``thermal simulate``'s default).
    """
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant '{variant}'; use one of {', '.join(VARIANTS)}")
    ids = []
    spindle = [p for p in demo_plans() if isinstance(p, SpindlePlan)]
    for i, plan in enumerate(spindle):
        if variant == "without_state":
            plan = replace(plan, scatter=None)
        elif variant == "speed_steps":
            same = {f.name: getattr(plan, f.name) for f in fields(SpindlePlan)}
            plan = SteppedPlan(**same, steps=PROGRAMS[i % len(PROGRAMS)])
        write_campaign(simulate_spindle_campaign(plan, seed=seed, effects=DEMO_EFFECTS), raw)
        ids.append(plan.campaign_id)
    return ids


def summarise(doc: dict[str, Any]) -> dict[str, Any]:
    """Return the figures of one workflow run that the check reports (um, K)."""
    val = doc.get("validation") or {}
    return {
        "named_effects": list(doc["named_effects"]),
        "quarantined": list(doc.get("quarantined") or []),
        "demo_effects_named": sorted(set(doc["named_effects"]) & DEMO_EFFECTS),
        "demo_effects_not_named": sorted(DEMO_EFFECTS - set(doc["named_effects"])),
        "named_but_not_in_demo": sorted(set(doc["named_effects"]) - DEMO_EFFECTS),
        "heldout_rmse_um": [doc["rmse_um_before"], doc["rmse_um_after"]],
        "heldout_rmse_T_K": [doc["rmse_T_K_before"], doc["rmse_T_K_after"]],
        "validation_rmse_um": [val.get("rmse_um_before"), val.get("rmse_um_after")],
        "steps": [
            {
                "effect": s["effect"],
                "delta_bic": s["evidence"]["delta_bic"],
                "heldout_reduction": s["evidence"]["heldout_reduction"],
                "heldout_T_reduction": s["evidence"]["heldout_T_reduction"],
            }
            for s in doc["steps"]
        ],
        "suspects": {s["effect"]: s["reason"] for s in doc.get("suspects") or []},
        "last_round": doc["candidates_by_step"][-1]["candidates"]
        if doc["candidates_by_step"]
        else [],
        "seconds": doc["seconds"],
    }


def _pair(values: list) -> str:
    a, b = values
    return "n/a" if a is None or b is None else f"{a:.2f} -> {b:.2f}"


def markdown(results: dict[str, dict[str, Any]], seed: int) -> str:
    """Return the check as a Markdown report."""
    lines = [
        "# The discrepancy workflow on the demo plans, with and without the unseen state",
        "",
        f"Demo spindle plans, seed {seed}; the demo twin's effects beyond the baseline: "
        + ", ".join(f"`{e}`" for e in sorted(DEMO_EFFECTS))
        + ". `shipped` = the demo as shipped (per-campaign machine state no sensor sees); "
        "`without_state` = the same plans with that state off (cold starts, 5 % heat scatter); "
        "`speed_steps` = the same plans and states, each run in speed steps.",
        "",
        "| variant | named | demo effects not named | held-out Z RMS (um) | held-out T RMS (K) "
        "| validation Z RMS (um) |",
        "|---|---|---|---|---|---|",
    ]
    for variant, r in results.items():
        lines.append(
            f"| {variant} | {', '.join(r['named_effects']) or 'nothing'} | "
            f"{', '.join(r['demo_effects_not_named']) or 'none'} | "
            f"{_pair(r['heldout_rmse_um'])} | {_pair(r['heldout_rmse_T_K'])} | "
            f"{_pair(r['validation_rmse_um'])} |"
        )
    for variant, r in results.items():
        if r["quarantined"]:
            lines += [
                "",
                f"Quarantined by validation in `{variant}` and left out: "
                f"{', '.join(r['quarantined'])} (see the workflow's log).",
            ]
    for variant, r in results.items():
        lines += ["", f"Candidates in the last round of `{variant}`:", ""]
        lines += [_candidate_line(c, r["named_effects"], r["suspects"]) for c in r["last_round"]]
    return "\n".join(lines) + "\n"


def _candidate_line(candidate: dict[str, Any], named: list[str], suspects: dict[str, str]) -> str:
    """Return one last-round candidate's figures and, if it passed, whether it was named.

    The last round names one when the search stopped at its most effects; a candidate that
    passed and was not named says why.
    """
    z_change, t_change = (
        signed_percent(0.0 - candidate[key]) for key in ("heldout_reduction", "heldout_T_reduction")
    )
    line = (
        f"- `{candidate['effect']}`: delta BIC {candidate['delta_bic']:.0f}, "
        f"held-out Z {z_change}, T {t_change}"
    )
    if not candidate.get("passes"):
        return line
    if candidate["effect"] in named:
        return line + "; named"
    reason = suspects.get(candidate["effect"])
    if reason is None:
        return line + "; passes the thresholds, held back by a gate (see the workflow's report)"
    return line + f"; passes the thresholds, held back as a suspect: {reason}"


def main(argv: list[str] | None = None) -> int:
    """Simulate every variant, run the workflow on each; write the JSON and the report."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.discrepancy_demo_check", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--out", type=Path, default=Path("reports/discrepancy_demo_check"))
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED)
    parser.add_argument("--params", type=Path, default=DEFAULT_PARAMS)
    args = parser.parse_args(argv)
    section = load_settings(DiscrepancySettings, "discrepancy", args.params)
    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    for variant in VARIANTS:
        with tempfile.TemporaryDirectory() as tmp:
            write_demo(Path(tmp) / "raw", variant, args.seed)
            doc = run_workflow(Path(tmp) / "raw", args.out / variant, section, args.params)
        results[variant] = summarise(doc)
        logger.info("demo %s: named %s", variant, results[variant]["named_effects"] or "nothing")
    (args.out / "demo_check.json").write_text(json.dumps(results, indent=2), encoding="utf-8")
    (args.out / "demo_check.md").write_text(markdown(results, args.seed), encoding="utf-8")
    logger.info("demo check written to %s", args.out / "demo_check.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())

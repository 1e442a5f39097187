"""``thermal simulate``: write synthetic campaigns from the physical twin.

Examples
--------
``thermal simulate --preset demo --out data/raw --seed 2016``
    the demo set (K01-K12, V01-V06, Y01, Y02), regenerated bit for bit from the seed;
``thermal simulate --preset single --id K13 --season summer --rpm 4000 --seed 13 --out DIR``
    one extra spindle-drift campaign (same machine, its own machine state drawn like the
    demo's);
``thermal simulate --preset workshop --out DIR --seed 2046``
    one continuous two-day run of a machine cut into six back-to-back campaigns W01-W06
    (16 unnamed sensors, X/Y/Z probes, speed log; :mod:`pipeline.twin.workshop`);
``thermal simulate --preset workshop --out DIR --interval-s 60``
    the same run sampled every 60 s instead of 20 s (a logger set to a longer interval);
``thermal simulate --preset workshop --logger-table logger.csv [--hours 24]``
    the same run as one data logger's wide table (:mod:`pipeline.twin.logger_export`), for
    ``thermal import logger``;
``thermal simulate --list-effects``
    the switchable physical effects.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from datetime import datetime
from pathlib import Path

from pipeline import paths
from pipeline.thermal.effects import EFFECTS, check_effects
from pipeline.twin.ambient import SEASON_OF_MONTH, season_of
from pipeline.twin.campaigns import (
    SEASON_START,
    AxisPlan,
    SpindlePlan,
    demo_plans,
    simulate_plan,
)
from pipeline.twin.conditions import DEMO_SCATTER
from pipeline.twin.effects import DEMO_EFFECTS
from pipeline.twin.logger_export import logger_table, write_logger_table
from pipeline.twin.workshop import (
    WORKSHOP_EFFECTS,
    WorkshopPlan,
    simulate_workshop,
    workshop_plan,
)
from pipeline.twin.writer import write_campaign

logger = logging.getLogger(__name__)

DEFAULT_SEED = 2016
WORKSHOP_SEED = 2046
SEASONS = ("winter", "spring", "summer", "autumn")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="thermal simulate",
        description="Write synthetic campaigns (raw contract, synthetic: true) from the twin.",
    )
    p.add_argument("--preset", choices=("demo", "single", "workshop"), default="demo")
    p.add_argument("--out", default=str(paths.RAW), help="raw directory (default data/raw)")
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"default {DEFAULT_SEED} ({WORKSHOP_SEED} for the workshop preset)",
    )
    p.add_argument(
        "--effects",
        default=None,
        help="comma-separated effects switched on, 'none' for the baseline "
        "(default: the preset's realistic set)",
    )
    p.add_argument("--only", default=None, help="demo: comma-separated campaign ids to write")
    p.add_argument("--list-effects", action="store_true", help="list the effects and exit")
    workshop = p.add_argument_group("workshop run (--preset workshop)")
    workshop.add_argument(
        "--logger-table",
        default=None,
        help="write the run as one data logger's CSV table to this file instead of campaigns",
    )
    workshop.add_argument(
        "--hours", type=float, default=None, help="--logger-table: only the first HOURS hours"
    )
    workshop.add_argument(
        "--interval-s",
        type=float,
        default=None,
        help="sampling interval of the run, s (default 20; must divide every campaign)",
    )
    single = p.add_argument_group("single spindle campaign (--preset single)")
    single.add_argument("--id", dest="campaign_id", default="K13")
    single.add_argument("--season", choices=SEASONS, default=None)
    single.add_argument("--start", default=None, help="ISO local time, e.g. 2024-08-20T08:30")
    single.add_argument("--rpm", type=float, default=4000.0)
    single.add_argument("--split", choices=("train", "validation"), default="train")
    single.add_argument("--run-min", type=float, default=270.0, help="running time, min")
    single.add_argument("--cooldown-min", type=float, default=60.0, help="stopped time, min")
    return p


def _effects(text: str | None, preset: str) -> frozenset[str]:
    if text is None:
        return WORKSHOP_EFFECTS if preset == "workshop" else DEMO_EFFECTS
    if text.strip().lower() == "none":
        return frozenset()
    return check_effects(n.strip() for n in text.split(",") if n.strip())


def _single_plan(args: argparse.Namespace) -> SpindlePlan:
    if args.start is not None:
        start = datetime.fromisoformat(args.start)
        if args.season is not None and SEASON_OF_MONTH[start.month] != args.season:
            raise ValueError(
                f"--start {args.start} is in {season_of(start)}, not {args.season}; "
                "drop --season or give a start in that season"
            )
    else:
        start = SEASON_START[args.season or "summer"]
    if args.rpm < 0 or args.run_min <= 0 or args.cooldown_min < 0:
        raise ValueError("--rpm and --cooldown-min must be >= 0 and --run-min > 0")
    return SpindlePlan(
        args.campaign_id,
        start,
        args.rpm,
        split=args.split,
        run_min=args.run_min,
        cooldown_min=args.cooldown_min,
        season=args.season,
        scatter=DEMO_SCATTER,
    )


def _plans(args: argparse.Namespace) -> tuple[SpindlePlan | AxisPlan, ...]:
    """Plans of the demo (``--only`` filters them) or single preset."""
    if args.preset == "single":
        return (_single_plan(args),)
    plans = demo_plans()
    if not args.only:
        return plans
    wanted = {s.strip() for s in args.only.split(",") if s.strip()}
    unknown = wanted - {p.campaign_id for p in plans}
    if unknown:
        raise ValueError(
            f"--only: no demo campaign {sorted(unknown)}; "
            f"demo ids: {', '.join(p.campaign_id for p in plans)}"
        )
    return tuple(p for p in plans if p.campaign_id in wanted)


def _write_workshop(args: argparse.Namespace, plan: WorkshopPlan, effects: frozenset[str]) -> int:
    """Simulate the workshop run; write its campaigns (or its logger table); return 0."""
    t0 = time.perf_counter()
    seed = WORKSHOP_SEED if args.seed is None else args.seed
    run = simulate_workshop(plan, seed=seed, effects=effects)
    if args.logger_table is not None:
        table = logger_table(run, args.hours)
        write_logger_table(table, Path(args.logger_table))
        logger.info("workshop run: %d logger rows written to %s", len(table), args.logger_table)
        return 0
    out = args.out
    for campaign in run.campaigns:
        write_campaign(campaign, out)
    logger.info(
        "workshop run: %d campaigns written to %s in %.1f s",
        len(run.campaigns),
        out,
        time.perf_counter() - t0,
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run ``thermal simulate``; return 0 on success, 2 on a usage error."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.list_effects:
        lines = [f"{name:<24} {e.description}" for name, e in EFFECTS.items()]
        lines.append(f"demo preset: {', '.join(sorted(DEMO_EFFECTS))}")
        lines.append(f"workshop preset: {', '.join(sorted(WORKSHOP_EFFECTS))}")
        sys.stdout.write("\n".join(lines) + "\n")
        return 0
    try:
        effects = _effects(args.effects, args.preset)
        plans = () if args.preset == "workshop" else _plans(args)
        workshop = None
        if args.preset == "workshop" and args.interval_s is None:
            workshop = workshop_plan()
        elif args.preset == "workshop":
            workshop = workshop_plan(args.interval_s)
    except (KeyError, ValueError) as err:
        sys.stderr.write(f"thermal simulate: {err.args[0] if err.args else err}\n")
        return 2
    if workshop is not None:
        return _write_workshop(args, workshop, effects)
    if any(v is not None for v in (args.logger_table, args.hours, args.interval_s)):
        sys.stderr.write(
            "thermal simulate: --logger-table, --hours and --interval-s need --preset workshop\n"
        )
        return 2
    seed = DEFAULT_SEED if args.seed is None else args.seed
    t0 = time.perf_counter()
    for plan in plans:
        campaign = simulate_plan(plan, seed=seed, effects=effects, preset=args.preset)
        write_campaign(campaign, args.out)
    logger.info(
        "%d synthetic campaign(s) written to %s in %.1f s",
        len(plans),
        args.out,
        time.perf_counter() - t0,
    )
    return 0

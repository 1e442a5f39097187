"""Scale: each stage's time and peak memory as campaigns and machines grow (``make bench-scale``).

For every size (machines x campaigns per machine, by default 1, 2, 4 x 6, 12, 24) the workshop
twin (:mod:`pipeline.twin.workshop`: 16 unnamed sensors, X/Y/Z probes, warm starts) writes the
campaigns into a copy of the repository whose demo campaigns are removed: each machine
(``workshop-1``, ``workshop-2``, ...) gets one run of back-to-back campaigns in each season
(spring, summer, autumn, winter, in that order; the campaigns shared out as evenly as they go,
6 as 2, 2, 1, 1), each run with its own seed: every size covers the same four seasons, so the
sizes differ in the campaigns only, not in the number of seasons left out in turn. Each
stage's command (``dvc.yaml``, in order) then runs alone in a process that reads its wall time
and its peak resident memory (the largest process of the stage, its joblib workers included:
``getrusage(RUSAGE_CHILDREN)``), logging to a local MLflow store in the copy.

The growth exponents are least-squares slopes on log-log axes: of each stage's time on the campaigns
per machine (one exponent per machine count) and on the machines (one per campaign count). Prints
the table and the exponents and writes them to ``reports/bench_scale.json``. With several machines,
one campaign is then added to the last machine and every stage runs again: the other machines'
results are reused (:mod:`pipeline.fit_cache`), so that rerun shows what a new campaign of one
machine costs. ``--dask`` runs the same sizes with the fits on a local Dask cluster (a scheduler and
two workers on 127.0.0.1, :mod:`pipeline.cluster`); there the peak memory is the stage's own
process, the workers' not counted. A size whose stage fails is reported with the stage's message and
the remaining stages of that size are not run.

Machines are noisy: compare the exponents and the ratios within one run, not seconds across
runs.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import yaml

from pipeline.cluster import SCHEDULER_VARIABLE
from pipeline.twin.workshop import simulate_workshop, workshop_plan
from pipeline.twin.writer import write_campaign
from tests.helpers.dask_cluster import running_dask_cluster
from tests.helpers.repository import copy_repository

MACHINES = (1, 2, 4)
CAMPAIGNS = (6, 12, 24)
RUN_STARTS = (
    datetime(2025, 4, 7, 7, 0),
    datetime(2025, 7, 7, 7, 0),
    datetime(2025, 10, 6, 7, 0),
    datetime(2026, 1, 12, 7, 0),
)
"""One workshop run per season, spring to winter, at every size: the campaigns grow, the seasons
(leave-one-season-out's folds, bounded by ``protocol.max_folds``) stay four."""
INTERVAL_S = 60.0
"""The workshop logger at 60 s: a third of the default's rows, the same cost structure."""
OUT = Path("reports/bench_scale.json")

_MEASURE = (
    "import json, resource, subprocess, sys, time\n"
    "begin = time.perf_counter()\n"
    "with open(sys.argv[1], 'wb') as log:\n"
    "    code = subprocess.run(sys.argv[2:], stdout=log, stderr=subprocess.STDOUT).returncode\n"
    "peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0\n"
    "print(json.dumps({'code': code, 'seconds': time.perf_counter() - begin, 'peak_mib': peak}))\n"
)
"""Runs one stage's command in a fresh process and prints its time (s) and peak RSS (MiB)."""


def write_fleet(raw: Path, machines: int, campaigns: int) -> list[str]:
    """Write ``machines`` x ``campaigns`` workshop campaigns into ``raw``; return their ids."""
    base = workshop_plan(INTERVAL_S)
    most = len(base.slots) * len(RUN_STARTS)
    if not len(RUN_STARTS) <= campaigns <= most:
        raise ValueError(
            f"campaigns per machine: {len(RUN_STARTS)} (one a season) to {most}, not {campaigns}"
        )
    shares = [len(part) for part in np.array_split(np.arange(campaigns), len(RUN_STARTS))]
    ids = []
    for m in range(1, machines + 1):
        for r, (start, share) in enumerate(zip(RUN_STARTS, shares, strict=True), start=1):
            slots = tuple(
                replace(s, campaign_id=f"M{m}R{r}{s.campaign_id}") for s in base.slots[:share]
            )
            plan = replace(
                base, start=start, slots=slots, run_id=f"scale-{m}-{r}", machine=f"workshop-{m}"
            )
            for campaign in simulate_workshop(plan, seed=1000 * m + r).campaigns:
                write_campaign(campaign, raw)
                ids.append(campaign.info.campaign_id)
    return ids


def run_stage(command: list[str], cwd: Path, env: dict[str, str], log: Path) -> dict:
    """Run one stage's command; return its ``seconds``, ``peak_mib`` and exit ``code``."""
    result = subprocess.run(
        [sys.executable, "-c", _MEASURE, str(log), *command],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(result.stdout.strip().splitlines()[-1])


def keep_candidates(work: Path, models: list[str] | None) -> None:
    """Keep only these models of ``params.yaml`` ``evaluate.candidates`` (None: all of them)."""
    if not models:
        return
    params = yaml.safe_load((work / "params.yaml").read_text())
    shipped = params["evaluate"]["candidates"]
    unknown = sorted(set(models) - set(shipped))
    if unknown:
        raise ValueError(f"--candidates: {unknown} not in params.yaml ({sorted(shipped)})")
    params["evaluate"]["candidates"] = {m: shipped[m] for m in shipped if m in models}
    (work / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))


def measure_size(
    root: Path, folder: Path, size: tuple[int, int], env: dict, models: list[str] | None
) -> dict:
    """Run every stage on one size (machines, campaigns per machine); return the figures.

    The campaigns are written into a fresh copy of ``root``.
    """
    machines, campaigns = size
    work = copy_repository(root, folder / f"m{machines}c{campaigns}")
    raw = work / "data" / "raw"
    shutil.rmtree(raw)
    raw.mkdir()
    write_fleet(raw, machines, campaigns)
    keep_candidates(work, models)
    env = {**env, "MLFLOW_TRACKING_URI": f"sqlite:///{work / 'mlflow.db'}"}
    figures = {"machines": machines, "campaigns_per_machine": campaigns}
    figures["stages"], failed = run_stages(work, env, "stage")
    if failed:
        figures["failed"] = failed
    elif machines > 1:
        add_campaign(raw, machines)
        figures["one_more"], failed = run_stages(work, env, "one-more")
        if failed:
            figures["failed"] = failed
    return figures


def run_stages(work: Path, env: dict, label: str) -> tuple[dict, dict | None]:
    """Run every stage's command in order; return their figures and the failure, if any."""
    stages = yaml.safe_load((work / "dvc.yaml").read_text())["stages"]
    measured_stages = {}
    for name, stage in stages.items():
        log = work / f"{label}-{name}.log"
        measured = run_stage(stage["cmd"].split(), work, env, log)
        if measured.pop("code") != 0:
            return measured_stages, {"stage": name, "output": log.read_text()[-2000:]}
        measured_stages[name] = measured
    return measured_stages, None


def add_campaign(raw: Path, machine: int) -> str:
    """Add to machine ``machine`` a copy of its first campaign a week later, cold; its id."""
    first = sorted(raw.glob(f"M{machine}R1*"))[0]
    added = raw / f"M{machine}X01"
    shutil.copytree(first, added)
    meta = yaml.safe_load((added / "campaign.yaml").read_text())
    start = datetime.fromisoformat(str(meta["start"])) + timedelta(days=7)
    meta.update(campaign_id=added.name, start=start, start_state="cold")
    (added / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return added.name


def slope(x: list[float], y: list[float]) -> float | None:
    """Least-squares slope of log(y) on log(x); None with fewer than two sizes."""
    if len(x) < 2:
        return None
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def exponents(sizes: list[dict]) -> dict:
    """Return every stage's growth exponents: in campaigns (per machine count), in machines.

    Each over the sizes that ran the stage; in machines, one per campaign count.
    """
    done = [s for s in sizes if "failed" not in s]
    stages = list(dict.fromkeys(name for s in done for name in s["stages"]))
    result: dict = {"campaigns": {}, "machines": {}}
    for key, fixed, along in (
        ("campaigns", "machines", "campaigns_per_machine"),
        ("machines", "campaigns_per_machine", "machines"),
    ):
        for value in sorted({s[fixed] for s in done}):
            row = [s for s in done if s[fixed] == value]
            result[key][str(value)] = {
                name: slope(
                    [s[along] for s in row if name in s["stages"]],
                    [s["stages"][name]["seconds"] for s in row if name in s["stages"]],
                )
                for name in stages
            }
    return result


def report_lines(figures: dict) -> list[str]:
    """Return the table of seconds and MiB per stage and size, then the exponents."""
    lines = []
    for backend, run in figures.items():
        lines.append(f"backend: {backend}")
        for size in run["sizes"]:
            head = f"{size['machines']} machine(s) x {size['campaigns_per_machine']} campaigns"
            lines.append(f"  {head}")
            for name, stage in size["stages"].items():
                lines.append(
                    f"    {name:<18}{stage['seconds']:>9.1f} s{stage['peak_mib']:>9.0f} MiB"
                )
            if size.get("one_more"):
                lines.append(
                    f"  then one campaign added to workshop-{size['machines']} (the others' "
                    "results reused):"
                )
                for name, stage in size["one_more"].items():
                    before = size["stages"][name]["seconds"]
                    lines.append(
                        f"    {name:<18}{stage['seconds']:>9.1f} s (first run {before:.1f} s)"
                    )
            if "failed" in size:
                last = size["failed"]["output"].strip().splitlines()[-1:] or [""]
                lines.append(f"    {size['failed']['stage']} FAILED: {last[0]}")
        for key, by_value in run["exponents"].items():
            for value, by_stage in by_value.items():
                shown = ", ".join(
                    f"{name} {e:.2f}" for name, e in by_stage.items() if e is not None
                )
                fixed = "machines" if key == "campaigns" else "campaigns per machine"
                lines.append(f"  time ~ {key}^e at {fixed} = {value}: {shown or 'n/a'}")
    return lines


@contextmanager
def _cluster(folder: Path, use: bool) -> Iterator[str | None]:
    """Yield a local Dask cluster's address while the block runs (``use``), else None."""
    if use:
        with running_dask_cluster(folder, n_workers=2) as address:
            yield address
    else:
        yield None


def main(argv: list[str] | None = None) -> int:
    """Measure every size on this repository; print and save the figures."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.bench_scale", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--machines", type=int, nargs="+", default=list(MACHINES))
    parser.add_argument("--campaigns", type=int, nargs="+", default=list(CAMPAIGNS))
    parser.add_argument("--dask", action="store_true", help="also on a local Dask cluster")
    parser.add_argument(
        "--candidates", nargs="+", help="only these models of evaluate.candidates (default: all)"
    )
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    bin_dir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"}
    figures = {}
    with tempfile.TemporaryDirectory(prefix="thermal-bench-scale-") as tmp:
        for backend in ("local", "dask") if args.dask else ("local",):
            with _cluster(Path(tmp), backend == "dask") as address:
                run_env = {**env, SCHEDULER_VARIABLE: address} if address else env
                sizes = [
                    measure_size(Path.cwd(), Path(tmp) / backend, (m, c), run_env, args.candidates)
                    for m in args.machines
                    for c in args.campaigns
                ]
            figures[backend] = {"sizes": sizes, "exponents": exponents(sizes)}
    sys.stdout.write("\n".join(report_lines(figures)) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Time each stage of the default ``dvc repro`` and the whole (``make bench``).

``python -m benchmarks.bench`` prints the figures.
It also times best-subset selection against a naive loop of least-squares fits
(:mod:`benchmarks.selection_bench`) and the compensation runtime's prediction of one cycle as
the run grows (:mod:`benchmarks.runtime_bench`). The repository (tracked files, the shipped
demo campaigns) is copied to a temporary folder and ``dvc repro`` runs there from scratch
against a fresh local MLflow store, so that the figures do not depend on caches. In a second
fresh copy each stage's command (from ``dvc.yaml``) is run alone, in order, to time it.
Machines are noisy: read the shares rather than absolute seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from benchmarks import runtime_bench, selection_bench
from tests.helpers.repository import copy_repository

TARGET_TOTAL_S = 180.0  # the whole default pipeline with all models, 2 cores
TARGET_TRACK_SHARE = 0.20
TARGET_DISCREPANCY_S = 120.0  # the full discrepancy search over the six candidates, 2 cores


def timed(command: list[str], cwd: Path, env: dict[str, str]) -> float:
    """Run ``command`` and return its wall time in seconds; raise with its output on failure."""
    begin = time.perf_counter()
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True)
    elapsed = time.perf_counter() - begin
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{result.stdout}\n{result.stderr}")
    return elapsed


def run_benchmark(root: Path) -> dict:
    """Time the whole pipeline and each stage in a fresh copy of ``root``."""
    bin_dir = Path(sys.executable).parent
    path = f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"
    with tempfile.TemporaryDirectory(prefix="thermal-bench-") as folder:
        whole_copy = copy_repository(root, Path(folder) / "whole")
        env = {
            **os.environ,
            "PATH": path,
            "MLFLOW_TRACKING_URI": f"sqlite:///{whole_copy / 'mlflow.db'}",
        }
        whole = timed([str(bin_dir / "dvc"), "repro"], whole_copy, env)
        # Stages one by one, logging to the store the whole run created (its tables exist, as
        # for every run but a store's first); then track once more into a brand-new store.
        stage_copy = copy_repository(root, Path(folder) / "stages")
        stages = yaml.safe_load((stage_copy / "dvc.yaml").read_text())["stages"]
        per_stage = {
            name: timed(stage["cmd"].split(), stage_copy, env) for name, stage in stages.items()
        }
        env["MLFLOW_TRACKING_URI"] = f"sqlite:///{stage_copy / 'fresh.db'}"
        track_fresh = timed(stages["track"]["cmd"].split(), stage_copy, env)
    return {"whole_s": whole, "stages_s": per_stage, "track_fresh_store_s": track_fresh}


def report_lines(figures: dict) -> list[str]:
    """Human-readable table of the figures, with the targets."""
    whole, stages = figures["whole_s"], figures["stages_s"]
    total_stages = sum(stages.values())
    lines = [f"{'stage':<18}{'seconds':>9}{'share':>8}"]
    lines += [f"{name:<18}{sec:>9.2f}{sec / total_stages:>8.1%}" for name, sec in stages.items()]
    track = stages.get("track", 0.0)
    fresh = figures["track_fresh_store_s"]
    lines += [
        f"{'sum of stages':<18}{total_stages:>9.2f}",
        f"whole dvc repro from scratch: {whole:.2f} s (target < {TARGET_TOTAL_S:.0f} s: "
        f"{'met' if whole < TARGET_TOTAL_S else 'NOT met'})",
        f"MLflow logging (track stage, existing store) / whole dvc repro: {track / whole:.1%} "
        f"(target <= {TARGET_TRACK_SHARE:.0%}: "
        f"{'met' if track / whole <= TARGET_TRACK_SHARE else 'NOT met'})",
        f"track into a brand-new store (also creates the MLflow tables): {fresh:.2f} s, "
        f"{fresh / whole:.1%} of the whole dvc repro",
    ]
    if "discrepancy" in stages:
        sec = stages["discrepancy"]
        lines.append(
            f"discrepancy workflow on the demo campaigns (full search, six candidates): "
            f"{sec:.2f} s (target < {TARGET_DISCREPANCY_S:.0f} s: "
            f"{'met' if sec < TARGET_DISCREPANCY_S else 'NOT met'})"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark on the repository in the working directory and print the figures."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.bench", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    figures = run_benchmark(Path.cwd())
    sys.stdout.write("\n".join(report_lines(figures)) + "\n\n")
    figures["best_subset"] = selection_bench.compare()
    sys.stdout.write("best-subset selection, fast exhaustive search vs naive lstsq loop\n")
    sys.stdout.write("\n".join(selection_bench.report_lines(figures["best_subset"])) + "\n\n")
    figures["runtime_cycle"] = runtime_bench.cycle_times()
    sys.stdout.write("compensation runtime, one cycle's prediction (workshop run, 20-s samples)\n")
    sys.stdout.write("\n".join(runtime_bench.report_lines(figures["runtime_cycle"])) + "\n")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

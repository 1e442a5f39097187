"""``thermal summary``: say where the results of the last ``dvc repro`` are and how to see them.

``make run`` ends with it. It only reads the stage outputs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pipeline import paths

LOCAL_STORE = "sqlite:///mlflow.db"


def summary_lines(root: Path) -> list[str]:
    """Lines describing the outputs found under ``root`` (the repository)."""
    lines = ["", "Results of dvc repro:"]
    report = root / paths.VALIDATION_REPORT
    if report.is_file():
        validation = json.loads(report.read_text())["summary"]
        lines.append(
            f"  validation       {paths.VALIDATION_REPORT}: {len(validation['valid'])} valid, "
            f"{len(validation['quarantined'])} quarantined "
            f"{', '.join(validation['quarantined'])}"
        )
    metrics = root / paths.CROSS_SEASON_METRICS
    if metrics.is_file():
        for model, selections in json.loads(metrics.read_text()).items():
            for selection, entry in selections.items():
                o = entry["overall"]
                lines.append(
                    f"  scores           {paths.CROSS_SEASON_METRICS}: {model}/{selection} "
                    f"S {o['S_um']} um, Mn {o['Mn_um']} um, Sd {o['Sd_um']} um, "
                    f"Mn_val {o['Mn_val_um']} um (residual std); Mn_rms {o['Mn_rms_um']} um"
                )
    lines += [
        f"  matrix           {paths.MATRIX_CSV}, {paths.MATRIX_PNG}",
        f"  thermal error    {paths.SPINDLE_THERMAL_ERROR}",
        f"  axis separation  {paths.AXIS_SLOPES}, {paths.SEPARATION_PLOTS}/*.png",
        "  plots            .venv/bin/dvc plots show  (writes dvc_plots/index.html)",
    ]
    record = root / paths.TRACKING_RECORD
    uri = LOCAL_STORE
    if record.is_file():
        tracking = json.loads(record.read_text())
        uri = tracking.get("tracking_uri", uri)
        lines.append(
            f"  MLflow           experiment '{tracking.get('experiment')}', parent run "
            f"{tracking.get('parent_run_id')} at {uri}"
        )
    if uri.startswith("sqlite:"):
        lines += [
            "",
            "Open the MLflow UI (then browse http://127.0.0.1:5000):",
            f"  .venv/bin/mlflow ui --backend-store-uri {uri} --port 5000",
        ]
    else:
        lines += ["", f"Open the MLflow UI of your tracking server: {uri}"]
    return lines


def main(argv: list[str] | None = None) -> int:
    """Write the summary to standard output."""
    parser = argparse.ArgumentParser(prog="thermal summary", description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("."), help="repository root")
    args = parser.parse_args(argv)
    sys.stdout.write("\n".join(summary_lines(args.root)) + "\n")
    return 0

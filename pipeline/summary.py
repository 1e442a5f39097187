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


def _um(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


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
    champion = root / paths.CHAMPION_CARD
    if champion.is_file():
        card = json.loads(champion.read_text())
        scores = card["scores_um"]
        lines.append(
            f"  champion         {card['model']}/{card['selection']}/{card['mode']} on "
            f"{', '.join(card['sensors']) or 'no sensor'}: S {scores.get('S_um')} um, "
            f"Mn {scores.get('Mn_um')} um, Sd {scores.get('Sd_um')} um, "
            f"Mn_val {scores.get('Mn_val_um')} um (residual std)"
        )
    axis = root / paths.AXIS_MODEL_METRICS
    if axis.is_file():
        figures = json.loads(axis.read_text())
        lines.append(
            f"  axis model       {paths.AXIS_MODEL_REPORT}: validation residual "
            f"{_um(figures.get('residual_min_um'))} to {_um(figures.get('residual_max_um'))} um"
        )
    discrepancy = root / paths.DISCREPANCY_DOCUMENT
    if discrepancy.is_file():
        doc = json.loads(discrepancy.read_text())
        val = doc.get("validation") or {}
        lines.append(
            f"  twin vs data     {paths.DISCREPANCY}/discrepancy.md: named "
            f"{', '.join(doc['named_effects']) or 'nothing'}; held-out Z "
            f"{_um(doc['rmse_um_before'])} -> {_um(doc['rmse_um_after'])} um"
            + (
                f", validation Z {_um(val.get('rmse_um_before'))} -> "
                f"{_um(val.get('rmse_um_after'))} um"
                if val
                else ""
            )
        )
    lines += [
        f"  comparison       {paths.MODEL_COMPARISON} (every model, scores, heat-maps, plots)",
        f"  selection        {paths.SELECTION}/ (sensitive points, evidence, stability)",
        f"  scores           {paths.CANDIDATE_SCORES}, {paths.SCORES_LONG}, "
        f"{paths.CROSS_SEASON_METRICS}",
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
        if tracking.get("champion_uri"):
            lines.append(
                f'  champion model   mlflow.pyfunc.load_model("{tracking["champion_uri"]}")'
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

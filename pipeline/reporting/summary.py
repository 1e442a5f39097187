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


def champion_line(card: dict) -> str:
    """One line on an axis' champion: what it is, its held-out score against no compensation."""
    scores = card["scores"]
    protocol = card.get("protocol")
    held_out = scores.get(f"{protocol}_Mn_rms_um") if protocol else None
    name = f"{card['model']}/{card['selection']}/{card['mode']}"
    if not card["compensate"]:
        return f"none: do not compensate ({card['reason']})"
    return (
        f"{name} on {', '.join(card['inputs']) or 'no input'}: held-out RMS {_um(held_out)} um "
        f"vs {_um(card.get('none_score_um'))} um uncompensated ({card.get('protocol_name')}); "
        f"validation RMS {_um(scores.get('pooled_Mn_val_rms_um'))} um"
    )


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
    for path in sorted((root / paths.CHAMPION).glob(f"*/{paths.CHAMPION_CARD_FILE}")):
        lines.append(
            f"  champion {path.parent.name:<7} " + champion_line(json.loads(path.read_text()))
        )
    lines += compensation_lines(root)
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
        if doc.get("status") == "untestable":
            lines.append(
                f"  twin vs data     {paths.DISCREPANCY}/discrepancy.md: untestable "
                f"({doc.get('reason', 'no reason given')})"
            )
        else:
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
    uri, runs_page = LOCAL_STORE, ""
    if record.is_file():
        tracking = json.loads(record.read_text())
        uri = tracking.get("tracking_uri", uri)
        if tracking.get("experiment_id") is not None:
            runs_page = runs_page_path(str(tracking["experiment_id"]))
        ranked = sorted(k for k in (tracking.get("views") or {}) if k.startswith("ranked-"))
        if ranked:  # each axis' candidates ranked, scores as columns (a shared view)
            runs_page = tracking["views"][ranked[0]]
        lines.append(
            f"  MLflow           experiment '{tracking.get('experiment')}', parent run "
            f"{tracking.get('parent_run_id')} at {uri}"
        )
        for axis, champion in (tracking.get("champions") or {}).items():
            if champion.get("uri"):
                lines.append(f'  model {axis:<10} mlflow.pyfunc.load_model("{champion["uri"]}")')
        lines += gate_lines(tracking.get("promotion") or [])
    if uri.startswith("sqlite:"):
        lines += [
            "",
            f"Open the MLflow UI (then browse http://127.0.0.1:5000{runs_page}):",
            f"  .venv/bin/mlflow ui --backend-store-uri {uri} --port 5000",
        ]
    else:
        lines += ["", f"Open the MLflow UI of your tracking server: {uri.rstrip('/')}{runs_page}"]
    return lines


def compensation_lines(root: Path) -> list[str]:
    """One line per axis on the replay proof (``reports/compensation/compensation.md``)."""
    summary = root / paths.COMPENSATION_SUMMARY
    if not summary.is_file():
        return []
    document = json.loads(summary.read_text())
    lines = [
        f"  replay {axis:<9} {record['headline']} ({paths.COMPENSATION_REPORT})"
        for axis, record in (document.get("axes") or {}).items()
    ]
    budget = root / paths.SENSOR_BUDGET
    if budget.is_file():
        lines.append(
            f"  sensor budget    {paths.SENSOR_BUDGET}, {paths.SENSOR_BUDGET_PLOT} (best model "
            "with k sensors, held-out RMS)"
        )
    lines.append(
        f"  compensate       .venv/bin/thermal compensate --source csv:<logger file> --sink "
        f"csv:<offsets.csv>  (bundles in {paths.COMPENSATION_BUNDLES}/)"
    )
    return lines


def gate_lines(decisions: list[dict]) -> list[str]:
    """One line per axis on the promotion gate's decision (``reports/promotion/promotion.md``)."""
    lines = []
    for decision in decisions:
        reason = decision["reason"]
        lines.append(
            f"  gate {decision['axis']:<11} {decision['action']} "
            f"v{decision.get('challenger_version') or '-'}: {reason[0].lower()}{reason[1:]} "
            f"({paths.PROMOTION_REPORT})"
        )
    return lines


def runs_page_path(experiment_id: str) -> str:
    """Return the UI path of an experiment's run list.

    MLflow 3 opens an experiment on its GenAI overview (traces) unless the page is asked for the
    model-training view: ``?workflowType=machine_learning`` lands on the runs.
    """
    return f"/#/experiments/{experiment_id}?workflowType=machine_learning"


def main(argv: list[str] | None = None) -> int:
    """Write the summary to standard output."""
    parser = argparse.ArgumentParser(prog="thermal summary", description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("."), help="repository root")
    args = parser.parse_args(argv)
    sys.stdout.write("\n".join(summary_lines(args.root)) + "\n")
    return 0

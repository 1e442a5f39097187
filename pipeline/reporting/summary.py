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
    """Lines describing the outputs found under ``root`` (the repository), machine by machine."""
    lines = ["", "Results of dvc repro:"]
    report = root / paths.VALIDATION_REPORT
    if report.is_file():
        validation = json.loads(report.read_text())["summary"]
        lines.append(
            f"  validation       {paths.VALIDATION_REPORT}: {len(validation['valid'])} valid, "
            f"{len(validation['quarantined'])} quarantined "
            f"{', '.join(validation['quarantined'])}"
        )
    compensation = _machines(root / paths.COMPENSATION_SUMMARY)
    axis_models = _machines(root / paths.AXIS_MODEL_METRICS)
    for machine in machine_folders(root):
        lines.append(f"  machine {machine}")
        lines += machine_lines(root, machine, compensation.get(machine), axis_models.get(machine))
    lines += [
        f"  comparison       {paths.MODEL_COMPARISON} (every model, scores, heat-maps, plots)",
        f"  selection        {paths.SELECTION}/ (sensitive points, evidence, stability)",
        f"  scores           {paths.CANDIDATE_SCORES}, {paths.SCORES_LONG}, "
        f"{paths.CROSS_SEASON_METRICS}",
        f"  thermal error    {paths.SPINDLE_THERMAL_ERROR}",
        f"  axis separation  {paths.AXIS_SLOPES}, {paths.SEPARATION_PLOTS}/*.png",
        "  plots            .venv/bin/dvc plots show  (writes dvc_plots/index.html)",
    ]
    if (root / paths.SENSOR_BUDGET).is_file():
        lines.append(
            f"  sensor budget    {paths.SENSOR_BUDGET}, {paths.SENSOR_BUDGET_PLOT} (best model "
            "with k sensors, held-out RMS)"
        )
    if compensation:
        lines.append(
            f"  compensate       .venv/bin/thermal compensate --source csv:<logger file> --sink "
            f"csv:<offsets.csv>{' --machine <machine>' if len(compensation) > 1 else ''}  "
            f"(bundles in {paths.COMPENSATION_BUNDLES}/)"
        )
    return lines + tracking_lines(root)


def _machines(path: Path) -> dict:
    """Return the ``machines`` entry of a stage's JSON output (empty without the file)."""
    return (json.loads(path.read_text()).get("machines") or {}) if path.is_file() else {}


def machine_folders(root: Path) -> list[str]:
    """Return the machines with an output: the champions' and the discrepancy's folders."""
    found = {p.name for p in (root / paths.CHAMPION).glob("*") if p.is_dir()}
    found |= {p.parent.name for p in (root / paths.DISCREPANCY).glob(f"*/{paths.DISCREPANCY_FILE}")}
    return sorted(found)


def machine_lines(
    root: Path, key: str, compensation: dict | None, axis_model: dict | None
) -> list[str]:
    """One machine's lines: champions, replay proofs, axis model, twin against its data.

    ``key``: the machine's folder name; ``compensation`` and ``axis_model``: its entries.
    """
    lines = [
        f"    champion {path.parent.name:<7} " + champion_line(json.loads(path.read_text()))
        for path in sorted((root / paths.CHAMPION / key).glob(f"*/{paths.CHAMPION_CARD_FILE}"))
    ]
    lines += [
        f"    replay {axis:<9} {record['headline']} ({paths.COMPENSATION_REPORT})"
        for axis, record in ((compensation or {}).get("axes") or {}).items()
    ]
    if axis_model:
        lines.append(
            f"    axis model     {paths.AXIS_MODEL_REPORT}: validation residual "
            f"{_um(axis_model.get('residual_min_um'))} to "
            f"{_um(axis_model.get('residual_max_um'))} um"
        )
    discrepancy = root / paths.discrepancy_document(key)
    if discrepancy.is_file():
        lines.append("    " + twin_line(key, json.loads(discrepancy.read_text())))
    return lines


def twin_line(key: str, doc: dict) -> str:
    """One line on the twin against a machine's campaigns (its ``discrepancy.md``)."""
    where = f"{paths.DISCREPANCY}/{key}/discrepancy.md"
    if doc.get("status") == "untestable":
        return f"twin vs data   {where}: untestable ({doc.get('reason', 'no reason given')})"
    val = doc.get("validation") or {}
    return (
        f"twin vs data   {where}: named {', '.join(doc['named_effects']) or 'nothing'}; "
        f"held-out Z {_um(doc['rmse_um_before'])} -> {_um(doc['rmse_um_after'])} um"
        + (
            f", validation Z {_um(val.get('rmse_um_before'))} -> {_um(val.get('rmse_um_after'))} um"
            if val
            else ""
        )
    )


def tracking_lines(root: Path) -> list[str]:
    """Where the MLflow runs and registered models are, each machine's gate, the UI command."""
    record = root / paths.TRACKING_RECORD
    uri, runs_page, lines = LOCAL_STORE, "", []
    if record.is_file():
        tracking = json.loads(record.read_text())
        uri = tracking.get("tracking_uri", uri)
        for machine, entry in (tracking.get("machines") or {}).items():
            if not runs_page and entry.get("experiment_id") is not None:
                runs_page = runs_page_path(str(entry["experiment_id"]))
            ranked = sorted(k for k in (entry.get("views") or {}) if k.startswith("ranked-"))
            if ranked and "viewStateShareKey" not in runs_page:
                runs_page = entry["views"][ranked[0]]  # candidates ranked, scores as columns
            lines.append(
                f"  MLflow           machine {machine}: experiment "
                f"'{tracking.get('experiment')}', parent run {entry.get('parent_run_id')} at {uri}"
            )
            for axis, champion in (entry.get("champions") or {}).items():
                if champion.get("uri"):
                    lines.append(
                        f'  model {axis:<10} mlflow.pyfunc.load_model("{champion["uri"]}")'
                    )
            lines += gate_lines(entry.get("promotion") or [])
    if uri.startswith("sqlite:"):
        return [
            *lines,
            "",
            f"Open the MLflow UI (then browse http://127.0.0.1:5000{runs_page}):",
            f"  .venv/bin/mlflow ui --backend-store-uri {uri} --port 5000",
        ]
    return [*lines, "", f"Open the MLflow UI of your tracking server: {uri.rstrip('/')}{runs_page}"]


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

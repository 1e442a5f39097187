"""The compensation stage's record and report: what runs per axis and what it left on replay."""

from __future__ import annotations

import math

import pandas as pd

from pipeline.compensation.bundle import AxisBundle
from pipeline.compensation.replay import AxisProof
from pipeline.machines import machine_key


def _um(value) -> str:
    return "-" if value is None or not math.isfinite(float(value)) else f"{float(value):.2f}"


def summary_record(
    bundle: AxisBundle, proof: AxisProof, coefficients: dict, controller: dict
) -> dict:
    """Return an axis' entry of ``reports/compensation/compensation.json``.

    Keys: ``model`` (the champion), ``compensate``, ``inputs``, ``proof`` (the replay's means
    and ratio, :func:`pipeline.compensation.replay.proof_summary`), ``linear`` (whether a
    coefficient table exists), ``tempcomp`` (the formula or why none), ``headline`` (one line).
    """
    card = bundle.card
    summary = dict(proof.summary)
    model = f"{card['model']}/{card['selection']}/{card['mode']}"
    if summary:
        headline = (
            f"replayed {summary['n_campaigns']} held-out campaign(s) through the runtime: "
            f"RMS {_um(summary['rms_before_um'])} um without compensation -> "
            f"{_um(summary['rms_after_um'])} um compensated ({model}; offline "
            f"{_um(summary['offline_rms_um'])} um, ratio {summary['ratio']:.2f}); largest drift "
            f"{_um(summary['max_drift_before_um'])} -> {_um(summary['max_drift_after_um'])} um"
        )
    else:
        headline = f"{model}: no held-out campaign to replay"
    return {
        "model": model,
        "compensate": bundle.compensate,
        "inputs": list(bundle.champion.spec.inputs),
        "proof": summary,
        "linear": bool(coefficients.get("linear")),
        "tempcomp": controller.get("heidenhain_tempcomp"),
        "headline": headline,
    }


def proof_markdown(axis: str, table: pd.DataFrame) -> list[str]:
    """Return the per-campaign proof table of one axis as Markdown lines."""
    lines = [
        f"### Axis {axis}: replay of the held-out campaigns",
        "",
        "| campaign | season | largest drift before / after (um) | drift range before / after "
        "(um) | RMS before / after (um) | offline RMS (um) | cycles limited | fallback cycles |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in table.itertuples():
        lines.append(
            f"| {row.campaign_id} | {row.season} | {_um(row.max_drift_before_um)} / "
            f"{_um(row.max_drift_after_um)} | {_um(row.range_before_um)} / "
            f"{_um(row.range_after_um)} | {_um(row.rms_before_um)} / {_um(row.rms_after_um)} | "
            f"{_um(row.offline_rms_um)} | {row.limited_share:.0%} | {row.fallback_cycles} |"
        )
    return [*lines, ""]


def fallback_markdown(fallbacks: list[dict]) -> list[str]:
    """Return the fallbacks' table: each sensor lost, what its fallback leaves held out."""
    if not fallbacks:
        return ["No fallback model: a lost sensor holds the last offset, then decays it.", ""]
    lines = [
        "When a sensor is lost the runtime falls back to the champion's family without it:",
        "",
        "| sensor lost | fallback held-out RMS (um) | champion (um) | no compensation (um) |",
        "|---|---|---|---|",
    ]
    for item in fallbacks:
        lines.append(
            f"| {item['lost']} | {_um(item.get('heldout_rms_um'))} | "
            f"{_um(item.get('champion_rms_um'))} | {_um(item.get('none_rms_um'))} |"
        )
    return [*lines, ""]


def render_report(document: dict, budget: pd.DataFrame, tables: dict[str, pd.DataFrame]) -> str:
    """Return ``reports/compensation/compensation.md``."""
    lines = [
        "# Compensation: what the machine runs, and what it leaves on replay",
        "",
        "Each held-out campaign is replayed through the compensation runtime (`thermal "
        "compensate`: input checks, the training code's input preparation run incrementally, "
        "the size and rate limits of `params.yaml` `compensation`) with the fit that did not "
        "see it. *Before*: the measured thermal error; *after*: what is left once the offset "
        "written is applied (ISO 230-3 style: largest drift and drift range over the test). "
        "*Offline*: the champion's held-out prediction of the same samples, without the "
        "runtime.",
        "",
    ]
    for machine, entry in document["machines"].items():
        lines += machine_markdown(machine, entry, tables.get(machine) or {})
    if not budget.empty:
        lines += ["## Sensors a machine can afford", "", budget.to_markdown(index=False), ""]
    return "\n".join(lines) + "\n"


def machine_markdown(machine: str, entry: dict, tables: dict[str, pd.DataFrame]) -> list[str]:
    """Return one machine's sections: each axis' headline, replay proof, fallbacks, exports."""
    lines = []
    for axis, record in entry["axes"].items():
        lines += [f"## Machine {machine}, axis {axis}", "", record["headline"] + ".", ""]
        if axis in tables:
            lines += proof_markdown(axis, tables[axis])
        lines += fallback_markdown(record.get("fallbacks") or [])
        tempcomp = record.get("tempcomp") or {}
        lines += [
            "",
            f"Controller exports in `reports/compensation/{machine_key(machine)}/{axis}/`: "
            "coefficients "
            + ("(linear model)" if record["linear"] else "none (the model is not linear)")
            + "; Heidenhain TEMPCOMP: "
            + str(tempcomp.get("formula") or tempcomp.get("reason") or "-")
            + ".",
            "",
        ]
    return lines

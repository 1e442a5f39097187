"""Write the discrepancy outputs: ``discrepancy.json``, ``discrepancy.md``, figures, MLflow run.

The report states, in an engineer's words, where the calibrated baseline twin disagrees with the
measurements (:mod:`pipeline.discrepancy.localise`), which effects the forward search named
(:mod:`pipeline.discrepancy.search`), with what evidence, and how far the held-out displacement
residual shrinks. Figures are built and saved with the helpers of :mod:`pipeline.plots`
(Agg canvas, no pyplot); mlflow is imported only when a run is logged.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from pipeline import plots
from pipeline.discrepancy.localise import Localisation
from pipeline.discrepancy.search import SearchResult, SearchSettings

logger = logging.getLogger(__name__)

JSON_FILE = "discrepancy.json"
MARKDOWN_FILE = "discrepancy.md"
FIT_FIGURE = "heldout_fit.png"
RESIDUAL_FIGURE = "residuals.png"
LOCALISATION_CSV = "localisation.csv"

EFFECT_WORDS = {
    "ambient_variation": "the workshop air temperature varies and the structure follows it",
    "centrifugal_growth": "the spindle nose shifts instantly with speed squared (centrifugal)",
    "nonlinear_bearing_heat": "bearing friction heat grows faster than linearly with speed",
    "sensor_lag": "the sensors read their locations through a first-order lag",
    "thermal_bending": "the column bends when its front and rear differ in temperature",
    "motor_heat": "the spindle motor heats the headstock",
}
"""One line per effect, for the report."""

STATUS_TESTED = "tested"
STATUS_UNTESTABLE = "untestable"
"""``discrepancy.json`` ``status``: the twin was compared with the campaigns, or could not be."""


def untestable_document(
    reason: str,
    *,
    needed_roles: Sequence[str],
    roles_present: Sequence[str],
    campaign_ids: Sequence[str],
    quarantined: Sequence[str],
    synthetic: bool,
) -> dict[str, Any]:
    """Return the ``discrepancy.json`` of campaigns the twin cannot be compared with.

    Fields: ``status`` (``untestable``), ``reason`` (in words, with what to add),
    ``needed_roles`` (sensor roles the twin's network is built from; at least one is needed),
    ``roles_present``, ``named_effects`` (empty), ``campaigns``, ``quarantined``,
    ``synthetic``.
    """
    return {
        "status": STATUS_UNTESTABLE,
        "reason": reason,
        "needed_roles": list(needed_roles),
        "roles_present": list(roles_present),
        "named_effects": [],
        "campaigns": list(campaign_ids),
        "quarantined": list(quarantined),
        "synthetic": bool(synthetic),
    }


def untestable_markdown(doc: Mapping[str, Any]) -> str:
    """Write the engineer's report when the twin cannot be compared with the campaigns."""
    source = "synthetic campaigns (not measurements)" if doc["synthetic"] else "measured campaigns"
    quarantined = (
        f" Quarantined and left out: {', '.join(doc['quarantined'])}." if doc["quarantined"] else ""
    )
    return "\n".join([
        "# Where the twin and the measurements disagree",
        "",
        f"**Untestable on these campaigns.** {doc['reason'][:1].upper()}{doc['reason'][1:]}.",
        "",
        f"Data: {len(doc['campaigns'])} spindle campaign(s) with a Z displacement, {source}; "
        f"sensor roles present: {', '.join(doc['roles_present']) or 'none'}.{quarantined}",
        "",
        "The physical twin is a thermal network whose nodes are the places of the sensors "
        "(`campaign.yaml` `sensors: <name>: {role: ...}`). Roles it can use: "
        + ", ".join(f"`{r}`" for r in doc["needed_roles"])
        + "; `ambient` drives it. Nothing was calibrated or named, and the `twin` candidate of "
        "the model comparison is skipped for this reason. The rest of the pipeline (the "
        "regression models, their scores and the champion) does not need the roles.",
        "",
    ])  # fmt: skip


def write_untestable(out_dir: Path, doc: Mapping[str, Any]) -> list[Path]:
    """Write ``discrepancy.json`` and ``discrepancy.md`` of an untestable folder."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for stale in (FIT_FIGURE, RESIDUAL_FIGURE, LOCALISATION_CSV):
        (out_dir / stale).unlink(missing_ok=True)
    json_path = out_dir / JSON_FILE
    json_path.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    md_path = out_dir / MARKDOWN_FILE
    md_path.write_text(untestable_markdown(doc), encoding="utf-8")
    return [json_path, md_path]


def build_document(
    result: SearchResult,
    before: Localisation,
    after: Localisation | None,
    settings: SearchSettings,
    *,
    synthetic: bool,
    campaign_ids: Sequence[str],
    quarantined: Sequence[str] = (),
) -> dict[str, Any]:
    """Assemble the content of ``discrepancy.json``.

    Fields: ``status`` (``tested``), ``named_effects``, ``rmse_um_before``,
    ``rmse_um_after`` (held-out Z RMS, um), ``rmse_T_K_before/after``, ``per_campaign``,
    ``steps`` (effect, evidence, RMS before/after, calibrated parameters with units),
    ``candidates_by_step`` (evidence of every candidate at every step), ``untestable``
    (effect -> missing roles), ``localisation`` (findings, ambient lag, before and after),
    ``thresholds``, ``campaigns``, ``quarantined``, ``synthetic``, ``validation`` (the named
    effects checked on the validation campaigns held back from the search, or None).
    """
    doc = {"status": STATUS_TESTED, **result.to_dict()}
    doc["localisation"] = {
        "before": {
            "findings": before.findings,
            "ambient_correlation": _num(before.ambient_correlation),
            "ambient_lag_min": _num(before.ambient_lag_min),
        }
    }
    if after is not None:
        doc["localisation"]["after"] = {
            "findings": after.findings,
            "ambient_correlation": _num(after.ambient_correlation),
            "ambient_lag_min": _num(after.ambient_lag_min),
        }
    doc["thresholds"] = {
        "min_heldout_reduction": settings.min_heldout_reduction,
        "min_heldout_temperature_reduction": settings.min_heldout_t_reduction,
        "max_delta_bic": settings.max_delta_bic,
        "n_folds": settings.n_folds,
    }
    doc["campaigns"] = list(campaign_ids)
    doc["quarantined"] = list(quarantined)
    doc["synthetic"] = bool(synthetic)
    return doc


def _num(x: float) -> float | None:
    x = float(x)
    return round(x, 4) if np.isfinite(x) else None


def _fmt(x: float | None, digits: int = 2) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def _pct(x: float | None) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:.0f} %"


def _motor_rise(params: Mapping[str, Any]) -> float | None:
    """Steady rise of the motor node over its surroundings per 1000 rpm, K (None if n/a)."""
    names = ("q_motor_W_per_krpm", "h_motor_W_per_K", "G_motor_headstock_W_per_K")
    values = [(params.get(n) or {}).get("value") for n in names]
    if any(v is None for v in values):
        return None
    q, h, g = values
    return q / (h + g)


def _per_campaign_table(label: str, per_campaign: Mapping[str, Any]) -> list[str]:
    """Markdown rows: Z (um) and temperature (K) RMS before and after, one row per campaign."""
    lines = [
        f"| {label} | Z before (um) | Z after (um) | T before (K) | T after (K) |",
        "|---|---:|---:|---:|---:|",
    ]
    for cid, row in per_campaign.items():
        b, a = row["before"], row["after"]
        lines.append(
            f"| {cid} | {_fmt(b.get('z_um'))} | {_fmt(a.get('z_um'))} | "
            f"{_fmt(b.get('t_k'))} | {_fmt(a.get('t_k'))} |"
        )
    return lines


def markdown(doc: Mapping[str, Any], figures: Sequence[str]) -> str:
    """Write the engineer's report (``discrepancy.md``) from the JSON document."""
    named = doc["named_effects"]
    source = "synthetic campaigns (not measurements)" if doc["synthetic"] else "measured campaigns"
    lines = [
        "# Where the twin and the measurements disagree",
        "",
        f"Data: {len(doc['campaigns'])} spindle campaigns, {source}"
        + (
            f"; quarantined and left out: {', '.join(doc['quarantined'])}"
            if doc["quarantined"]
            else ""
        )
        + ".",
        f"Held-out = displacement residual on campaigns not used for calibration "
        f"({len(doc['folds'])}-fold cross-validation across the "
        f"{sum(len(f) for f in doc['folds'])} searched campaigns)"
        + (
            f"; the {len(doc['validation']['campaigns'])} validation campaigns are held back "
            "from the search and used only for the check below."
            if doc.get("validation")
            else "."
        ),
        "",
        "## What the baseline twin misses",
        "",
    ]
    lines += [f"- {f}" for f in doc["localisation"]["before"]["findings"]]
    lines += ["", "## What is missing", ""]
    if named:
        lines.append(
            f"The search names **{len(named)}** effect(s), in order: "
            + ", ".join(f"`{e}`" for e in named)
            + "."
        )
        lines.append("")
        for step in doc["steps"]:
            ev = step["evidence"]
            lines.append(
                f"- adding `{step['effect']}` ({EFFECT_WORDS.get(step['effect'], '')}) reduces the "
                f"held-out Z residual from {_fmt(step['rmse_um_before'])} um to "
                f"{_fmt(step['rmse_um_after'])} um RMS ({_pct(ev['heldout_reduction'])}), "
                f"temperatures from {_fmt(step['rmse_T_K_before'])} K to "
                f"{_fmt(step['rmse_T_K_after'])} K; BIC changes by {_fmt(ev['delta_bic'], 1)}."
            )
            own = step["effect_parameters"]
            shown = ", ".join(f"{k} = {_fmt(v['value'], 4)} {v['unit']}" for k, v in own.items())
            shown = shown or "none (it uses the measured signals)"
            lines.append(
                f"  - its own calibrated parameters: {shown} (all parameters in discrepancy.json)"
            )
            rise = _motor_rise(step["parameters"]) if step["effect"] == "motor_heat" else None
            if rise is not None:
                lines.append(
                    "  - read the motor loss together with the node's cooling: the temperatures "
                    "fix the motor node's steady rise over its surroundings, q / (h + G) = "
                    f"{_fmt(rise, 3)} K per 1000 rpm, and its time constant, not q, h and its "
                    "heat capacity one by one (they scale together while its link to the "
                    "headstock is weak)"
                )
    else:
        lines.append(
            "No candidate effect passes the thresholds: the baseline twin explains the data "
            "within what the cross-validation can tell apart. Nothing is named."
        )
    lines += [
        "",
        f"Overall held-out Z residual: **{_fmt(doc['rmse_um_before'])} um** with the baseline, "
        f"**{_fmt(doc['rmse_um_after'])} um** with "
        + (f"the twin + {', '.join(named)}" if named else "no effect added")
        + f"; temperatures {_fmt(doc['rmse_T_K_before'])} K -> {_fmt(doc['rmse_T_K_after'])} K.",
        "",
    ]
    lines += _per_campaign_table("campaign", doc["per_campaign"])
    val = doc.get("validation")
    if val:
        lines += [
            "",
            "## Check on the validation campaigns",
            "",
            f"Calibrated on all {sum(len(f) for f in doc['folds'])} searched campaigns, the "
            f"baseline twin predicts the validation campaigns ({', '.join(val['campaigns'])}), "
            "which no step of the search has seen, with a Z residual of "
            f"**{_fmt(val['rmse_um_before'])} um** RMS and temperatures "
            f"{_fmt(val['rmse_T_K_before'])} K; "
            + (f"the twin + {', '.join(named)}" if named else "with nothing added it is the same")
            + f": **{_fmt(val['rmse_um_after'])} um**, {_fmt(val['rmse_T_K_after'])} K.",
            "",
        ]
        lines += _per_campaign_table("validation campaign", val["per_campaign"])
    if "after" in doc["localisation"] and named:
        lines += ["", "## What remains after adding the named effects", ""]
        lines += [f"- {f}" for f in doc["localisation"]["after"]["findings"]]
    lines += ["", "## Evidence of every candidate", ""]
    lines.append(
        f"An effect is named when it reduces the held-out Z RMS by at least "
        f"{100 * doc['thresholds']['min_heldout_reduction']:.0f} % or the held-out temperature "
        f"RMS by at least {100 * doc['thresholds']['min_heldout_temperature_reduction']:.0f} %, "
        f"and changes BIC by at most {doc['thresholds']['max_delta_bic']:g}; the candidate with "
        "the lowest BIC among those is added and the search repeats."
    )
    for entry in doc["candidates_by_step"]:
        lines += [
            "",
            f"Step {entry['step']}:",
            "",
            "| effect | held-out Z RMS (um) | Z reduction | held-out T RMS (K) | T reduction "
            "| delta BIC | delta AICc | passes |",
            "|---|---:|---:|---:|---:|---:|---:|---|",
        ]
        for c in entry["candidates"]:
            lines.append(
                f"| `{c['effect']}` | {_fmt(c['rmse_heldout_um'])} | "
                f"{_pct(c['heldout_reduction'])} | {_fmt(c['rmse_heldout_T_K'], 3)} | "
                f"{_pct(c['heldout_T_reduction'])} | "
                f"{_fmt(c['delta_bic'], 1)} | {_fmt(c['delta_aicc'], 1)} | "
                f"{'yes' if c['passes'] else 'no'} |"
            )
    if doc["untestable"]:
        lines += ["", "## Effects that cannot be tested on these data", ""]
        for effect, roles in doc["untestable"].items():
            lines.append(
                f"- `{effect}`: no sensor with role {' / '.join(roles)}; map one in campaign.yaml "
                "to test it."
            )
    if figures:
        lines += ["", "## Figures", ""]
        lines += [f"![{Path(f).stem}]({Path(f).name})" for f in figures]
    return "\n".join(lines) + "\n"


def _prediction(campaign, residual: np.ndarray) -> np.ndarray:
    return np.asarray(campaign.z_um, dtype=float) - np.asarray(residual, dtype=float)


def heldout_fit_figure(
    campaigns: Sequence, result: SearchResult, title: str, max_panels: int = 3
) -> Figure:
    """Build measured Z vs held-out baseline and augmented twin, a few campaigns.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        ``t_s`` (s), ``z_um`` (um), ``rpm`` (rpm) and ``season`` (optional) of each campaign.
    result : SearchResult
        ``baseline.heldout`` / ``final.heldout`` ``z_residual_um`` by campaign (um) and
        ``named_effects``.
    title : str
        Wrapped to the figure's width.
    max_panels : int
        Campaigns shown (those with the largest baseline residual).

    Returns
    -------
    Figure
    """
    base = result.baseline.heldout.z_residual_um
    final = result.final.heldout.z_residual_um
    by_id = {c.campaign_id: c for c in campaigns}
    ranked = sorted(base, key=lambda c: -float(np.sqrt(np.nanmean(base[c] ** 2))))[:max_panels]
    fig = plots.new_figure(1.6 + 3.6 * max(len(ranked), 1), 4.6)
    axes = fig.subplots(1, max(len(ranked), 1), squeeze=False)
    label = "twin + " + ", ".join(result.named_effects) if result.named_effects else "twin (same)"
    speed_handles: list = []
    for ax, cid in zip(axes[0], ranked, strict=False):
        c = by_id[cid]
        minutes = np.asarray(c.t_s, dtype=float) / 60.0
        speed = ax.twinx()
        speed_handles = speed.step(minutes, c.rpm, where="post", color="0.65", lw=0.9,
                                   label="spindle speed (right axis)")  # fmt: skip
        speed.set_ylabel("spindle speed (rpm)", color="0.4")
        ax.set_zorder(speed.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.plot(minutes, c.z_um, "k.", ms=3, label="measured")
        ax.plot(minutes, _prediction(c, base[cid]), "-", label="baseline twin")
        ax.plot(minutes, _prediction(c, final[cid]), "--", label=label)
        name = plots.campaign_label(cid, getattr(c, "season", None))
        ax.set_title(f"{name}, held out", fontsize=plots.PANEL_TITLE_FONTSIZE)
        ax.set(xlabel="elapsed time (min)", ylabel="Z drift (um)")
    if ranked:
        handles, names = axes[0][0].get_legend_handles_labels()
        fig.legend([*handles, *speed_handles], [*names, "spindle speed (right axis)"],
                   loc="outside lower center", ncols=4, fontsize=9)  # fmt: skip
    fig.suptitle(plots.wrap_text(fig, title, plots.TITLE_FONTSIZE), fontsize=plots.TITLE_FONTSIZE)
    return fig


def plot_heldout_fit(
    campaigns: Sequence, result: SearchResult, title: str, out: Path, max_panels: int = 3
) -> None:
    """Measured Z vs held-out baseline and augmented twin, a few campaigns, as a PNG.

    Parameters
    ----------
    campaigns, result, title, max_panels
        See :func:`heldout_fit_figure`.
    out : Path
        PNG path; parent folders are created.
    """
    plots.save_figure(heldout_fit_figure(campaigns, result, title, max_panels), out)


def residuals_figure(campaigns: Sequence, result: SearchResult, title: str) -> Figure:
    """Build the held-out Z residuals before and after, every campaign, and RMS per campaign.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        ``t_s`` (s) and ``season`` (optional) of each campaign.
    result : SearchResult
        ``baseline.heldout`` / ``final.heldout`` ``z_residual_um`` by campaign (um) and
        ``named_effects``.
    title : str
        Wrapped to the figure's width.

    Returns
    -------
    Figure
    """
    before = result.baseline.heldout.z_residual_um
    after = result.final.heldout.z_residual_um
    by_id = {c.campaign_id: c for c in campaigns}
    ids = sorted(before)
    seasons = {cid: getattr(by_id[cid], "season", None) for cid in ids}
    names = {cid: plots.campaign_label(cid, seasons[cid]) for cid in ids}
    fig = plots.new_figure(plots.MAX_WIDTH_IN, 8.0)
    axes = fig.subplot_mosaic([["before", "after"], ["rms", "rms"]], sharey=False)
    palette = colormaps["tab20" if len(ids) <= 20 else "turbo"]
    colours = palette(np.linspace(0, 1, len(ids))) if len(ids) > 20 else palette.colors
    lim = max((float(np.nanmax(np.abs(v))) for v in before.values()), default=1.0) * 1.05
    augmented = "twin + " + ", ".join(result.named_effects) if result.named_effects else None
    for key, series, name in (
        ("before", before, "baseline twin"),
        ("after", after, augmented or "augmented twin (nothing named: the baseline)"),
    ):
        ax = axes[key]
        for colour, cid in zip(colours, ids, strict=False):
            if cid in series:
                ax.plot(np.asarray(by_id[cid].t_s) / 60.0, series[cid], lw=1, color=colour,
                        label=names[cid])  # fmt: skip
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(plots.wrap_text(fig, f"held-out residual, {name}", 10.5, 5.0), fontsize=10.5)
        ax.set(xlabel="elapsed time (min)", ylabel="measured - twin Z (um)", ylim=(-lim, lim))
    handles, labels = axes["before"].get_legend_handles_labels()
    named = "campaign (season)" if any(seasons.values()) else "campaign"
    fig.legend(handles, labels, loc="outside right upper", fontsize=8, title=named,
               title_fontsize=8)  # fmt: skip
    rms_b = [float(np.sqrt(np.nanmean(before[c] ** 2))) for c in ids]
    rms_a = [float(np.sqrt(np.nanmean(after[c] ** 2))) if c in after else np.nan for c in ids]
    x = np.arange(len(ids))
    bars = axes["rms"]
    bars.bar(x - 0.2, rms_b, 0.4, label="baseline twin")
    bars.bar(x + 0.2, rms_a, 0.4, label=augmented or "augmented twin")
    bars.set_xticks(x, [plots.campaign_label(c, seasons[c], "\n") for c in ids], fontsize=8.5)
    bars.set_title("held-out Z RMS per campaign", fontsize=10.5)
    bars.set(xlabel=f"held-out {named}", ylabel="held-out Z RMS (um)")
    bars.legend(fontsize=8)
    fig.suptitle(plots.wrap_text(fig, title, plots.TITLE_FONTSIZE), fontsize=plots.TITLE_FONTSIZE)
    fig.canvas.draw()
    plots.fit_tick_labels(fig, bars.xaxis, bars.bbox.width / max(len(ids), 1))
    return fig


def plot_residuals(campaigns: Sequence, result: SearchResult, title: str, out: Path) -> None:
    """Held-out Z residuals before and after, every campaign, and RMS per campaign, as a PNG.

    Parameters
    ----------
    campaigns, result, title
        See :func:`residuals_figure`.
    out : Path
        PNG path; parent folders are created.
    """
    plots.save_figure(residuals_figure(campaigns, result, title), out)


def write_outputs(
    out_dir: Path,
    doc: Mapping[str, Any],
    campaigns: Sequence,
    result: SearchResult,
    before: Localisation,
) -> list[Path]:
    """Write JSON, figures, localisation table and Markdown into ``out_dir``; return the files."""
    out_dir.mkdir(parents=True, exist_ok=True)
    data = "synthetic data" if doc["synthetic"] else "measured data"
    fit_png, res_png = out_dir / FIT_FIGURE, out_dir / RESIDUAL_FIGURE
    plot_heldout_fit(campaigns, result, f"Z drift on held-out campaigns ({data})", fit_png)
    plot_residuals(campaigns, result, f"Displacement residual before and after ({data})", res_png)
    table = out_dir / LOCALISATION_CSV
    before.table.to_csv(table, index=False, float_format="%.4g")
    json_path = out_dir / JSON_FILE
    json_path.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    md_path = out_dir / MARKDOWN_FILE
    md_path.write_text(markdown(doc, [str(fit_png), str(res_png)]), encoding="utf-8")
    logger.info("wrote %s, %s and figures to %s", JSON_FILE, MARKDOWN_FILE, out_dir)
    return [json_path, md_path, fit_png, res_png, table]


def log_mlflow(files: Sequence[Path], doc: Mapping[str, Any], settings: Mapping[str, Any]) -> str:
    """Log one MLflow run with the metrics, the named effects and the report files.

    Parameters
    ----------
    files : sequence of Path
        Report files, logged as artifacts under ``discrepancy/``.
    doc : mapping
        The ``discrepancy.json`` content.
    settings : mapping
        ``experiment``, ``default_tracking_uri``, ``local_artifact_dir`` of the discrepancy
        params section; ``$MLFLOW_TRACKING_URI`` wins over the default store.

    Returns
    -------
    str
        The run id.
    """
    from pipeline.tracking.location import (
        absolute_store_uri,
        local_artifact_location,
        resolve_tracking_uri,
    )
    from pipeline.tracking.store import ensure_experiment, make_client

    uri = absolute_store_uri(resolve_tracking_uri(settings))
    experiment = str(settings.get("experiment") or "thermal-discrepancy")
    client = make_client(uri)
    location = local_artifact_location(
        uri, str(settings.get("local_artifact_dir") or "mlartifacts"), experiment
    )
    experiment_id = ensure_experiment(client, experiment, location)
    tags = {
        "stage": "discrepancy",
        "status": str(doc.get("status", STATUS_TESTED)),
        "synthetic": str(bool(doc["synthetic"])).lower(),
        "named_effects": ",".join(doc["named_effects"]) or "none",
    }
    if doc.get("status") == STATUS_UNTESTABLE:
        tags["mlflow.note.content"] = f"Untestable: {doc['reason']}"
    run = client.create_run(experiment_id, tags=tags, run_name="discrepancy")
    run_id = run.info.run_id
    try:
        for key in ("rmse_um_before", "rmse_um_after", "rmse_T_K_before", "rmse_T_K_after"):
            if doc.get(key) is not None:
                client.log_metric(run_id, key, float(doc[key]))
        # the gap along the search: step 0 = baseline, step k = after the k-th named effect
        if doc.get("rmse_um_before") is not None:
            client.log_metric(run_id, "heldout_rmse_um", float(doc["rmse_um_before"]), step=0)
        for k, step in enumerate(doc.get("steps", []), start=1):
            client.log_metric(run_id, "heldout_rmse_um", float(step["rmse_um_after"]), step=k)
            for name, value in step["effect_parameters"].items():
                if value["value"] is not None:
                    client.log_param(run_id, f"{step['effect']}.{name}_{value['unit']}",
                                     value["value"])  # fmt: skip
        for cid, pair in doc.get("per_campaign", {}).items():  # held-out, per campaign
            for when in ("before", "after"):
                for key, name in (("z_um", "rmse_um"), ("t_k", "rmse_T_K")):
                    value = pair[when].get(key)
                    if value is not None and np.isfinite(value):
                        client.log_metric(run_id, f"{name}_{when}.{cid}", float(value))
        val = doc.get("validation") or {}
        for key in ("rmse_um_before", "rmse_um_after", "rmse_T_K_before", "rmse_T_K_after"):
            if val.get(key) is not None:  # the validation campaigns the search never saw
                client.log_metric(run_id, f"validation_{key}", float(val[key]))
        client.log_param(run_id, "named_effects", ",".join(doc["named_effects"]) or "none")
        for name, value in doc.get("thresholds", {}).items():
            client.log_param(run_id, name, str(value))
        client.log_param(run_id, "campaigns", ",".join(doc["campaigns"])[:500])
        for path in files:
            client.log_artifact(run_id, str(path), artifact_path="discrepancy")
    except BaseException:
        client.set_terminated(run_id, "FAILED")
        raise
    client.set_terminated(run_id)
    logger.info("logged MLflow run %s in experiment '%s'", run_id, experiment)
    return run_id

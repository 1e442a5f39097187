"""Write the discrepancy outputs: ``discrepancy.json``, ``discrepancy.md``, figures.

The report states, in an engineer's words (:mod:`pipeline.discrepancy.report_text`), where the
calibrated baseline twin disagrees with the measurements (:mod:`pipeline.discrepancy.localise`),
which effects the forward search named (:mod:`pipeline.discrepancy.search`), with what evidence,
and how far the held-out displacement residual shrinks. Figures are built and saved with the
helpers of :mod:`pipeline.plots` (Agg canvas, no pyplot). The MLflow run is logged by
:mod:`pipeline.tracking.discrepancy_run`.
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
from pipeline.discrepancy.report_text import markdown, untestable_markdown
from pipeline.discrepancy.search import SearchResult, SearchSettings
from pipeline.fit_statistics import root_mean_square

logger = logging.getLogger(__name__)

JSON_FILE = "discrepancy.json"
MARKDOWN_FILE = "discrepancy.md"
FIT_FIGURE = "heldout_fit.png"
RESIDUAL_FIGURE = "residuals.png"
LOCALISATION_CSV = "localisation.csv"

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


def _write_document(out_dir: Path, doc: Mapping[str, Any], report: str) -> list[Path]:
    """Write ``doc`` as ``discrepancy.json`` and ``report`` as ``discrepancy.md``; return both."""
    json_path = out_dir / JSON_FILE
    json_path.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    md_path = out_dir / MARKDOWN_FILE
    md_path.write_text(report, encoding="utf-8")
    return [json_path, md_path]


def write_untestable(out_dir: Path, doc: Mapping[str, Any]) -> list[Path]:
    """Write ``discrepancy.json`` and ``discrepancy.md`` of an untestable folder."""
    out_dir.mkdir(parents=True, exist_ok=True)
    for stale in (FIT_FIGURE, RESIDUAL_FIGURE, LOCALISATION_CSV):
        (out_dir / stale).unlink(missing_ok=True)
    return _write_document(out_dir, doc, untestable_markdown(doc))


def build_document(
    result: SearchResult,
    before: Localisation,
    after: Localisation | None,
    settings: SearchSettings,
    *,
    synthetic: bool,
    campaign_ids: Sequence[str],
    quarantined: Sequence[str] = (),
    identifiability: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Assemble the content of ``discrepancy.json``.

    Fields: ``status`` (``tested``), ``named_effects``, ``suspects`` (effects that passed but were
    held back, with the reason), ``rmse_um_before``, ``rmse_um_after`` (held-out Z RMS, um),
    ``rmse_T_K_before/after``, ``per_campaign``, ``steps`` (effect, evidence, RMS before/after,
    calibrated parameters with units), ``candidates_by_step`` (evidence of every candidate at every
    step), ``untestable`` (effect -> missing roles), ``baseline_parameters`` and
    ``final_parameters`` (calibrated on every searched campaign), ``folds`` (held-out campaigns of
    each fold), ``seconds`` (the search's wall time), ``localisation`` (findings, ambient lag,
    before and after), ``thresholds``, ``campaigns``, ``quarantined``, ``synthetic``, ``validation``
    (the named effects checked on the validation campaigns held back from the search, or None), and
    last, when given, ``identifiability`` (effect -> its class and figures,
    :meth:`pipeline.discrepancy.identifiability.EffectIdentifiability.to_dict`).
    """
    doc = {"status": STATUS_TESTED, **result.to_dict()}
    doc["localisation"] = {"before": _localisation_fields(before)}
    if after is not None:
        doc["localisation"]["after"] = _localisation_fields(after)
    doc["thresholds"] = {
        "min_heldout_reduction": settings.min_heldout_reduction,
        "min_heldout_temperature_reduction": settings.min_heldout_t_reduction,
        "max_delta_bic": settings.max_delta_bic,
        "n_folds": settings.n_folds,
    }
    doc["campaigns"] = list(campaign_ids)
    doc["quarantined"] = list(quarantined)
    doc["synthetic"] = bool(synthetic)
    if identifiability is not None:
        doc["identifiability"] = dict(identifiability)
    return doc


def _localisation_fields(localisation: Localisation) -> dict[str, Any]:
    """Return the findings, the ambient correlation and its lag (min) of a localisation."""
    return {
        "findings": localisation.findings,
        "ambient_correlation": _num(localisation.ambient_correlation),
        "ambient_lag_min": _num(localisation.ambient_lag_min),
    }


def _num(x: float) -> float | None:
    """Return ``x`` rounded to 4 decimals, or None when not finite (JSON has no NaN)."""
    x = float(x)
    return round(x, 4) if np.isfinite(x) else None


def _prediction(campaign, residual: np.ndarray) -> np.ndarray:
    return np.asarray(campaign.z_um, dtype=float) - np.asarray(residual, dtype=float)


def _heldout_residuals(campaigns: Sequence, result: SearchResult) -> tuple[dict, dict, dict]:
    """Return the held-out Z residuals (um) of the baseline and final twin, and the campaigns.

    Each of the three is a dict keyed by campaign id.
    """
    by_id = {c.campaign_id: c for c in campaigns}
    return result.baseline.heldout.z_residual_um, result.final.heldout.z_residual_um, by_id


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
    base, final, by_id = _heldout_residuals(campaigns, result)
    ranked = sorted(base, key=lambda c: -root_mean_square(base[c]))[:max_panels]
    fig = plots.new_figure(1.6 + 3.6 * max(len(ranked), 1), 4.6)
    axes = fig.subplots(1, max(len(ranked), 1), squeeze=False)
    label = "twin + " + ", ".join(result.named_effects) if result.named_effects else "twin (same)"
    speed_handles: list = []
    for ax, cid in zip(axes[0], ranked, strict=False):
        c = by_id[cid]
        minutes = np.asarray(c.t_s, dtype=float) / 60.0
        speed = ax.twinx()
        speed_handles = speed.step(
            minutes, c.rpm, where="post", color="0.65", lw=0.9, label="spindle speed (right axis)"
        )
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
        fig.legend(
            [*handles, *speed_handles],
            [*names, "spindle speed (right axis)"],
            loc="outside lower center",
            ncols=4,
            fontsize=9,
        )
    fig.suptitle(plots.wrap_text(fig, title, plots.TITLE_FONTSIZE), fontsize=plots.TITLE_FONTSIZE)
    return fig


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
    before, after, by_id = _heldout_residuals(campaigns, result)
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
                minutes = np.asarray(by_id[cid].t_s) / 60.0
                ax.plot(minutes, series[cid], lw=1, color=colour, label=names[cid])
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(plots.wrap_text(fig, f"held-out residual, {name}", 10.5, 5.0), fontsize=10.5)
        ax.set(xlabel="elapsed time (min)", ylabel="measured - twin Z (um)", ylim=(-lim, lim))
    handles, labels = axes["before"].get_legend_handles_labels()
    named = "campaign (season)" if any(seasons.values()) else "campaign"
    fig.legend(
        handles, labels, loc="outside right upper", fontsize=8, title=named, title_fontsize=8
    )
    rms_b = [root_mean_square(before[c]) for c in ids]
    rms_a = [root_mean_square(after[c]) if c in after else np.nan for c in ids]
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
    fit_title = f"Z drift on held-out campaigns ({data})"
    plots.save_figure(heldout_fit_figure(campaigns, result, fit_title), fit_png)
    residual_title = f"Displacement residual before and after ({data})"
    plots.save_figure(residuals_figure(campaigns, result, residual_title), res_png)
    table = out_dir / LOCALISATION_CSV
    before.table.to_csv(table, index=False, float_format="%.4g")
    written = _write_document(out_dir, doc, markdown(doc, [str(fit_png), str(res_png)]))
    logger.info("wrote %s, %s and figures to %s", JSON_FILE, MARKDOWN_FILE, out_dir)
    return [*written, fit_png, res_png, table]

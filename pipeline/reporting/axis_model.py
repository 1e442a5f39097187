"""The figure of the linear-axis composite model: measured vs modelled error, and residuals.

Written by the ``model_axis`` stage to ``reports/axis_model/<machine>.png``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402


def plot(points: pd.DataFrame, report: dict, out: Path) -> None:
    """Measured vs composite error per pass, and the residuals, of each scored campaign.

    Validation campaigns are drawn when there are any, else the training campaigns (fit).

    Parameters
    ----------
    points : DataFrame
        Scored points with ``role`` (see :func:`pipeline.models.axis_fit.build`).
    report : dict
        The report (title, status, patent band).
    out : Path
        PNG path; parent folders are created.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    if points.empty:
        fig, ax = plt.subplots(figsize=(7, 2.5))
        ax.axis("off")
        ax.text(0.5, 0.5, report["message"], ha="center", va="center", wrap=True)
        fig.savefig(out, dpi=110)
        plt.close(fig)
        return
    role = "validation" if (points["role"] == "validation").any() else "fit"
    shown = points[points["role"] == role]
    campaigns = sorted(pd.unique(shown["campaign_id"]))
    fig, axes = plt.subplots(2, len(campaigns), figsize=(7 * len(campaigns), 8), squeeze=False)
    band = report["patent_band_um"]
    for column, campaign_id in enumerate(campaigns):
        rows = shown[shown["campaign_id"] == campaign_id]
        _draw_campaign(axes[0, column], axes[1, column], rows, band)
        axes[0, column].set_title(f"{campaign_id} ({role}): measured (o) and composite (-)")
        axes[1, column].set_title(f"{campaign_id}: residual = measured - composite")
    kind = "SYNTHETIC data" if report.get("synthetic") else "measured data"
    fig.suptitle(
        f"Linear-axis composite model E = P_geo(x) + (k(T) - k0) x ({kind})\n"
        f"{report['slope_model']['equation']}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def _draw_campaign(top: plt.Axes, bottom: plt.Axes, rows: pd.DataFrame, band: float) -> None:
    colours = plt.cm.plasma(np.linspace(0, 0.85, rows["elapsed_min"].nunique()))
    for colour, (minute, group) in zip(colours, rows.groupby("elapsed_min"), strict=True):
        top.plot(group["target_mm"], group["measured_um"], "o", ms=3, color=colour)
        top.plot(
            group["target_mm"], group["predicted_um"], "-", color=colour, label=f"{minute:g} min"
        )
        bottom.plot(
            group["target_mm"],
            group["residual_um"],
            "o-",
            ms=3,
            color=colour,
            label=f"{minute:g} min",
        )
    for level in (-band, band):
        bottom.axhline(level, color="k", ls="--", lw=1)
    bottom.text(rows["target_mm"].min(), band, f" patent: +-{band:g} um", va="bottom", fontsize=7)
    top.set(xlabel="position (mm)", ylabel="positioning error (um)")
    bottom.set(xlabel="position (mm)", ylabel="residual (um)")
    top.legend(fontsize=7)
    bottom.legend(fontsize=7)

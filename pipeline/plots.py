"""Figures written by the stages (matplotlib, non-interactive Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402


def score_heatmaps(matrices: dict[str, pd.DataFrame], title: str, out: Path) -> None:
    """Draw train x test score matrices side by side and save them as a PNG.

    Parameters
    ----------
    matrices : dict of str to DataFrame
        Panel title -> matrix (rows: training campaign, columns: test campaign), um.
    title : str
        Figure title (says whether the data are synthetic).
    out : Path
        PNG path; parent folders are created.
    """
    fig, axes = plt.subplots(1, len(matrices), figsize=(7.5 * len(matrices), 6), squeeze=False)
    for ax, (name, matrix) in zip(axes[0], matrices.items(), strict=True):
        values = matrix.to_numpy(dtype=float)
        image = ax.imshow(values, cmap="viridis_r", aspect="auto")
        ax.set_xticks(range(matrix.shape[1]), matrix.columns, rotation=90, fontsize=7)
        ax.set_yticks(range(matrix.shape[0]), matrix.index, fontsize=7)
        ax.set_xlabel("applied to campaign")
        ax.set_ylabel("built on campaign")
        ax.set_title(name)
        middle = np.nanmean([np.nanmin(values), np.nanmax(values)])
        for (i, j), value in np.ndenumerate(values):
            if np.isfinite(value):
                colour = "w" if value > middle else "k"
                ax.text(j, i, f"{value:.1f}", ha="center", va="center", fontsize=5, color=colour)
        fig.colorbar(image, ax=ax, label="um")
    fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def axis_separation(
    passes: pd.DataFrame, geometric: pd.DataFrame, campaign_id: str, title: str, out: Path
) -> None:
    """Plot measured, geometric and thermal positioning error of one axis campaign.

    Parameters
    ----------
    passes : DataFrame
        Rows of ``axis_thermal_error`` for the campaign: ``elapsed_min``, ``target_mm``,
        ``measured_um``, ``geometric_um``, ``thermal_um``, ``thermal_fit_um``.
    geometric : DataFrame
        Dense curve of the fitted geometric polynomial: ``target_mm``, ``geometric_um``.
    campaign_id : str
    title : str
        Suffix of the figure title (e.g. "synthetic data").
    out : Path
        PNG path.
    """
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5))
    colours = plt.cm.plasma(np.linspace(0, 0.85, passes["elapsed_min"].nunique()))
    for colour, (minute, rows) in zip(colours, passes.groupby("elapsed_min"), strict=True):
        left.plot(rows["target_mm"], rows["measured_um"], "o-", ms=3, color=colour,
                  label=f"{minute:g} min")  # fmt: skip
        right.plot(rows["target_mm"], rows["thermal_um"], "o", ms=3, color=colour)
        right.plot(rows["target_mm"], rows["thermal_fit_um"], "-", color=colour,
                   label=f"{minute:g} min")  # fmt: skip
    left.plot(geometric["target_mm"], geometric["geometric_um"], "k--", lw=2,
              label="geometric (polynomial fit of the cold pass)")  # fmt: skip
    left.set(xlabel="position (mm)", ylabel="positioning error (um)",
             title="measured (bidirectional mean) and geometric part")  # fmt: skip
    right.set(xlabel="position (mm)", ylabel="thermal error (um)",
              title="thermal part = measured - geometric, with first-order fit")  # fmt: skip
    left.legend(fontsize=7)
    right.legend(fontsize=7)
    fig.suptitle(f"{campaign_id}: geometric / thermal separation ({title})")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def selection_stability(stability: pd.DataFrame, title: str, out: Path) -> None:
    """Heat-map of how often each method chose each sensor across the training campaigns.

    Parameters
    ----------
    stability : DataFrame
        ``method``, ``sensor``, ``frequency`` (0-1), ``times_chosen``, ``n_campaigns``.
    title : str
        Figure title (says whether the data are synthetic).
    out : Path
        PNG path; parent folders are created.
    """
    table = stability.pivot_table(index="method", columns="sensor", values="frequency")
    counts = stability.pivot_table(index="method", columns="sensor", values="times_chosen")
    fig, ax = plt.subplots(figsize=(1.0 + 0.7 * max(table.shape[1], 1), 1.5 + 0.5 * len(table)))
    image = ax.imshow(table.to_numpy(dtype=float), cmap="Blues", vmin=0, vmax=1, aspect="auto")
    ax.set_xticks(range(table.shape[1]), table.columns)
    ax.set_yticks(range(table.shape[0]), table.index)
    for (i, j), value in np.ndenumerate(counts.to_numpy(dtype=float)):
        if np.isfinite(value):
            ax.text(j, i, f"{int(value)}", ha="center", va="center", fontsize=8)
    fig.colorbar(image, ax=ax, label="share of training campaigns")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def predicted_vs_measured(
    panels: dict[str, pd.DataFrame], labels: tuple[str, str], title: str, out: Path
) -> None:
    """Measured thermal error and two models' predictions, one panel per campaign.

    Parameters
    ----------
    panels : dict of str to DataFrame
        Campaign id -> ``elapsed_min``, ``measured_um``, ``first_um``, ``second_um``.
    labels : tuple of str
        Legend labels of ``first_um`` and ``second_um``.
    title : str
    out : Path
        PNG path; parent folders are created.
    """
    n = max(len(panels), 1)
    columns = min(n, 3)
    rows = -(-n // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(5 * columns, 3.2 * rows), squeeze=False)
    for ax, (campaign, frame) in zip(axes.flat, panels.items(), strict=False):
        ax.plot(frame["elapsed_min"], frame["measured_um"], "k.", ms=3, label="measured")
        ax.plot(frame["elapsed_min"], frame["first_um"], "-", label=labels[0])
        ax.plot(frame["elapsed_min"], frame["second_um"], "--", label=labels[1])
        ax.set_title(campaign)
        ax.set_xlabel("time (min)")
        ax.set_ylabel("thermal error (um)")
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)

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

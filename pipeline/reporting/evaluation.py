"""The figures and report sections of the ``evaluate`` stage.

One heat-map per candidate of its cross-campaign scores (``reports/matrices``), the held-out
predictions of the best model and the best plain baseline against the measurement
(``reports/comparison``), each axis' section of ``reports/model_comparison.md`` and its rows of
the DVC plot tables.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline import paths, plots
from pipeline.machines import MACHINE_COLUMN, axis_label, machine_key
from pipeline.protocol.evaluation import CANDIDATE, AxisComparison, AxisEvaluation, label
from pipeline.protocol.scoring import score_matrix
from pipeline.protocol.units import CampaignSeries
from pipeline.reporting import comparison as comparison_report


def prediction_panels(series: list[CampaignSeries], comparison: AxisComparison) -> dict:
    """Measured and predicted error of held-out campaigns, per campaign (um).

    The validation campaigns when there are any, else the training campaigns, each predicted by
    the protocol fit that left it out (the comparison's held-out tables); ``second_um`` is NaN
    where the plain baseline has no such fit.
    """
    validation = [s.campaign_id for s in series if s.split == "validation"]
    shown = validation or [s.campaign_id for s in series if s.split == "train"]
    plain = dict(tuple(comparison.plain_heldout.groupby("campaign_id", sort=False)))
    panels = {}
    for campaign, first in comparison.best_heldout.groupby("campaign_id", sort=False):
        if campaign not in shown:
            continue
        second = plain.get(campaign)
        panels[campaign] = pd.DataFrame(
            {
                "elapsed_min": first["elapsed_s"].to_numpy() / 60.0,
                "measured_um": first["measured_um"].to_numpy(),
                "first_um": first["predicted_um"].to_numpy(),
                "second_um": np.nan if second is None else second["predicted_um"].to_numpy(),
            }
        )
    return panels


def write_matrices(scores: pd.DataFrame, title_suffix: str) -> list[str]:
    """Matrices CSV (every axis and candidate, both scores) and one heat-map per candidate.

    Each heat-map shows the RMS of the residual (um) of the candidate built on each training
    unit (rows) and applied to each campaign (columns, labelled with their season; training
    campaigns, then the validation ones), the fits on a unit's own campaigns outlined.

    Parameters
    ----------
    scores : DataFrame
        The long score table (``reports/cross_season_scores.csv``): ``machine``, ``axis``,
        ``model``,
        ``selection``, ``mode``, ``scheme``, ``train_unit``, ``test_campaign``, ``test_split``,
        ``test_season``, ``role``, ``resid_std_um`` and ``rmse_um`` (um).
    title_suffix : str
        Says whether the data are synthetic; ends the heat-maps' titles.

    Returns
    -------
    list of str
        Heat-map paths relative to ``reports/``.
    """
    cross = scores[scores["scheme"] != "pooled"]
    frames, figures = [], []
    paths.MATRICES.mkdir(parents=True, exist_ok=True)
    for path in paths.MATRICES.glob("*.png"):
        path.unlink()
    keys_all = [MACHINE_COLUMN, "axis", *CANDIDATE]
    for keys, group in cross.groupby(keys_all, sort=True):
        for column in ("resid_std_um", "rmse_um"):
            matrix = score_matrix(group, column)
            matrix.index = pd.MultiIndex.from_tuples(
                [(*keys, column, unit) for unit in matrix.index],
                names=[*keys_all, "score", "train_unit"],
            )
            frames.append(matrix)
        out = paths.MATRICES / f"{'__'.join([machine_key(keys[0]), *keys[1:]])}.png"
        campaigns = group.drop_duplicates("test_campaign")
        in_sample = group.assign(fit=(group["role"] == "fit").astype(float))
        figure = plots.score_heatmap_figure(
            {"RMS of the residual (um)": score_matrix(group, "rmse_um")},
            f"Machine {keys[0]}, axis {keys[1]}, candidate {' / '.join(keys[2:])}: built on each "
            "training unit, "
            f"applied to every campaign ({title_suffix})",
            seasons=dict(zip(campaigns["test_campaign"], campaigns["test_season"], strict=True)),
            validation=set(campaigns.loc[campaigns["test_split"] == "validation", "test_campaign"]),
            in_sample=score_matrix(in_sample, "fit") > 0,
        )
        plots.save_figure(figure, out)
        figures.append(out.relative_to(paths.REPORTS).as_posix())
    matrix = pd.concat(frames) if frames else pd.DataFrame(columns=[*keys_all, "score"])
    matrix.to_csv(paths.MATRIX_CSV, float_format="%.4f")
    return figures


@dataclass(frozen=True)
class AxisReport:
    """What one axis adds to the report and the DVC plot tables."""

    section: str
    plot_rows: list[dict]
    predictions: list[pd.DataFrame]


def report_axis(
    machine: str,
    item: AxisEvaluation,
    comparison: AxisComparison,
    summary: pd.DataFrame,
    card: dict,
    selected: dict,
    separation: dict,
    heatmaps: list[str],
    origin: str,
    twin_text: str,
) -> AxisReport:
    """One axis' report section, its held-out figure and its rows of the DVC plot tables.

    Formats what the protocol computed for one axis of ``machine``: the evaluation (``item``,
    champion decided) and its comparison of the best model with the plain baseline
    (``comparison``); ``summary``, ``selected`` and ``separation`` are the machine's.
    """
    name = axis_label(machine, item.axis)
    rows = summary[summary["axis"] == item.axis]
    decision = item.decision
    first, second = comparison.best, comparison.plain
    panels = prediction_panels(item.series, comparison)
    figure = paths.COMPARISON_FIGURES / f"heldout_{name}.png"
    labels = (
        f"best model: {label(first)}",
        "no plain baseline" if second is None else f"plain: {label(second)}",
    )
    where = (
        "validation campaigns, built on all training campaigns"
        if any(s.split == "validation" for s in item.series)
        else "each training campaign, predicted by the fit that left it out"
    )
    seasons = {s.campaign_id: s.season for s in item.series}
    title = f"Machine {machine}, axis {item.axis}: {where} ({origin})"
    plots.save_figure(plots.predicted_vs_measured_figure(panels, labels, title, seasons), figure)
    context = comparison_report.AxisContext(
        machine,
        item.axis,
        rows,
        decision,
        card,
        selected["axes"][item.axis],
        item.series,
        item.skipped,
        second,
        comparison.groups,
        {key: counts.text() for key, counts in item.warnings.items()},
    )
    figures = comparison_report.AxisFigures(
        figure.relative_to(paths.REPORTS).as_posix(),
        labels,
        [h for h in heatmaps if h.startswith(f"matrices/{machine_key(machine)}__{item.axis}__")],
    )
    plot_rows = [
        {
            MACHINE_COLUMN: machine,
            "axis": item.axis,
            "candidate": f"{machine} {item.axis}: {label(row)}",
            "heldout_rms_um": row.get(decision.column) if decision.column else np.nan,
            "eta": row.get(f"{item.protocol}_eta") if item.protocol else np.nan,
        }
        for _, row in rows.iterrows()
    ]
    predictions = [
        frame.rename(columns={"first_um": "predicted_um"})
        .drop(columns="second_um")
        .assign(machine=machine, axis=item.axis, campaign_id=campaign)
        for campaign, frame in panels.items()
    ]
    section = comparison_report.axis_section(context, separation, figures, twin_text)
    return AxisReport(section, plot_rows, predictions)

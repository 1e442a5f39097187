"""Every figure the pipeline writes reads as a picture: text inside, axes labelled, seasons named.

Each figure function is rendered from small synthetic inputs into ``tmp_path``; the checks are
those of the review: no text clipped at the figure's edges (every drawn text artist's extent
inside the figure, 1 px allowed), an axis label with its unit on every axis, and every campaign
of a heat-map named with its season.
"""

import logging
import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from pipeline import paths, plots
from pipeline.discrepancy import report
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.reporting.evaluation import write_matrices

SEASONS = ("winter", "spring", "summer", "autumn")
TRAIN = [f"K{i:02d}" for i in range(1, 13)]
VALIDATION = [f"V{i:02d}" for i in range(1, 7)]
SEASON_OF = {
    **{c: SEASONS[i // 3] for i, c in enumerate(TRAIN)},
    **{c: SEASONS[(3 + i // 3) % 4] for i, c in enumerate(VALIDATION)},
}
UNITS = [*TRAIN, *(f"not_{s}" for s in SEASONS), "all_training"]
UNIT = re.compile(r"\((um|mm|min|rpm|0-1)\)")


def saved(fig, path):
    """Save like the stages do; the PNG exists and no text leaves the figure."""
    plots.save_figure(fig, path)
    assert path.is_file() and path.stat().st_size > 10_000
    assert plots.text_outside_figure(fig) == []
    return fig


def labels_of(fig):
    """Return (xlabel, ylabel) of every visible axes, the x label of twins taken from their twin.

    Colour bars have only their long (y) axis labelled, twins share their x axis.
    """
    found = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        xlabel = ax.get_xlabel()
        if ax.get_label() == "<colorbar>":
            xlabel = None
        elif not xlabel:
            xlabel = next(
                (o.get_xlabel() for o in ax.get_shared_x_axes().get_siblings(ax) if o is not ax),
                "",
            )
        found.append((xlabel, ax.get_ylabel()))
        assert ax.get_ylabel().strip(), f"axes without y label: {ax}"
        assert xlabel is None or xlabel.strip(), f"axes without x label: {ax}"
    return found


def no_overlap(fig, labels):
    """Neighbouring tick labels do not run into each other (horizontally)."""
    renderer = fig.canvas.get_renderer()
    boxes = sorted((t.get_window_extent(renderer) for t in labels), key=lambda b: b.x0)
    for left, right in zip(boxes, boxes[1:], strict=False):
        assert left.x1 <= right.x0 + 1, (left, right)


def score_matrix_18x17(seed=0):
    rng = np.random.default_rng(seed)
    values = rng.uniform(0.1, 40.0, (len(UNITS), len(TRAIN) + len(VALIDATION)))
    values[3, 5] = np.nan
    values[0, 0] = 0.127
    values[1, 1] = 123.4
    return pd.DataFrame(values, index=UNITS, columns=[*TRAIN, *VALIDATION])


def in_sample_of(matrix):
    inside = pd.DataFrame(False, index=matrix.index, columns=matrix.columns)
    for unit in matrix.index:
        if unit in TRAIN:
            inside.loc[unit, unit] = True
        elif unit.startswith("not_"):
            inside.loc[unit, [c for c in TRAIN if SEASON_OF[c] != unit[4:]]] = True
        else:
            inside.loc[unit, TRAIN] = True
    return inside


def test_heatmap_reads_18_columns_by_17_rows(tmp_path):
    matrix = score_matrix_18x17()
    title = (
        "Axis Z, candidate pls_dl / gra_top_k / static: built on each training unit, applied "
        "to every campaign (SYNTHETIC data from the physical twin)"
    )
    fig = plots.score_heatmap_figure(
        {"RMS of the residual (um)": matrix}, title, SEASON_OF, VALIDATION, in_sample_of(matrix)
    )
    saved(fig, tmp_path / "heatmap.png")
    assert 10.0 <= fig.get_figwidth() <= 12.0 and fig.dpi == 100
    ax, colorbar = fig.axes
    assert ax.get_xlabel() == "test campaign (season)"
    assert ax.get_ylabel() == "model built on (training unit)"
    assert colorbar.get_ylabel() == "RMS of the residual (um)"
    assert UNIT.search(colorbar.get_ylabel())
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    assert ticks == [f"{c}\n{SEASON_OF[c]}" for c in matrix.columns]
    rows = [t.get_text() for t in ax.get_yticklabels()]
    assert rows[0] == "K01 (winter)" and rows[-1] == "all_training"
    no_overlap(fig, ax.get_xticklabels())
    # the split: a vertical line between the last training and the first validation campaign
    assert any(list(line.get_xdata()) == [len(TRAIN) - 0.5] * 2 for line in ax.get_lines()), (
        "no separator before the validation campaigns"
    )
    top = [t.get_text() for t in ax.child_axes[0].get_xticklabels()]
    assert top == ["training campaigns", "validation campaigns"]
    # every finite cell is written, legibly, in a colour that contrasts with the cell
    cells = [t for t in ax.texts]
    assert len(cells) == np.isfinite(matrix.to_numpy()).sum()
    assert min(t.get_fontsize() for t in cells) >= 6
    assert {t.get_text() for t in cells} >= {"0.13", "123"}
    assert {t.get_color() for t in cells} == {"k", "w"}
    # the fits are outlined, the suptitle is wrapped, not cut
    assert len(ax.patches) == in_sample_of(matrix).to_numpy().sum()
    assert "\n" in fig.get_suptitle()
    assert fig.get_suptitle().replace("\n", " ") == title


def test_heatmap_without_seasons_or_validation_still_fits(tmp_path):
    matrix = score_matrix_18x17().loc[TRAIN[:4], TRAIN[:4]]
    fig = saved(plots.score_heatmap_figure({"RMS (um)": matrix}, "short"), tmp_path / "h.png")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "test campaign" and not ax.child_axes
    assert [t.get_text() for t in ax.get_xticklabels()] == TRAIN[:4]


def test_write_matrices_passes_seasons_split_and_fits(tmp_path, monkeypatch):
    monkeypatch.setattr(paths, "REPORTS", tmp_path)
    monkeypatch.setattr(paths, "MATRICES", tmp_path / "matrices")
    monkeypatch.setattr(paths, "MATRIX_CSV", tmp_path / "matrix.csv")
    campaigns = [*TRAIN[:3], VALIDATION[0]]
    rows = [
        {
            "machine": "vmc 450",
            "axis": "Z",
            "model": "mlr",
            "selection": "all",
            "mode": "static",
            "scheme": "campaign",
            "train_unit": unit,
            "test_campaign": test,
            "test_season": SEASON_OF[test],
            "test_split": "validation" if test in VALIDATION else "train",
            "role": "fit" if unit == test else "validation" if test in VALIDATION else "prediction",
            "rmse_um": 1.0 + i,
            "resid_std_um": 0.5,
        }
        for i, (unit, test) in enumerate((u, t) for u in TRAIN[:3] for t in campaigns)
    ]
    drawn = {}
    real = plots.score_heatmap_figure

    def keep(*args, **kwargs):
        drawn["fig"] = real(*args, **kwargs)
        return drawn["fig"]

    monkeypatch.setattr(plots, "score_heatmap_figure", keep)
    figures = write_matrices(pd.DataFrame(rows), "synthetic data")
    assert figures == ["matrices/vmc-450__Z__mlr__all__static.png"]
    assert (tmp_path / figures[0]).is_file()
    ax = drawn["fig"].axes[0]
    ticks = [t.get_text() for t in ax.get_xticklabels()]
    assert ticks == ["K01\nwinter", "K02\nwinter", "K03\nwinter", "V01\nautumn"]
    assert len(ax.patches) == 3  # the diagonal fits
    assert any(list(line.get_xdata()) == [2.5, 2.5] for line in ax.get_lines())
    assert plots.text_outside_figure(drawn["fig"]) == []


def passes_table():
    rows = []
    for minute in (0, 20, 50, 110, 190, 340, 390):
        for target in range(0, 290, 10):
            thermal = 0.07 * minute**0.5 * target / 10
            rows.append(
                {
                    "elapsed_min": minute,
                    "target_mm": target,
                    "thermal_um": thermal,
                    "measured_um": thermal + np.sin(target / 40),
                    "geometric_um": 0.0,
                    "thermal_fit_um": thermal,
                }
            )
    return pd.DataFrame(rows)


def test_axis_separation_labels_and_fits(tmp_path):
    geometric = pd.DataFrame({"target_mm": np.linspace(0, 280, 50), "geometric_um": 0.0})
    fig = plots.axis_separation_figure(passes_table(), geometric, "Y01", "SYNTHETIC data")
    saved(fig, tmp_path / "Y01.png")
    assert labels_of(fig) == [
        ("position (mm)", "positioning error (um)"),
        ("position (mm)", "thermal error (um)"),
    ]
    assert fig.get_figwidth() <= plots.MAX_WIDTH_IN


def test_selection_stability_labels_rotated_inputs_and_fits(tmp_path):
    inputs = [f"T{i}" for i in range(1, 11)] + [
        f"speed{a}_lag_{t}min" for a in ("", "2") for t in (10, 30, 90, 270)
    ]
    methods = ["all", "all_speed", "best_subset", "correlation_grouping", "fc_grd", "gra_top_k"]
    rng = np.random.default_rng(1)
    chosen = rng.integers(0, 13, (len(methods), len(inputs)))
    stability = pd.DataFrame(
        [
            {
                "method": m,
                "sensor": s,
                "times_chosen": int(chosen[i, j]),
                "n_campaigns": 12,
                "frequency": chosen[i, j] / 12,
            }
            for i, m in enumerate(methods)
            for j, s in enumerate(inputs)
        ]
    )
    title = (
        "Axis Z: how often each input is chosen, across the training campaigns (SYNTHETIC data "
        "from the physical twin)"
    )
    fig = saved(plots.selection_stability_figure(stability, title), tmp_path / "stability.png")
    ax = fig.axes[0]
    assert labels_of(fig) == [
        ("model input (temperature sensor or speed response)", "selection method"),
        (None, "share of training campaigns (0-1)"),
    ]
    assert [t.get_text() for t in ax.get_xticklabels()][:3] == ["T1", "T2", "T3"]
    assert ax.get_xticklabels()[0].get_rotation() == 45


@pytest.mark.parametrize("n_panels", [0, 1, 6])
def test_predicted_vs_measured_labels_and_fits(tmp_path, n_panels):
    minutes = np.arange(0, 330, 3.0)
    panels = {
        c: pd.DataFrame(
            {
                "elapsed_min": minutes,
                "measured_um": -np.sqrt(minutes),
                "first_um": -np.sqrt(minutes) + 1,
                "second_um": -np.sqrt(minutes) - 1,
            }
        )
        for c in VALIDATION[:n_panels]
    }
    labels = ("best model: pls_dl/gra_top_k/static", "plain: ridge/all/static")
    title = (
        "Axis Z: validation campaigns, built on all training campaigns (SYNTHETIC data from "
        "the physical twin)"
    )
    fig = plots.predicted_vs_measured_figure(panels, labels, title, seasons=SEASON_OF)
    saved(fig, tmp_path / "heldout.png")
    assert fig.get_figwidth() <= plots.MAX_WIDTH_IN
    assert labels_of(fig) == [("elapsed time (min)", "thermal error (um)")] * n_panels
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible() and ax.axison]
    assert titles == [f"{c} ({SEASON_OF[c]})" for c in VALIDATION[:n_panels]]
    if n_panels:
        assert [t.get_text() for t in fig.legends[0].get_texts()] == ["measured", *labels]


def discrepancy_inputs(n=12):
    t_s = np.arange(0, 330 * 60, 180.0)
    rpm = np.where(t_s < 270 * 60, 2000.0, 0.0)
    ids = TRAIN[:n]
    campaigns = [
        MeasuredCampaign(
            cid,
            t_s,
            rpm,
            pd.DataFrame({"T1": 20.0 + t_s / 3600}),
            {"T1": "other"},
            -np.sqrt(t_s / 60) * (1 + k / 10),
            season=SEASON_OF[cid],
            split="train",
        )
        for k, cid in enumerate(ids)
    ]
    rng = np.random.default_rng(2)
    before = {c: rng.normal(0, 1 + k / 4, t_s.size) for k, c in enumerate(ids)}
    after = {c: 0.5 * r for c, r in before.items()}
    result = SimpleNamespace(
        named_effects=["motor_heat"],
        baseline=SimpleNamespace(heldout=SimpleNamespace(z_residual_um=before)),
        final=SimpleNamespace(heldout=SimpleNamespace(z_residual_um=after)),
    )
    return campaigns, result


def test_discrepancy_heldout_fit_labels_seasons_and_fits(tmp_path):
    campaigns, result = discrepancy_inputs()
    fig = report.heldout_fit_figure(campaigns, result, "Z drift on held-out campaigns (synthetic)")
    saved(fig, tmp_path / "heldout_fit.png")
    labels = labels_of(fig)
    assert labels.count(("elapsed time (min)", "Z drift (um)")) == 3
    assert labels.count(("elapsed time (min)", "spindle speed (rpm)")) == 3
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles and all(re.search(r"K\d\d \((winter|spring|summer|autumn)\)", t) for t in titles)


@pytest.mark.parametrize("n_campaigns", [3, 12, 24])
def test_discrepancy_residuals_labels_seasons_and_fits(tmp_path, n_campaigns):
    campaigns, result = discrepancy_inputs(min(n_campaigns, 12))
    if n_campaigns > 12:  # more campaigns than the demo: the tick labels must still fit
        extra = [
            MeasuredCampaign(
                f"X{k:02d}", c.t_s, c.rpm, c.temperatures, c.roles, c.z_um, season=c.season
            )
            for k, c in enumerate(campaigns)
        ]
        campaigns = [*campaigns, *extra]
        for c in extra:
            result.baseline.heldout.z_residual_um[c.campaign_id] = np.ones(c.t_s.size)
            result.final.heldout.z_residual_um[c.campaign_id] = np.ones(c.t_s.size)
    fig = report.residuals_figure(campaigns, result, "Displacement residual (synthetic data)")
    saved(fig, tmp_path / "residuals.png")
    assert labels_of(fig) == [
        ("elapsed time (min)", "measured - twin Z (um)"),
        ("elapsed time (min)", "measured - twin Z (um)"),
        ("held-out campaign (season)", "held-out Z RMS (um)"),
    ]
    bars = fig.axes[2]
    ticks = [t.get_text() for t in bars.get_xticklabels()]
    season = {c.campaign_id: c.season for c in campaigns}
    separator = "\n" if n_campaigns <= 12 else " "  # upright on one line when they do not fit
    assert ticks == [f"{c}{separator}{season[c]}" for c in sorted(season)]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == [f"{c} ({season[c]})" for c in sorted(season)]
    if bars.get_xticklabels()[0].get_rotation() == 0:
        no_overlap(fig, bars.get_xticklabels())


def test_the_check_finds_clipped_text_and_wrapping_cures_it(tmp_path, caplog):
    title = "a title far too long for a figure five inches wide, " * 3
    fig = plots.new_figure(5.0, 3.0)
    ax = fig.subplots()
    ax.set(xlabel="elapsed time (min)", ylabel="thermal error (um)")
    fig.suptitle(title)
    outside = plots.text_outside_figure(fig)
    assert len(outside) == 1 and "a title far too long" in outside[0]
    with caplog.at_level(logging.WARNING, logger="pipeline.plots"):
        plots.save_figure(fig, tmp_path / "clipped.png")
    assert "text outside the figure" in caplog.text
    fig.suptitle(plots.wrap_text(fig, title, 12))
    assert fig.get_suptitle().count("\n") >= 2
    assert plots.text_outside_figure(fig) == []


def test_tick_labels_outside_the_view_are_not_counted():
    fig = plots.new_figure(4.0, 3.0)
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set(xlabel="x (mm)", ylabel="y (um)", xlim=(0.2, 0.8))
    fig.canvas.draw()
    drawn = [t.get_text() for t in plots.drawn_texts(fig) if t in ax.get_xticklabels()]
    assert drawn and all(0.2 <= float(x.replace("\u2212", "-")) <= 0.8 for x in drawn)


def test_campaign_label_and_ink():
    assert plots.campaign_label("K01", "winter") == "K01 (winter)"
    assert plots.campaign_label("K01", "winter", "\n") == "K01\nwinter"
    assert plots.campaign_label("K01", None) == "K01"
    assert plots.campaign_label("K01", float("nan")) == "K01"
    assert plots.ink_for((1.0, 1.0, 0.8, 1.0)) == "k"
    assert plots.ink_for((0.2, 0.0, 0.3, 1.0)) == "w"

"""Figures written by the stages (matplotlib, non-interactive Agg canvas, no pyplot state).

Every figure is read as a picture in the MLflow artifact viewer, about 800-1000 px wide: figures
are at most :data:`MAX_WIDTH_IN` inches wide at :data:`DPI` dots per inch, use matplotlib's
constrained layout, wrap long titles to the figure's width, label every axis with its unit and
name each campaign with its season where the season is known. Each figure has a function that
builds it (``*_figure``, returns the :class:`~matplotlib.figure.Figure`) and one that writes it
(:func:`save_figure`, which logs a warning for any text that falls outside the picture; see
:func:`text_outside_figure`).
"""

from __future__ import annotations

import logging
import textwrap
from collections.abc import Collection, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.image import imsave
from matplotlib.patches import Rectangle
from matplotlib.text import Text

LOGGER = logging.getLogger(__name__)

DPI = 100
MAX_WIDTH_IN = 12.0
TITLE_FONTSIZE = 12.0
PANEL_TITLE_FONTSIZE = 10.5
MIN_TICK_FONTSIZE = 6.5


def new_figure(width_in: float, height_in: float) -> Figure:
    """Return an empty figure on an Agg canvas with constrained layout.

    Parameters
    ----------
    width_in, height_in : float
        Size, inches; the width is capped at :data:`MAX_WIDTH_IN` (1200 px at :data:`DPI`).

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(min(width_in, MAX_WIDTH_IN), height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, out: Path) -> None:
    """Draw a figure once, warn about any text outside it, and write that picture as a PNG.

    The picture checked is the one written: the drawn canvas is saved as it is, at :data:`DPI`
    (``savefig`` would lay out and draw the figure again).

    Parameters
    ----------
    fig : Figure
        Built by one of the ``*_figure`` functions (Agg canvas).
    out : Path
        PNG path; parent folders are created.
    """
    fig.canvas.draw()
    outside = text_outside_figure(fig, drawn=True)
    if outside:
        LOGGER.warning("%s: text outside the figure: %s", out, "; ".join(outside))
    out.parent.mkdir(parents=True, exist_ok=True)
    imsave(out, np.asarray(fig.canvas.buffer_rgba()), format="png", dpi=fig.dpi)


def text_outside_figure(
    fig: Figure, tolerance_px: float = 1.0, *, drawn: bool = False
) -> list[str]:
    """Describe every drawn text whose extent leaves the figure (the text is clipped there).

    Checks titles, suptitle, axis labels, drawn tick labels, colour-bar labels, legends and
    annotations of visible axes. The figure is drawn first, so that the layout is final, unless
    ``drawn`` says it just was.

    Parameters
    ----------
    fig : Figure
    tolerance_px : float
        Overhang allowed at each edge, px.
    drawn : bool
        The figure was drawn (``fig.canvas.draw()``) since its last change.

    Returns
    -------
    list of str
        One ``'<text>' at x0..x1, y0..y1 px`` entry per text outside the figure's
        ``0..width, 0..height`` px box; empty when everything fits.
    """
    if not drawn:
        fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    problems = []
    for text in drawn_texts(fig):
        box = text.get_window_extent(renderer)
        if (
            box.x0 < -tolerance_px
            or box.y0 < -tolerance_px
            or box.x1 > width + tolerance_px
            or box.y1 > height + tolerance_px
        ):
            problems.append(
                f"{text.get_text()!r} at x {box.x0:.0f}..{box.x1:.0f}, y {box.y0:.0f}..{box.y1:.0f}"
                f" px (figure {width:.0f} x {height:.0f} px)"
            )
    return problems


def drawn_texts(fig: Figure) -> list[Text]:
    """Return the visible, non-empty texts of a drawn figure.

    Tick labels count only for the ticks inside their axis' view interval (the ones drawn).

    Parameters
    ----------
    fig : Figure
        Already drawn (``fig.canvas.draw()``), so that tick labels carry their final text.

    Returns
    -------
    list of Text
    """
    tick_labels: set[int] = set()
    drawn: list[Text] = []
    for axis in fig.findobj(Axis):
        ticks = [*axis.get_major_ticks(), *axis.get_minor_ticks()]
        low, high = sorted(axis.get_view_interval())
        slack = 1e-9 * max(high - low, 1.0)
        for tick in ticks:
            labels = (tick.label1, tick.label2)
            tick_labels.update(id(label) for label in labels)
            loc = tick.get_loc()
            if tick.get_visible() and loc is not None and low - slack <= loc <= high + slack:
                drawn.extend(label for label in labels if label.get_visible())
    for text in fig.findobj(Text):
        if id(text) not in tick_labels and text.get_visible():
            drawn.append(text)
    return [t for t in drawn if t.get_text().strip() and (t.axes is None or t.axes.get_visible())]


def wrap_text(fig: Figure, text: str, fontsize: float, width_in: float | None = None) -> str:
    """Wrap a text at word boundaries so that every line fits a width.

    Parameters
    ----------
    fig : Figure
        Figure the text goes into (Agg canvas; its dpi sets the scale).
    text : str
        May already contain line breaks; each line is wrapped on its own.
    fontsize : float
        Font size the text is drawn at, pt.
    width_in : float, optional
        Available width, inches; default 96 % of the figure's width.

    Returns
    -------
    str
        The text with line breaks added where a line was too wide.
    """
    available_px = (0.96 * fig.get_figwidth() if width_in is None else width_in) * fig.dpi
    renderer = fig.canvas.get_renderer()
    font = FontProperties(size=fontsize)

    def widest(block: str) -> float:
        return max(
            renderer.get_text_width_height_descent(line, font, ismath=False)[0]
            for line in block.split("\n")
        )

    lines = []
    for line in text.split("\n"):
        wrapped, chars = line, len(line)
        width = widest(line)
        if width > available_px and chars > 8:
            # Start from the width the line's mean character width allows (measuring a text is
            # the cost here), then narrow until every line fits.
            chars = max(8, int(chars * available_px / width))
            wrapped = textwrap.fill(line, chars)
            while chars > 8 and widest(wrapped) > available_px:
                chars -= max(1, chars // 20)
                wrapped = textwrap.fill(line, chars)
        count = wrapped.count("\n") + 1
        if count > 1:  # as many lines, of even length: no short last line
            even = -(-len(line) // count)
            while even < chars and textwrap.fill(line, even).count("\n") + 1 > count:
                even += 1
            if widest(textwrap.fill(line, even)) <= available_px:
                wrapped = textwrap.fill(line, even)
        lines.append(wrapped)
    return "\n".join(lines)


def campaign_label(campaign_id: str, season: str | None, separator: str = " ") -> str:
    r"""Name a campaign with its season: ``K01 (winter)``, or ``K01\nwinter`` with a line break.

    Parameters
    ----------
    campaign_id : str
    season : str or None
        Left out when missing or empty.
    separator : str
        ``" "`` puts the season in parentheses; ``"\n"`` puts it on a second line.

    Returns
    -------
    str
    """
    if season is None or (isinstance(season, float) and np.isnan(season)) or not str(season):
        return str(campaign_id)
    if separator == "\n":
        return f"{campaign_id}\n{season}"
    return f"{campaign_id}{separator}({season})"


def ink_for(rgba: tuple[float, ...]) -> str:
    """Return black or white, whichever reads better on a background colour.

    Parameters
    ----------
    rgba : tuple of float
        Background colour, components 0-1.

    Returns
    -------
    str
        ``"k"`` on light backgrounds (relative luminance above 0.45), ``"w"`` on dark ones.
    """
    red, green, blue = rgba[:3]
    return "k" if 0.2126 * red + 0.7152 * green + 0.0722 * blue > 0.45 else "w"


def fit_tick_labels(fig: Figure, axis: Axis, spacing_px: float) -> bool:
    """Shrink (down to 6.5 pt), then turn upright on one line, tick labels wider than their spacing.

    Parameters
    ----------
    fig : Figure
        Drawn at least once, so that the layout and the labels are known.
    axis : Axis
        An x axis with one label per category.
    spacing_px : float
        Distance between neighbouring ticks, px.

    Returns
    -------
    bool
        True if the labels were turned upright (they then need more room than the layout gave
        them); False if they were left as they were or only made smaller.
    """
    labels = [label for label in axis.get_ticklabels() if label.get_text()]
    if not labels or spacing_px <= 0:
        return False
    renderer = fig.canvas.get_renderer()
    widest = max(label.get_window_extent(renderer).width for label in labels)
    if widest <= 0.92 * spacing_px:
        return False
    fontsize = labels[0].get_fontsize() * 0.92 * spacing_px / widest
    if fontsize >= MIN_TICK_FONTSIZE:
        for label in labels:
            label.set_fontsize(fontsize)
        return False
    axis.set_ticks(
        axis.get_ticklocs(),
        [label.get_text().replace("\n", " ") for label in axis.get_ticklabels()],
        rotation=90,
        fontsize=max(MIN_TICK_FONTSIZE, labels[0].get_fontsize() * 0.9),
    )
    return True


def _cell_text(value: float) -> str:
    if abs(value) < 1:
        return f"{value:.2f}"
    return f"{value:.1f}" if abs(value) < 100 else f"{value:.0f}"


def score_heatmap_figure(
    matrices: dict[str, pd.DataFrame],
    title: str,
    seasons: Mapping[str, str] | None = None,
    validation: Collection[str] = (),
    in_sample: pd.DataFrame | None = None,
) -> Figure:
    r"""Build the train x test score heat-maps, one panel per matrix, values written in the cells.

    Columns are labelled ``campaign\nseason``; a thick vertical line and the labels on top
    separate the training from the validation campaigns; a horizontal line separates the
    single-campaign training units from the units of several campaigns (``not_<season>``...);
    cells whose campaign is part of the training unit (a fit, not a prediction) are outlined.

    Parameters
    ----------
    matrices : dict of str to DataFrame
        Quantity with its unit (panel title and colour-bar label, e.g.
        ``"RMS of the residual (um)"``) -> matrix (rows: training unit, columns: test campaign,
        training campaigns first, then the validation ones), um.
    title : str
        Figure title (says whether the data are synthetic); wrapped to the figure's width.
    seasons : mapping of str to str, optional
        Campaign id -> season, for the tick labels.
    validation : collection of str
        Campaign ids of the validation split.
    in_sample : DataFrame of bool, optional
        Same labels as the matrices: True where the test campaign is in the training unit.

    Returns
    -------
    Figure
    """
    seasons = dict(seasons or {})
    validation = set(validation)
    n_rows = max((m.shape[0] for m in matrices.values()), default=1)
    n_cols = max((m.shape[1] for m in matrices.values()), default=1)
    panel_width = float(np.clip(3.8 + 0.42 * n_cols, 7.0, MAX_WIDTH_IN))
    height = float(np.clip(3.2 + 0.36 * n_rows, 5.0, 11.0))
    fig = new_figure(panel_width * max(len(matrices), 1), height)
    axes = fig.subplots(1, max(len(matrices), 1), squeeze=False)[0]
    cells = []
    for ax, (name, matrix) in zip(axes, matrices.items(), strict=False):
        mask = None
        if in_sample is not None:
            mask = in_sample.reindex(index=matrix.index, columns=matrix.columns, fill_value=False)
        cells.append(
            (ax, matrix.shape, _draw_heatmap(fig, ax, name, matrix, seasons, validation, mask))
        )
    fig.suptitle(wrap_text(fig, title, TITLE_FONTSIZE), fontsize=TITLE_FONTSIZE)
    # The cell values sit inside their axes and are sized to the cells once the layout is
    # known: left out of the layout and of this measuring draw, which they would only slow.
    for _, _, texts in cells:
        for text in texts:
            text.set_in_layout(False)
            text.set_visible(False)
    fig.draw_without_rendering()
    upright = False
    for ax, (rows, columns), texts in cells:
        cell_w = ax.bbox.width / max(columns, 1)
        cell_h = ax.bbox.height / max(rows, 1)
        upright |= fit_tick_labels(fig, ax.xaxis, cell_w)
        px_per_pt = fig.dpi / 72.0
        chars = max((len(t.get_text()) for t in texts), default=4)
        size = min(9.0, 0.55 * cell_h / px_per_pt, 0.9 * cell_w / (0.64 * chars * px_per_pt))
        for text in texts:
            text.set_fontsize(max(size, 5.0))
            text.set_visible(True)
    if not upright:
        # The layout just computed still holds (labels only made smaller, cell values outside
        # it): keep it rather than compute it again when the figure is drawn.
        fig.set_layout_engine("none")
    return fig


def _draw_heatmap(
    fig: Figure,
    ax: Axes,
    name: str,
    matrix: pd.DataFrame,
    seasons: dict[str, str],
    validation: set[str],
    in_sample: pd.DataFrame | None,
) -> list[Text]:
    values = matrix.to_numpy(dtype=float)
    finite = values[np.isfinite(values)]
    norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0.0, 1.0))
    cmap = colormaps["viridis_r"].with_extremes(bad="0.85")
    image = ax.imshow(
        np.ma.masked_invalid(values), cmap=cmap, norm=norm, aspect="auto", interpolation="nearest"
    )
    columns, units = [str(c) for c in matrix.columns], [str(u) for u in matrix.index]
    ax.set_xticks(
        range(len(columns)),
        [campaign_label(c, seasons.get(c), "\n") for c in columns],
        fontsize=8.5,
    )
    ax.set_yticks(
        range(len(units)), [campaign_label(u, seasons.get(u)) for u in units], fontsize=8.5
    )
    ax.tick_params(length=2)
    ax.set_xlabel("test campaign (season)" if seasons else "test campaign")
    ax.set_ylabel("model built on (training unit)")
    first_validation = next((j for j, c in enumerate(columns) if c in validation), None)
    if first_validation:
        ax.axvline(first_validation - 0.5, color="k", lw=3)
        top = ax.secondary_xaxis("top")
        top.set_xticks(
            [(first_validation - 1) / 2, (first_validation + len(columns) - 1) / 2],
            ["training campaigns", "validation campaigns"],
            fontsize=9,
        )
        top.tick_params(length=0)
    single = [u in set(columns) for u in units]
    for i in range(1, len(units)):
        if single[i] != single[i - 1]:
            ax.axhline(i - 0.5, color="k", lw=2)
    note = ""
    if in_sample is not None and in_sample.to_numpy(dtype=bool).any():
        note = "; outlined cells: scored on a campaign of the training unit (a fit)"
        for (i, j), inside in np.ndenumerate(in_sample.to_numpy(dtype=bool)):
            if inside:
                edge = ink_for(cmap(norm(values[i, j]))) if np.isfinite(values[i, j]) else "k"
                ax.add_patch(
                    Rectangle((j - 0.44, i - 0.44), 0.88, 0.88, fill=False, ec=edge, lw=1.2)
                )
    texts = [
        ax.text(
            j,
            i,
            _cell_text(value),
            ha="center",
            va="center",
            fontsize=8,
            color=ink_for(cmap(norm(value))),
        )
        for (i, j), value in np.ndenumerate(values)
        if np.isfinite(value)
    ]
    fig.colorbar(image, ax=ax, label=name, fraction=0.05, pad=0.02)
    width = ax.get_position().width * fig.get_figwidth()
    ax.set_title(
        wrap_text(fig, name + note, PANEL_TITLE_FONTSIZE, 0.9 * width),
        fontsize=PANEL_TITLE_FONTSIZE,
    )
    return texts


def axis_separation_figure(
    passes: pd.DataFrame, geometric: pd.DataFrame, campaign_id: str, title: str
) -> Figure:
    """Build the measured, geometric and thermal positioning error of one axis campaign.

    Parameters
    ----------
    passes : DataFrame
        Rows of ``axis_thermal_error`` for the campaign: ``elapsed_min`` (min), ``target_mm``
        (mm), ``measured_um``, ``geometric_um``, ``thermal_um``, ``thermal_fit_um`` (um).
    geometric : DataFrame
        Dense curve of the fitted geometric polynomial: ``target_mm`` (mm), ``geometric_um``
        (um).
    campaign_id : str
    title : str
        Suffix of the figure title (e.g. "synthetic data").

    Returns
    -------
    Figure
    """
    fig = new_figure(MAX_WIDTH_IN, 5.4)
    left, right = fig.subplots(1, 2)
    colours = colormaps["plasma"](np.linspace(0, 0.85, max(passes["elapsed_min"].nunique(), 1)))
    for colour, (minute, rows) in zip(colours, passes.groupby("elapsed_min"), strict=False):
        left.plot(
            rows["target_mm"],
            rows["measured_um"],
            "o-",
            ms=3,
            color=colour,
            label=f"{minute:g} min",
        )
        right.plot(rows["target_mm"], rows["thermal_um"], "o", ms=3, color=colour)
        right.plot(
            rows["target_mm"], rows["thermal_fit_um"], "-", color=colour, label=f"{minute:g} min"
        )
    left.plot(
        geometric["target_mm"],
        geometric["geometric_um"],
        "k--",
        lw=2,
        label="geometric part\n(polynomial fit of the cold pass)",
    )
    half = 0.45 * fig.get_figwidth()
    for ax, text in (
        (left, "measured (bidirectional mean) and geometric part"),
        (right, "thermal part = measured - geometric (dots), first-order fit (lines)"),
    ):
        ax.set_title(
            wrap_text(fig, text, PANEL_TITLE_FONTSIZE, half), fontsize=PANEL_TITLE_FONTSIZE
        )
    left.set(xlabel="position (mm)", ylabel="positioning error (um)")
    right.set(xlabel="position (mm)", ylabel="thermal error (um)")
    for ax in (left, right):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, title="elapsed time", title_fontsize=8)
    fig.suptitle(
        wrap_text(fig, f"{campaign_id}: geometric / thermal separation ({title})", TITLE_FONTSIZE),
        fontsize=TITLE_FONTSIZE,
    )
    return fig


def selection_stability_figure(stability: pd.DataFrame, title: str) -> Figure:
    """Build the heat-map of how often each method chose each input across the campaigns.

    Parameters
    ----------
    stability : DataFrame
        ``method``, ``sensor``, ``frequency`` (0-1), ``times_chosen``, ``n_campaigns``; methods
        and inputs are shown in the order they first appear.
    title : str
        Figure title (says whether the data are synthetic); wrapped to the figure's width.

    Returns
    -------
    Figure
    """
    methods = list(pd.unique(stability["method"]))
    inputs = list(pd.unique(stability["sensor"]))
    table = stability.pivot_table(index="method", columns="sensor", values="frequency")
    table = table.reindex(index=methods, columns=inputs)
    counts = stability.pivot_table(index="method", columns="sensor", values="times_chosen")
    counts = counts.reindex(index=methods, columns=inputs)
    width = float(np.clip(3.5 + 0.55 * len(inputs), 6.5, MAX_WIDTH_IN))
    fig = new_figure(width, float(np.clip(3.4 + 0.45 * len(methods), 4.0, 9.0)))
    ax = fig.subplots()
    cmap = colormaps["Blues"]
    norm = Normalize(0.0, 1.0)
    image = ax.imshow(table.to_numpy(dtype=float), cmap=cmap, norm=norm, aspect="auto")
    ax.set_xticks(
        range(len(inputs)), inputs, rotation=45, ha="right", rotation_mode="anchor", fontsize=8.5
    )
    ax.set_yticks(range(len(methods)), methods, fontsize=9)
    ax.set_xlabel("model input (temperature sensor or speed response)")
    ax.set_ylabel("selection method")
    for (i, j), value in np.ndenumerate(counts.to_numpy(dtype=float)):
        if np.isfinite(value):
            share = table.iat[i, j]
            ink = ink_for(cmap(norm(share))) if np.isfinite(share) else "k"
            ax.text(j, i, f"{int(value)}", ha="center", va="center", fontsize=8, color=ink)
    fig.colorbar(image, ax=ax, label="share of training campaigns (0-1)", fraction=0.05)
    n_campaigns = stability["n_campaigns"].max() if len(stability) else 0
    note = f"number in a cell: training campaigns (of {n_campaigns:g}) whose selection chose it"
    ax.set_title(wrap_text(fig, note, 9.5, 0.8 * fig.get_figwidth()), fontsize=9.5)
    fig.suptitle(wrap_text(fig, title, TITLE_FONTSIZE), fontsize=TITLE_FONTSIZE)
    return fig


def predicted_vs_measured_figure(
    panels: dict[str, pd.DataFrame],
    labels: tuple[str, str],
    title: str,
    seasons: Mapping[str, str] | None = None,
) -> Figure:
    """Build the measured thermal error and two models' predictions, one panel per campaign.

    Parameters
    ----------
    panels : dict of str to DataFrame
        Campaign id -> ``elapsed_min`` (min), ``measured_um``, ``first_um``, ``second_um`` (um).
    labels : tuple of str
        Legend labels of ``first_um`` and ``second_um``.
    title : str
        Wrapped to the figure's width.
    seasons : mapping of str to str, optional
        Campaign id -> season, shown in the panel titles.

    Returns
    -------
    Figure
    """
    seasons = dict(seasons or {})
    n = max(len(panels), 1)
    columns = min(n, 3)
    rows = -(-n // columns)
    fig = new_figure(2.0 + 3.4 * columns, 1.4 + 2.9 * rows)
    axes = fig.subplots(rows, columns, squeeze=False)
    for ax, (campaign, frame) in zip(axes.flat, panels.items(), strict=False):
        ax.plot(frame["elapsed_min"], frame["measured_um"], "k.", ms=3, label="measured")
        ax.plot(frame["elapsed_min"], frame["first_um"], "-", label=labels[0])
        ax.plot(frame["elapsed_min"], frame["second_um"], "--", label=labels[1])
        ax.set_title(campaign_label(campaign, seasons.get(campaign)), fontsize=PANEL_TITLE_FONTSIZE)
        ax.set_xlabel("elapsed time (min)")
        ax.set_ylabel("thermal error (um)")
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    if panels:
        handles, names = axes.flat[0].get_legend_handles_labels()
        fig.legend(
            handles, names, loc="outside lower center", ncols=3 if columns > 1 else 1, fontsize=9
        )
    else:
        axes.flat[0].set_visible(True)
        axes.flat[0].set_axis_off()
        axes.flat[0].text(0.5, 0.5, "no held-out prediction to show", ha="center", va="center")
    fig.suptitle(wrap_text(fig, title, TITLE_FONTSIZE), fontsize=TITLE_FONTSIZE)
    return fig

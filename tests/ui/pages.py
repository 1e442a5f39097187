"""The pages of the MLflow UI (3.x) that the UI check visits, and their checks (pure).

The UI is a single-page app; everything after ``#`` is its route. The parameters below were
read from its bundled JavaScript (``mlflow/server/js/build/static/js/``):

- ``/experiments/<id>?workflowType=machine_learning``: the experiment in the model-training
  view (MLflow 3 otherwise opens its GenAI overview); the header shows the description;
- ``/experiments/<id>/runs?searchFilter=...&orderByKey=metrics.`<key>`&orderByAsc=true``: the
  run list, filtered and sorted (the query is read on the ``/runs`` route only). The filter
  selects the pipeline's children directly (``tags.`mlflow.parentRunId` = '<id>'``), so no
  parent row has to be expanded. Columns (``selectedColumns``) are UI state kept in the
  browser, not in the URL: the list shows the sort key in its "Sort:" button, not as a column;
- ``/compare-runs?runs=["<id>",...]&experiments=["<id>"]``: JSON lists, as the UI writes them.
  Its metric and tag tables render about 300 px of rows (the first metrics in alphabetical
  order), and its artifact section lists only the files common to the runs' artifact roots, so
  figure in a sub-folder would not be shown there (the pipeline logs its evidence at the root).
  Which file the section previews is React state: the check clicks the heat-map in its file
  tree (:attr:`Page.select`) and expects one loaded image per compared run;
- ``/metric?runs=[...]&metric="<key>"&experiments=[...]&plot_metric_keys=["<key>"]``: one metric
  of several runs, chart and table, the page Compare links each metric to;
- ``/models/<name>/versions/<version>``: a registered version, aliases shown as ``@ <alias>``;
- ``/experiments/<id>/runs/<run id>/artifacts/<path>``: a run's artifact in the artifact browser.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote, urlencode

from pipeline.tracking import views
from tests.ui.dom import PageDom, error_phrases
from tests.ui.expect import HEAT_MAP, AxisPlan, Child, Plan, Version

ML_VIEW = {"workflowType": "machine_learning"}
DESCRIPTION_WORDS = 8
WINDOW_WIDTH = 1600
WINDOW_HEIGHT = 1200
COMPARE_HEIGHT = 2700  # visualisations, run details, parameters, metrics, artifacts, tags
ROW_HEIGHT = 45  # a run-list row with its margins, CSS px
IMAGE_SOURCES = ("blob:", "data:", "http")
MIN_TEXT_NODES = 60  # fewer on a page with missing items: probably still loading
VALUE_NODE = re.compile(r"(-?[\d,]+(?:\.\d+)?(?:e[-+]?\d+)?) \(step=-?\d+\)", re.IGNORECASE)


@dataclass(frozen=True)
class Check:
    """One thing a page must show.

    Attributes
    ----------
    label : str
        What it is, for the report (e.g. ``champion run 'Z/mlr/all/static'``).
    text : str
        The text to find.
    exact : bool
        True: a whole text node of the page (run and model names); False: anywhere in the page
        text, compared on letters and digits only (a description rendered from Markdown).
    required : bool
        False for what the page may legitimately leave out (reported, never a problem).
    value : float or None
        If set, the node ``text`` (a run name in a metric table) must be followed by the node
        ``<value> (step=<n>)``, the value equal to this one to 1e-3 (the UI may round).
    """

    label: str
    text: str
    exact: bool = True
    required: bool = True
    value: float | None = None


@dataclass(frozen=True)
class Page:
    """A page of the UI to visit and what it must show.

    Attributes
    ----------
    name : str
        Page name in the report, e.g. ``runs Z``.
    url : str
        Full URL.
    screenshot : str
        PNG file name in the output folder.
    checks : tuple of Check
        Texts the page must show.
    order : tuple of tuple of str
        ``(run id, run name)`` the run table must show first, in this order.
    order_metric : mapping of str to float
        The ranking metric of the runs of ``order`` by run id (equal values may swap places).
    run_names : mapping of str to str
        Names of the runs the table may show, by run id, for the report.
    image : str or None
        ``alt`` of an image the page must show loaded (an artifact path).
    image_count : int
        How many such images it must show: one per compared run on Compare.
    select : str or None
        Artifact to click in the Compare page's Artifacts file tree before the capture (the
        selection is React state, not in the URL; :func:`tests.ui.browser.render` clicks it).
    height : int
        Window height, CSS px (tables render only the rows that fit).
    """

    name: str
    url: str
    screenshot: str
    checks: tuple[Check, ...] = ()
    order: tuple[tuple[str, str], ...] = ()
    order_metric: Mapping[str, float] = field(default_factory=dict)
    run_names: Mapping[str, str] = field(default_factory=dict)
    image: str | None = None
    image_count: int = 1
    select: str | None = None
    height: int = WINDOW_HEIGHT


@dataclass
class PageResult:
    """What a rendered page showed: found and missing items, problem lines."""

    found: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def _json(value: Any) -> str:
    return quote(json.dumps(value, separators=(",", ":")), safe="")


def experiment_url(base: str, experiment_id: str) -> str:
    """Return the experiment's page in the model-training view (not the GenAI overview)."""
    return f"{base}/#/experiments/{experiment_id}?{urlencode(ML_VIEW)}"


def runs_url(base: str, experiment_id: str, search_filter: str, metric: str | None) -> str:
    """Return the run list filtered by ``search_filter``, sorted by ``metric`` ascending."""
    query = {**ML_VIEW, "searchFilter": search_filter}
    if metric:
        query |= {"orderByKey": f"metrics.`{metric}`", "orderByAsc": "true"}
    return f"{base}/#/experiments/{experiment_id}/runs?{urlencode(query, quote_via=quote)}"


def compare_url(base: str, run_ids: Sequence[str], experiment_ids: Sequence[str]) -> str:
    """Return the Compare page of ``run_ids``."""
    runs, experiments = _json(list(run_ids)), _json(list(experiment_ids))
    return f"{base}/#/compare-runs?runs={runs}&experiments={experiments}"


def metric_url(
    base: str, run_ids: Sequence[str], metric: str, experiment_ids: Sequence[str]
) -> str:
    """Return the page of one metric of several runs (chart and table)."""
    return (
        f"{base}/#/metric?runs={_json(list(run_ids))}&metric={_json(metric)}"
        f"&experiments={_json(list(experiment_ids))}&plot_metric_keys={_json([metric])}"
    )


def model_version_url(base: str, name: str, version: str) -> str:
    """Return a registered model version's page."""
    return f"{base}/#/models/{quote(name, safe='')}/versions/{quote(str(version), safe='')}"


def artifact_url(base: str, experiment_id: str, run_id: str, path: str) -> str:
    """Return a run's artifact in the run page's artifact browser (model-training view)."""
    route = f"#/experiments/{experiment_id}/runs/{run_id}/artifacts/{quote(path)}"
    return f"{base}/{route}?{urlencode(ML_VIEW)}"


def words(text: str) -> str:
    """Return the letters-and-digits words of ``text`` joined by single spaces."""
    return " ".join(re.findall(r"[0-9A-Za-z]+", text))


def description_start(description: str, count: int = DESCRIPTION_WORDS) -> str:
    """Return the first ``count`` words of a Markdown description (link targets left out)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", description)
    return " ".join(words(text).split()[:count])


def _names(label: str, runs: Iterable[Child | None]) -> list[Check]:
    return [Check(f"{label} '{child.name}'", child.name) for child in runs if child is not None]


def _values(metric: str, runs: Iterable[Child]) -> list[Check]:
    checks = []
    for child in runs:
        value = child.metrics.get(metric, math.nan)
        known = f"= {value:g}" if not math.isnan(value) else "(none in the store)"
        label = f"{metric} of '{child.name}' {known}"
        checks.append(Check(label, child.name, value=value))
    return checks


def _runs_page(base: str, plan: Plan, axis: AxisPlan, leaders: Sequence[Child]) -> Page:
    others = [child for child in leaders if child is not axis.champion]
    checks = _names("champion run", [axis.champion]) + _names("ranked run", others)
    if axis.metric:
        checks.append(Check(f"'Sort: {axis.metric}'", f"Sort: {axis.metric}", exact=False))
    count = f"{len(axis.listed)} matching runs"
    checks.append(Check(f"'{count}'", count, exact=False))
    if axis.shared_view:  # the shared view opens with the scores as columns
        url = base + views.view_path(plan.experiment_id, axis.shared_view)
        checks.append(Check("'Metrics' columns", "Metrics"))
    else:
        url = runs_url(base, plan.experiment_id, axis.search_filter, axis.metric)
    return Page(
        f"runs {axis.axis}",
        url,
        f"02_runs_ranked_{axis.axis}.png",
        tuple(checks),
        order=tuple((child.run_id, child.name) for child in leaders) if axis.metric else (),
        order_metric={
            child.run_id: child.metrics.get(axis.metric or "", math.nan) for child in leaders
        },
        run_names={child.run_id: child.name for child in axis.listed},
        height=max(WINDOW_HEIGHT, 400 + ROW_HEIGHT * len(axis.listed)),
    )


def _compare_page(base: str, plan: Plan, axis: AxisPlan, leaders: Sequence[Child]) -> Page:
    checks = _names("run", leaders)
    if axis.has_rank:
        checks.append(Check("tag 'rank'", "rank"))
    if axis.metric:
        label = f"metric {axis.metric} in the metric table (first rows only)"
        checks.append(Check(label, axis.metric, required=False))
    ids = [child.run_id for child in leaders]
    return Page(
        f"compare {axis.axis}",
        compare_url(base, ids, [plan.experiment_id]),
        f"03_compare_{axis.axis}.png",
        tuple(checks),
        image=HEAT_MAP,
        image_count=len(leaders),
        select=HEAT_MAP,
        height=COMPARE_HEIGHT,
    )


def _model_page(base: str, axis: AxisPlan, version: Version) -> Page:
    checks = [
        Check(f"model '{version.name}'", version.name),
        Check(f"'Version {version.version}'", f"Version {version.version}", exact=False),
        Check("alias '@ champion'", "@ champion", exact=False),
    ]
    start = description_start(version.description)
    if start:
        checks.append(Check(f"description '{start}...'", start, exact=False))
    checks += _names("source run", [axis.champion])
    return Page(
        f"model {axis.axis}",
        model_version_url(base, version.name, version.version),
        f"04_champion_model_{axis.axis}.png",
        tuple(checks),
    )


def axis_pages(base: str, plan: Plan, axis: AxisPlan, top: int = 3) -> list[Page]:
    """Return the pages of one axis that its store allows.

    Parameters
    ----------
    base : str
        The UI's address, ``http://127.0.0.1:<port>``.
    plan : Plan
        The experiment.
    axis : AxisPlan
        The axis' runs, ranking, champion and version.
    top : int
        How many of the best-ranked runs to compare.

    Returns
    -------
    list of Page
        Run list; Compare (two runs or more); champion's model version (if registered); ranking
        metric (if any); champion's heat-map (if a champion).
    """
    leaders = list(axis.ranked[:top])
    pages = [_runs_page(base, plan, axis, leaders)]
    if len(leaders) >= 2:
        pages.append(_compare_page(base, plan, axis, leaders))
    if axis.version is not None:
        pages.append(_model_page(base, axis, axis.version))
    if axis.metric and leaders:
        pages.append(
            Page(
                f"metric {axis.axis}",
                metric_url(base, [c.run_id for c in leaders], axis.metric, [plan.experiment_id]),
                f"05_ranking_metric_{axis.axis}.png",
                (Check(f"metric {axis.metric}", axis.metric), *_values(axis.metric, leaders)),
            )
        )
    if axis.champion is not None:
        pages.append(
            Page(
                f"heat-map {axis.axis}",
                artifact_url(base, plan.experiment_id, axis.champion.run_id, HEAT_MAP),
                f"06_champion_heatmap_{axis.axis}.png",
                tuple(_names("champion run", [axis.champion])),
                image=HEAT_MAP,
            )
        )
    return pages


def make_pages(base: str, plan: Plan, top: int = 3) -> list[Page]:
    """Return every page to visit: the experiment, then each axis' pages."""
    checks = [Check(f"experiment name '{plan.experiment_name}'", plan.experiment_name)]
    start = description_start(plan.description)
    if start:
        checks.append(Check(f"description '{start}...'", start, exact=False))
    experiment = Page(
        "experiment", experiment_url(base, plan.experiment_id), "01_experiment.png", tuple(checks)
    )
    return [experiment] + [page for axis in plan.axes for page in axis_pages(base, plan, axis, top)]


def _order_problem(page: Page, dom: PageDom) -> str | None:
    wanted = [run_id for run_id, _ in page.order]
    shown = dom.run_order()[: len(wanted)]
    value = page.order_metric
    swapped = [
        (want, got)
        for want, got in zip(wanted, shown, strict=False)
        if want != got and value.get(want) != value.get(got, math.nan)
    ]
    if len(shown) == len(wanted) and not swapped:
        return None
    names = {**page.run_names, **dict(page.order)}
    return (
        f"{page.name}: the first rows show {', '.join(names.get(i, i) for i in shown) or 'no run'}"
        f"; expected in rank order {', '.join(names[i] for i in wanted)}"
    )


def _shows_value(nodes: Sequence[str], name: str, value: float) -> bool:
    for index, node in enumerate(nodes[:-1]):
        match = VALUE_NODE.fullmatch(nodes[index + 1]) if node == name else None
        shown = float(match.group(1).replace(",", "")) if match else math.nan
        if math.isclose(shown, value, rel_tol=1e-3, abs_tol=1e-3):
            return True
    return False


def _check_images(page: Page, dom: PageDom, result: PageResult) -> None:
    """Count the images ``alt=page.image`` with a source (loaded, when the capture knows)."""
    shown = [
        src
        for alt, src in dom.images
        if alt == page.image
        and src.startswith(IMAGE_SOURCES)
        and (dom.loaded is None or src in dom.loaded)
    ]
    if page.select is None:
        label, ok = f"image {page.image}", bool(shown)
        problem = f"{page.name}: {label} not shown"
    else:
        count = page.image_count
        label = f"{len(shown)} of {count} compared runs show image {page.image}"
        ok = len(shown) == count
        problem = (
            f"{page.name}: {label} in the Artifacts section (one loaded image per run expected)"
        )
    (result.found if ok else result.missing).append(label)
    if not ok:
        result.problems.append(problem)


def check_page(page: Page, dom: PageDom) -> PageResult:
    """Compare what a rendered page shows with what it must show.

    Parameters
    ----------
    page : Page
        The page and its checks.
    dom : PageDom
        The rendered page.

    Returns
    -------
    PageResult
        Found and missing items, one problem per error shown or required item missing.
    """
    result = PageResult()
    for banner in dom.banners:
        result.problems.append(f"{page.name}: the page shows the error '{banner[:200]}'")
    for phrase in error_phrases(dom.text):
        if not any(phrase.lower() in banner.lower() for banner in dom.banners):
            result.problems.append(f"{page.name}: the page shows '{phrase}'")
    nodes, text = set(dom.nodes), f" {words(dom.text)} "
    for check in page.checks:
        shown = check.text in nodes if check.exact else f" {words(check.text)} " in text
        if check.value is not None:
            shown = _shows_value(dom.nodes, check.text, check.value)
        (result.found if shown else result.missing).append(check.label)
        if not shown and check.required:
            result.problems.append(f"{page.name}: {check.label} not shown")
    if page.image:
        _check_images(page, dom, result)
    if page.order:
        problem = _order_problem(page, dom)
        if problem:
            result.missing.append("rank order")
            result.problems.append(problem)
        else:
            result.found.append(f"rank order of the first {len(page.order)}")
    if any(check.required for check in page.checks) and len(dom.nodes) < MIN_TEXT_NODES:
        if result.problems:
            result.problems.append(
                f"{page.name}: only {len(dom.nodes)} text nodes; the page may not have finished "
                "loading (raise --budget-ms)"
            )
    return result

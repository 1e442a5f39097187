"""The UI check's pure parts: reading a rendered page, the UI's addresses, what each page must show.

No browser, no server: DOM strings in (error banners and phrases, table rows, images), the URLs
of the UI's routes, the plan made from a complete and from an older store layout, and the
problems :func:`tests.ui.pages.check_page` names.
"""

from __future__ import annotations

import pytest

from tests.ui.dom import error_phrases, parse_dom
from tests.ui.expect import Child, StoreView, Version, make_plan
from tests.ui.pages import (
    Check,
    Page,
    check_page,
    compare_url,
    description_start,
    experiment_url,
    make_pages,
    model_version_url,
    runs_url,
)

PARENT = "p" * 32
SCREENSHOTS = [
    "01_experiment.png",
    "02_runs_ranked_Z.png",
    "03_compare_Z.png",
    "04_champion_model_Z.png",
    "05_ranking_metric_Z.png",
    "06_champion_heatmap_Z.png",
]


# --- reading a rendered page ------------------------------------------------------------------


def test_error_banner_and_phrases_are_found_but_not_the_word_error():
    html = (
        "<html><head><title>Error</title></head><body>"
        "<script>const m='Something went wrong';</script>"
        "<div class='du-bois-light-alert du-bois-light-alert-error' role='alert'>"
        "<span>Experiment load error:</span> <span>No Experiment with id=999 exists</span></div>"
        "<h1>thermal-error</h1><p>Error model of the spindle: 0.404 um, 404 runs</p>"
        "</body></html>"
    )
    dom = parse_dom(html)
    assert dom.banners == ["Experiment load error: No Experiment with id=999 exists"]
    assert error_phrases(dom.text) == ["load error", "No Experiment with id=999 exists"]
    assert error_phrases("thermal-error Error model 0.404 um, 404 runs, Error stack") == []


@pytest.mark.parametrize(
    ("text", "phrase"),
    [
        ("Page Not Found Model nope v3 does not exist, go back", "Page Not Found"),
        ("Request error Invalid clause(s) in filter string", "Request error"),
        ("Something went wrong", "Something went wrong"),
        ("TypeError: Failed to fetch", "Failed to fetch"),
        ("404: Resource not found", "404"),
        ("Loading artifact failed", "Loading artifact failed"),
    ],
)
def test_error_phrases_of_the_ui(text, phrase):
    assert phrase in error_phrases(text)


def test_rows_are_read_in_screen_order_and_hidden_text_is_left_out():
    row = '<div role="row" row-index="{i}"><a href="#/experiments/7/runs/{run}">{name}</a></div>'
    html = (
        "<body><noscript>You need to enable JavaScript</noscript>"
        + row.format(i=1, run="b" * 32, name="Z/ridge/all/static")
        + row.format(i=0, run="a" * 32, name="Z/mlr/all/static")
        + '<svg><text>Failed to load</text></svg><img alt="x.png" src="blob:http://h/1">'
        "</body>"
    )
    dom = parse_dom(html)
    assert dom.run_order() == ["a" * 32, "b" * 32]
    assert dom.nodes == ["Z/ridge/all/static", "Z/mlr/all/static"]
    assert dom.images == [("x.png", "blob:http://h/1")]
    assert error_phrases(dom.text) == []


# --- URLs -------------------------------------------------------------------------------------


def test_urls_use_the_parameters_of_the_ui():
    base = "http://127.0.0.1:5000"
    assert experiment_url(base, "2") == f"{base}/#/experiments/2?workflowType=machine_learning"
    url = runs_url(base, "2", "tags.eligible = 'true'", "loso_Mn_rms_um")
    assert url.startswith(f"{base}/#/experiments/2/runs?workflowType=machine_learning&")
    assert "searchFilter=tags.eligible%20%3D%20%27true%27" in url
    assert url.endswith("orderByKey=metrics.%60loso_Mn_rms_um%60&orderByAsc=true")
    assert compare_url(base, ["a1", "b2"], ["2"]) == (
        f"{base}/#/compare-runs?runs=%5B%22a1%22%2C%22b2%22%5D&experiments=%5B%222%22%5D"
    )
    assert model_version_url(base, "thermal error/Z", "3") == (
        f"{base}/#/models/thermal%20error%2FZ/versions/3"
    )
    assert description_start("**Thermal** [errors](http://x.org/a) of the *spindle*", 4) == (
        "Thermal errors of the"
    )


# --- what the pages must show -----------------------------------------------------------------


def _child(name, rank, metric, *, eligible=True, champion=False, layout=True):
    axis, model, selection, mode = name.split("/")
    tags = {"axis": axis, "model": model, "selection": selection, "mode": mode}
    if layout:
        tags |= {"eligible": str(eligible).lower(), "rank": rank, "champion": str(champion).lower()}
        if not eligible:
            tags["ineligible_reason"] = "one-step"
    else:
        tags["champion"] = str(champion).lower()
    metrics = {("loso_Mn_rms_um" if layout else "loso.Mn_rms_um"): metric}
    evidence = frozenset({"cross_season_rms.png", "scores.json"} if layout else ())
    return Child(name.replace("/", "")[:32].ljust(32, "0"), name, tags, metrics, evidence)


def _view(children, *, layout=True, version_run=None):
    champion = next(c for c in children if c.tags.get("champion") == "true")
    version = Version(
        "thermal-error-spindle-Z",
        "3",
        "Axis Z: pls_dl",
        ("champion",),
        version_run or champion.run_id,
    )
    return StoreView(
        "2",
        "thermal-error",
        {
            "mlflow.note.content": "Thermal-error models",
            "mlflow.sharedViewState.ranked-vmc-450-Z": "{}",
        }
        if layout
        else {},
        PARENT,
        {"ranked_by.Z": "loso_Mn_rms_um"} if layout else {},
        tuple(children),
        {"Z": version},
    )


RECORD = {
    "experiment": "thermal-error",
    "machine": "vmc-450",
    "experiment_id": "2",
    "parent_run_id": PARENT,
    "champions": {
        "Z": {
            "registered_model": "thermal-error-spindle-vmc-450-Z",
            "version": "3",
            "model": "pls_dl/gra_top_k/static",
        }
    },
}


def test_plan_of_the_complete_layout_ranks_the_eligible_runs():
    children = [
        _child("Z/ridge_dl/gra_top_k/static", "2", 2.20),
        _child("Z/pls_dl/gra_top_k/static", "1", 2.19, champion=True),
        _child("Z/tv_ar/none/one_step", "", 0.35, eligible=False),
        _child("Z/none/none/static", "3", 25.3),
    ]
    plan, problems = make_plan(_view(children), RECORD)
    assert problems == []
    (axis,) = plan.axes
    assert [c.name for c in axis.ranked] == [
        "Z/pls_dl/gra_top_k/static",
        "Z/ridge_dl/gra_top_k/static",
        "Z/none/none/static",
    ]
    assert axis.champion.name == "Z/pls_dl/gra_top_k/static"
    assert axis.metric == "loso_Mn_rms_um"
    assert axis.search_filter.endswith("and tags.axis = 'Z' and tags.eligible = 'true'")
    pages = make_pages("http://h", plan)
    assert [page.screenshot for page in pages] == SCREENSHOTS
    (runs,) = [page for page in pages if page.name == "runs Z"]
    assert runs.url.endswith(
        "/runs?workflowType=machine_learning&viewStateShareKey=ranked-vmc-450-Z"
    )
    (compare,) = [page for page in pages if page.name == "compare Z"]
    heat_map = "cross_season_rms.png"
    assert (compare.select, compare.image, compare.image_count) == (heat_map, heat_map, 3)


def test_plan_of_an_older_store_names_what_is_missing_and_falls_back():
    children = [
        _child("Z/pls_dl/gra_top_k/static", "", 2.19, champion=True, layout=False),
        _child("Z/tv_ar/none/one_step", "", 0.35, layout=False),
    ]
    plan, problems = make_plan(_view(children, layout=False), RECORD)
    text = "\n".join(problems)
    assert "store: experiment 'thermal-error' has no description" in text
    assert "store: tag 'eligible' missing: 2 of 2 child runs" in text
    assert "store: tag 'rank' missing" in text
    assert "store: parent run pppp" in text and "no tag ranked_by.Z" in text
    assert "store: artifact cross_season_rms.png missing" in text
    (axis,) = plan.axes
    assert axis.metric == "loso.Mn_rms_um"
    assert [c.name for c in axis.ranked] == ["Z/tv_ar/none/one_step", "Z/pls_dl/gra_top_k/static"]


def test_plan_names_a_record_that_disagrees_with_the_store():
    children = [
        _child("Z/pls_dl/gra_top_k/static", "1", 2.19, champion=True),
        _child("Z/mlr/all/static", "2", 2.1),
    ]
    record = {**RECORD, "champions": {"Z": {**RECORD["champions"]["Z"], "model": "mlr/x/static"}}}
    _, problems = make_plan(_view(children, version_run="r" * 32), record)
    text = "\n".join(problems)
    assert "record: the champion Z/mlr/x/static of axis Z in reports/mlflow_run.json is not" in text
    assert "Z/pls_dl/gra_top_k/static ranks before Z/mlr/all/static but its loso_Mn_rms_um" in text
    assert "store: thermal-error-spindle-Z v3 comes from run rrrr" in text


def test_check_page_names_the_page_and_the_missing_item():
    page = Page(
        "runs Z",
        "http://h/#/",
        "02.png",
        (Check("champion run 'Z/a'", "Z/a"), Check("'2 matching runs'", "2 matching runs", False)),
        order=(("a" * 32, "Z/a"), ("b" * 32, "Z/b")),
        order_metric={"a" * 32: 1.0, "b" * 32: 2.0},
    )
    row = '<div row-index="{i}"><a href="#/experiments/1/runs/{run}">{name}</a></div>'
    shown = row.format(i=0, run="b" * 32, name="Z/b") + row.format(i=1, run="a" * 32, name="Z/a")
    result = check_page(page, parse_dom(f"<body>{shown}<span>2 matching runs</span></body>"))
    assert result.problems == [
        "runs Z: the first rows show Z/b, Z/a; expected in rank order Z/a, Z/b",
        "runs Z: only 3 text nodes; the page may not have finished loading (raise --budget-ms)",
    ]
    result = check_page(
        page, parse_dom(f"<body>{row.format(i=0, run='a' * 32, name='Z/x')}</body>")
    )
    assert "runs Z: champion run 'Z/a' not shown" in result.problems
    assert "runs Z: '2 matching runs' not shown" in result.problems


def test_metric_values_must_follow_the_run_names():
    page = Page(
        "metric Z",
        "http://h/#/metric",
        "05.png",
        (Check("value of 'Z/a'", "Z/a", value=2.1915), Check("value of 'Z/b'", "Z/b", value=2.2)),
    )
    cells = "".join(f"<td>{text}</td>" for text in ("Z/b", "Z/a", "2.192 (step=0)", "Z/b", ""))
    result = check_page(page, parse_dom(f"<body><table><tr>{cells}</tr></table></body>"))
    assert result.found == ["value of 'Z/a'"]
    assert result.problems[0] == "metric Z: value of 'Z/b' not shown"


def test_compare_must_show_one_loaded_heat_map_per_run():
    page = Page(
        "compare Z",
        "http://h/#/compare-runs",
        "03.png",
        image="cross_season_rms.png",
        image_count=3,
        select="cross_season_rms.png",
    )
    images = (
        "".join(f'<img alt="cross_season_rms.png" src="blob:http://h/{i}">' for i in range(3))
        + '<img alt="" src="blob:http://h/0">'
    )
    dom = parse_dom(f"<body>{images}</body>")
    dom.loaded = frozenset({"blob:http://h/0", "blob:http://h/1", "blob:http://h/2"})
    assert check_page(page, dom).found == ["3 of 3 compared runs show image cross_season_rms.png"]
    dom.loaded = frozenset({"blob:http://h/0", "blob:http://h/2"})  # one still loading
    assert check_page(page, dom).problems == [
        "compare Z: 2 of 3 compared runs show image cross_season_rms.png in the Artifacts "
        "section (one loaded image per run expected)"
    ]
    dom = parse_dom("<body><h3>Select a file to preview</h3></body>")
    assert check_page(page, dom).missing == ["0 of 3 compared runs show image cross_season_rms.png"]

"""``make ui-check``: prove in a real browser that the MLflow UI shows the pipeline's runs.

After ``make run`` (its ``track`` stage), ``python -m tests.ui.check`` reads
``reports/mlflow_run.json`` and the store, starts ``mlflow ui`` on the store (a tracking server,
``MLFLOW_TRACKING_URI`` ``http(s)://...``, is used as it is, and so is ``--ui-url``), opens each
page a metrology engineer needs in headless Chromium (driven by Playwright,
:mod:`tests.ui.browser`), writes a screenshot of each to ``reports/ui/`` and checks the rendered
text:

1. ``01_experiment.png``: the experiment, model-training view: its name and description;
2. ``02_runs_ranked_<axis>.png``: the axis' eligible candidates sorted by the metric the
   pipeline ranks them by (parent tag ``ranked_by.<axis>``), best first: the champion and the
   top-ranked runs, in rank order, and the number of eligible runs;
3. ``03_compare_<axis>.png``: the Compare page of the top-ranked candidates (names, ``rank``)
   with ``cross_season_rms.png`` clicked in its Artifacts file tree: one heat-map per run, side
   by side;
4. ``04_champion_model_<axis>.png``: the champion's registered version: name, version,
   description, alias ``champion``, source run;
5. ``05_ranking_metric_<axis>.png``: the ranking metric of the top-ranked candidates;
6. ``06_champion_heatmap_<axis>.png``: the champion's ``cross_season_rms.png``.

It also checks the store's layout (:mod:`tests.ui.expect`) and that the UI server serves each
champion's evidence files. Each problem is one line naming the page (or ``store``, ``record``,
``artifacts``) and what is missing. Exit code 0 when there is none, 1 otherwise, 2 without
Chromium.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

from pipeline.config import DEFAULT_PARAMS
from pipeline.errors import InputDataError, MissingInputError, UserError
from pipeline.machines import machine_key
from pipeline.paths import REPORTS, TRACKING_RECORD
from pipeline.settings.base import load_settings
from pipeline.settings.tracking import DEFAULT_TRACKING_URI, TrackingSettings
from pipeline.tracking.store import public_uri as public
from pipeline.tracking.store import sqlite_path
from tests.helpers.processes import HEALTH_TIMEOUT_S, ServerError, healthy, running_mlflow
from tests.ui import browser
from tests.ui.expect import EVIDENCE, Plan, make_plan, read_store
from tests.ui.pages import Page, check_page, make_pages

PROG = "ui-check"
ENV_TRACKING_URI = "MLFLOW_TRACKING_URI"
DEFAULT_STORE = DEFAULT_TRACKING_URI
SCREENSHOTS = REPORTS / "ui"
BUDGET_MS = 15000
NO_CHROMIUM = (
    "no Chromium found; install Debian's chromium (apt-get install -y chromium) "
    "or set CHROMIUM=/path"
)

Write = Callable[[str], None]


def read_record(path: Path) -> list[dict[str, Any]]:
    """Read ``reports/mlflow_run.json``, written by the ``track`` stage: each machine's record.

    Returns
    -------
    list of dict
        One per machine: its entry with the store and experiment it shares with the others.

    Raises
    ------
    MissingInputError
        If the file is missing.
    InputDataError
        If it is not a JSON object of machines, each with ``experiment_id`` and
        ``parent_run_id``.
    """
    if not path.is_file():
        raise MissingInputError(
            f"{path} not found: run `make run` (or .venv/bin/dvc repro) first; its track stage "
            "logs the runs to MLflow and writes this file"
        )
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputDataError(f"{path} is not valid JSON ({error}); rerun thermal track") from None
    if not isinstance(record, dict) or not isinstance(record.get("machines"), dict):
        raise InputDataError(f"{path} is not a JSON object of machines; rerun thermal track")
    shared = {key: value for key, value in record.items() if key != "machines"}
    entries = [{**shared, **entry} for entry in record["machines"].values()]
    for entry in entries:
        missing = [key for key in ("experiment_id", "parent_run_id") if not entry.get(key)]
        if missing:
            raise InputDataError(
                f"{path}: machine {entry.get('machine')} lacks {', '.join(missing)}; rerun "
                "thermal track"
            )
    if not entries:
        raise InputDataError(f"{path} names no machine's run; rerun thermal track")
    return entries


def resolve_store(
    option: str | None,
    env: Mapping[str, str],
    record: Mapping[str, Any],
    params_path: Path = DEFAULT_PARAMS,
) -> str:
    """Return the tracking store to check; a SQLite path is made absolute.

    Parameters
    ----------
    option : str or None
        ``--tracking-uri``.
    env : mapping
        The environment (``MLFLOW_TRACKING_URI``).
    record : mapping
        ``reports/mlflow_run.json`` (``tracking_uri``: where the track stage logged).
    params_path : Path
        ``params.yaml`` (``tracking.default_tracking_uri``), if it exists.

    Returns
    -------
    str
        The first of ``option``, ``$MLFLOW_TRACKING_URI``, the record's ``tracking_uri``, the
        params default and ``sqlite:///mlflow.db``; a relative SQLite path is taken from the
        working directory, as the track stage does.

    Raises
    ------
    MissingInputError
        If a SQLite store's file does not exist.
    """
    default = DEFAULT_STORE
    if params_path.is_file():
        default = load_settings(TrackingSettings, "tracking", params_path).default_tracking_uri
    uri = option or env.get(ENV_TRACKING_URI) or record.get("tracking_uri") or default
    path = sqlite_path(uri)
    if path is None:
        return uri
    if not Path(path).is_file():
        raise MissingInputError(
            f"no MLflow store at {path} ({uri}): run `make run` first (its track stage fills "
            f"it), or set {ENV_TRACKING_URI} to the store the pipeline logged to"
        )
    return f"sqlite:///{Path(path).resolve().as_posix()}"


def is_server(uri: str) -> bool:
    """Return whether ``uri`` is a tracking server (which serves its own UI)."""
    return uri.startswith(("http://", "https://"))


@contextmanager
def running_mlflow_ui(store_uri: str, timeout_s: float = HEALTH_TIMEOUT_S) -> Iterator[str]:
    """Run ``mlflow ui`` on ``store_uri`` until the ``with`` block ends; yield its base URL.

    The runs' artifacts are served from their own (``file://``) artifact locations; see
    :func:`tests.helpers.processes.running_mlflow`.
    """
    with tempfile.TemporaryDirectory(prefix="thermal-ui-check-") as folder:
        arguments = ["ui", "--backend-store-uri", store_uri]
        with running_mlflow(arguments, Path(folder), timeout_s) as base_url:
            yield base_url


def fetch(url: str, timeout_s: float = 30.0) -> tuple[int, bytes]:
    """GET ``url``; return the HTTP status and body (status 0 when nothing answered)."""
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as response:  # noqa: S310
            return response.status, response.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()
    except (urllib.error.URLError, OSError):
        return 0, b""


def _is_table(body: bytes) -> bool:
    try:
        table = json.loads(body)
    except (json.JSONDecodeError, UnicodeDecodeError):
        return False
    return isinstance(table, dict) and {"columns", "data"} <= set(table)


def evidence_problems(base: str, plan: Plan) -> list[str]:
    """Return a problem for each champion evidence file the UI server does not serve.

    The heat-map must come back as a PNG, the score table as MLflow's table JSON (``columns``,
    ``data``), from the ``get-artifact`` endpoint the UI itself uses.
    """
    problems = []
    for axis in plan.axes:
        champion = axis.champion
        if champion is None:
            continue
        for path in (path for path in EVIDENCE if path in champion.artifacts):
            query = urlencode({"path": path, "run_uuid": champion.run_id})
            status, body = fetch(f"{base}/get-artifact?{query}")
            served = body.startswith(b"\x89PNG") if path.endswith(".png") else _is_table(body)
            if status != 200 or not served:
                problems.append(
                    f"artifacts {axis.axis}: the UI server answers {status or 'nothing'} "
                    f"({len(body)} bytes) for {path} of {champion.name}"
                )
    return problems


def visit(
    pages: Sequence[Page], chromium: str, out: Path, budget_ms: int, write: Write
) -> list[str]:
    """Render each page in one Chromium, write its screenshot and summary; return the problems."""
    problems: list[str] = []
    try:
        with browser.launched(chromium) as running:
            for page in pages:
                screenshot = out / page.screenshot
                write(f"{page.name}\n  {page.url}\n")
                try:
                    dom, notes = browser.render(running, page, screenshot, budget_ms)
                except browser.BrowserError as error:
                    problems.append(f"{page.name}: not rendered: {str(error).splitlines()[0]}")
                    write(f"  not rendered: {error}\n")
                    continue
                result = check_page(page, dom)
                problems += [f"{page.name}: {note}" for note in notes] + result.problems
                write(f"  screenshot {screenshot}\n  found: {'; '.join(result.found) or '-'}\n")
                if result.missing or notes:
                    write(f"  missing: {'; '.join(notes + result.missing)}\n")
    except browser.BrowserError as error:
        problems.append(f"chromium: {str(error).splitlines()[0]}")
    return problems


def run_check(args: argparse.Namespace, chromium: str, write: Write) -> list[str]:
    """Read the record and the store, serve the UI, visit the pages; return the problems."""
    from mlflow import MlflowClient

    records = read_record(args.record)
    store = resolve_store(args.tracking_uri, os.environ, records[0])
    client = MlflowClient(tracking_uri=store, registry_uri=store)
    plans = [make_plan(read_store(client, record), record) for record in records]

    def check(base: str) -> list[str]:
        found = []
        for record, (plan, problems) in zip(records, plans, strict=True):
            out = args.out / machine_key(record["machine"]) if len(records) > 1 else args.out
            pages = make_pages(base, plan, args.top)
            found += (
                problems
                + evidence_problems(base, plan)
                + visit(pages, chromium, out, args.budget_ms, write)
            )
        return found

    if args.ui_url or is_server(store):
        base = (args.ui_url or store).rstrip("/")
        if not healthy(base, timeout_s=10):
            raise InputDataError(f"the MLflow UI at {public(base)} does not answer /health")
        write(f"{PROG}: MLflow UI {public(base)}, store {public(store)}\n")
        return check(base)
    try:
        with running_mlflow_ui(store) as base:
            write(f"{PROG}: started mlflow ui {base} on {store}\n")
            return check(base)
    except ServerError as error:
        raise InputDataError(str(error)) from None


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tracking-uri",
        help=f"store to check (default: ${ENV_TRACKING_URI}, the record's tracking_uri, "
        f"params.yaml tracking.default_tracking_uri, {DEFAULT_STORE})",
    )
    parser.add_argument(
        "--ui-url", help="an MLflow UI already serving that store (default: start mlflow ui)"
    )
    parser.add_argument("--record", type=Path, default=TRACKING_RECORD, help="the track record")
    parser.add_argument("--out", type=Path, default=SCREENSHOTS, help="screenshot folder")
    parser.add_argument(
        "--budget-ms",
        type=int,
        default=BUDGET_MS,
        help="longest wait per page for what it must show, and on Compare for the file tree "
        f"and the images, ms (default {BUDGET_MS})",
    )
    parser.add_argument("--top", type=int, default=3, help="best-ranked runs to compare")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the check; print a summary per page, then one line per problem.

    Returns
    -------
    int
        0 when every page shows what it must, 1 otherwise (or when the record or the store
        cannot be read), 2 without Chromium.
    """
    args = _parse_args(argv)
    chromium = browser.find_chromium()
    if chromium is None:
        sys.stderr.write(f"{PROG}: error: {NO_CHROMIUM}\n")
        return 2

    def write(text: str) -> None:
        sys.stdout.write(text)
        sys.stdout.flush()

    try:
        problems = run_check(args, chromium, write)
    except UserError as error:
        sys.stderr.write(f"{PROG}: error: {error}\n")
        return 1
    if problems:
        sys.stderr.write(
            f"{PROG}: {len(problems)} problem(s):\n"
            + "".join(f"  {problem}\n" for problem in problems)
        )
        return 1
    write(f"{PROG}: every page shows what it must\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``make ui-check``: the MLflow UI in a real Chromium (Playwright), on a real store and mlflow ui.

Fast tests: the store's resolution, credentials kept out of the output, the Chromium lookup, the
exit code without Chromium and without a track record. Slow tests (skipped without Chromium): a
small store in the tracking layout (:mod:`tests.ui.store`, no pipeline run) served by one
``mlflow ui`` for the module; the check passes on it and writes its screenshots, and it fails,
naming the page and the item, when the champion's ranking metric and a heat-map are missing.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.errors import MissingInputError
from tests.helpers.processes import ServerError
from tests.ui.browser import find_chromium
from tests.ui.check import NO_CHROMIUM, public, resolve_store, running_mlflow_ui

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
CHECK = [sys.executable, "-m", "tests.ui.check"]
"""What ``make ui-check`` runs (from the repository root; elsewhere with ``PYTHONPATH``)."""
SCREENSHOTS = (
    "01_experiment.png",
    "02_runs_ranked_Z.png",
    "03_compare_Z.png",
    "04_champion_model_Z.png",
    "05_ranking_metric_Z.png",
    "06_champion_heatmap_Z.png",
)


def _run_check(work: Path, env: dict[str, str], *options: str) -> subprocess.CompletedProcess:
    """Run the check as ``make ui-check`` does, in ``work`` (its ``reports/``)."""
    return subprocess.run(
        [*CHECK, *options],
        cwd=work,
        env={**env, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_resolve_store_order_and_missing_sqlite_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mlflow.db").write_bytes(b"")
    record = {"tracking_uri": "sqlite:///mlflow.db"}
    absolute = f"sqlite:///{(tmp_path / 'mlflow.db').resolve().as_posix()}"
    assert resolve_store(None, {}, record) == absolute
    assert resolve_store(None, {"MLFLOW_TRACKING_URI": "http://srv:5000"}, record) == (
        "http://srv:5000"
    )
    assert resolve_store("https://a", {"MLFLOW_TRACKING_URI": "http://b"}, record) == "https://a"
    with pytest.raises(MissingInputError, match="no MLflow store at other.db"):
        resolve_store("sqlite:///other.db", {}, record)


def test_credentials_are_not_printed():
    assert public("https://me:secret@mlflow.example:5000/") == "https://mlflow.example:5000/"
    assert public("sqlite:////abs/mlflow.db") == "sqlite:////abs/mlflow.db"


def test_without_chromium_the_check_exits_2_with_what_to_do(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "CHROMIUM"}
    env["PATH"] = str(BIN)  # the venv only: no chromium there
    done = _run_check(tmp_path, env)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip() == f"ui-check: error: {NO_CHROMIUM}"


def test_without_a_track_record_the_check_exits_1_with_what_to_do(tmp_path):
    fake = tmp_path / "my-chromium"  # never started: the record is read first
    fake.write_text("#!/bin/sh\nexit 1\n")
    fake.chmod(0o755)
    done = _run_check(tmp_path, {**os.environ, "CHROMIUM": str(fake)})
    assert done.returncode == 1, done.stdout + done.stderr
    assert done.stderr.startswith("ui-check: error: reports/mlflow_run.json not found: run ")
    assert not (tmp_path / "reports" / "ui").exists()


# --- a real browser on a real store -----------------------------------------------------------


@pytest.fixture(scope="module")
def chromium() -> str:
    path = find_chromium()
    if path is None:
        pytest.skip("no Chromium: apt-get install -y chromium, or set CHROMIUM=/path")
    return path


@pytest.fixture(scope="module")
def served_store(tmp_path_factory, chromium):
    """Two executions in one SQLite store, served by one mlflow ui for the module."""
    from tests.ui.store import build_ui_store  # defines an MLflow model class: slow tests only

    root = tmp_path_factory.mktemp("ui-store")
    complete = build_ui_store(root, "thermal-error-ui", "thermal-error-spindle-ui-Z")
    broken = build_ui_store(
        root,
        "thermal-error-ui-broken",
        "thermal-error-spindle-broken-Z",
        drop_champion_metric=True,
        drop_heat_map_rank="2",
    )
    with running_mlflow_ui(complete.tracking_uri) as base:
        yield base, complete, broken


def _ui_check(work: Path, store, base: str) -> subprocess.CompletedProcess:
    from tests.ui.store import write_record

    write_record(work, store.record)
    env = {**os.environ, "MLFLOW_TRACKING_URI": store.tracking_uri}
    return _run_check(work, env, "--ui-url", base)


@pytest.mark.slow
def test_ui_check_passes_and_writes_the_screenshots(tmp_path, served_store):
    base, complete, _ = served_store
    done = _ui_check(tmp_path, complete, base)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "every page shows what it must" in done.stdout
    assert f"found: champion run '{complete.champion_run_name}'" in done.stdout
    compare = done.stdout.split("\ncompare Z\n", 1)[1].split("\nmodel Z\n", 1)[0]
    assert "; 3 of 3 compared runs show image cross_season_rms.png" in compare, compare
    assert "missing:" not in compare, compare
    for name in SCREENSHOTS:
        png = (tmp_path / "reports" / "ui" / name).read_bytes()
        assert png.startswith(b"\x89PNG") and len(png) > 20_000, name


@pytest.mark.slow
def test_ui_check_names_the_missing_ranking_metric_and_heat_map(tmp_path, served_store):
    base, _, broken = served_store
    done = _ui_check(tmp_path, broken, base)
    assert done.returncode == 1, done.stdout + done.stderr
    problems = done.stderr
    assert "store: metric loso_Mn_rms_um missing (axis Z): 1 of 4 child runs" in problems
    assert (
        "runs Z: the first rows show Z/ridge_dl/gra_top_k/static, Z/mlr/best_subset/static, "
        "Z/none/none/static; expected in rank order Z/pls_dl/gra_top_k/static, "
        "Z/ridge_dl/gra_top_k/static, Z/mlr/best_subset/static"
    ) in problems
    assert (
        "metric Z: loso_Mn_rms_um of 'Z/pls_dl/gra_top_k/static' (none in the store) not shown"
    ) in problems
    assert "runs Z: champion run" not in problems  # the champion is listed, only not first
    # The rank-2 run logged no heat-map: Compare's file tree (common files only) cannot list it.
    assert "store: artifact cross_season_rms.png missing: 1 of 5 child runs" in problems
    assert (
        "compare Z: the Artifacts file tree lists no cross_season_rms.png (it lists: " in problems
    )
    assert (
        "compare Z: 0 of 3 compared runs show image cross_season_rms.png in the Artifacts section"
    ) in problems


@pytest.mark.slow
def test_a_server_that_cannot_start_is_reported_with_its_output(tmp_path):
    (tmp_path / "not-a-db.db").write_text("this is not SQLite\n" * 100)
    with pytest.raises(ServerError, match=r"mlflow ui exited with code \d+"):
        with running_mlflow_ui(f"sqlite:///{tmp_path / 'not-a-db.db'}", timeout_s=60):
            pass


def test_chromium_from_the_environment(tmp_path):
    fake = tmp_path / "my-chromium"
    fake.write_text("#!/bin/sh\n")
    fake.chmod(0o755)
    assert find_chromium({"CHROMIUM": str(fake), "PATH": ""}) == str(fake)
    assert find_chromium({"CHROMIUM": str(tmp_path / "none"), "PATH": ""}) is None
    assert find_chromium({"PATH": str(tmp_path)}) is None

"""Warnings counted per fit and candidate, one summary line per stage; progress of long loops."""

from __future__ import annotations

import importlib
import io
import json
import logging
import os
import re
import time
import warnings

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from joblib import delayed

from pipeline import cluster, progress
from pipeline.cli import COMMANDS
from pipeline.errors import ClusterUnreachableError
from pipeline.models.registry import make_model
from pipeline.progress import QUIET_FOR_S, Progress, run_jobs
from pipeline.protocol.champion import choose_champion
from pipeline.protocol.cross_season import Candidate, fit_and_score
from pipeline.protocol.evaluation import AxisEvaluation, fitted_record
from pipeline.protocol.units import campaign_series, training_units
from pipeline.reporting.comparison import score_table
from pipeline.tracking import records
from pipeline.warnings_capture import captured, summarise_warnings
from tests.helpers.processes import free_port

DL, MLR = Candidate("dl", "all"), Candidate("mlr", "all")


def _series(collinear: bool):
    """Two training campaigns and a validation one; T2 = 2 T1 exactly when ``collinear``."""
    frames = []
    for campaign, split, season in [
        ("K1", "train", "winter"),
        ("K2", "train", "summer"),
        ("V1", "validation", "autumn"),
    ]:
        t = np.arange(40) * 180.0
        rise = 8 * (1 - np.exp(-t / 3000))
        other = 2 * rise if collinear else 4 * (1 - np.exp(-t / 9000))
        frames.append(
            pd.DataFrame(
                {
                    "campaign_id": campaign,
                    "split": split,
                    "season": season,
                    "elapsed_s": t,
                    "rise_T1": rise,
                    "rise_T2": other,
                    "thermal_error_um": 3 * rise,
                }
            )
        )
    return campaign_series(pd.concat(frames, ignore_index=True), ["T1", "T2"], "temperature_rise")


def _pooled_fit(candidate: Candidate, collinear: bool):
    series = _series(collinear)
    unit = training_units(series)[-1]
    model = make_model(candidate.model, **({"lag": 1} if candidate.model == "dl" else {}))
    return fit_and_score(candidate, unit, series, model, ["T1", "T2"])


def test_a_fit_on_collinear_temperatures_has_its_warnings_counted_not_printed():
    with warnings.catch_warnings(record=True) as escaped:
        warnings.simplefilter("always")
        result = _pooled_fit(DL, collinear=True)
        clean = _pooled_fit(MLR, collinear=False)
    assert escaped == []
    assert result.warnings.by_category["SingularMatrixWarning"] >= 1
    assert "rank-deficient" in result.warnings.first["SingularMatrixWarning"]
    assert (result.warnings.fits, result.warnings.fits_warned) == (1, 1)
    assert clean.warnings.total == 0 and clean.warnings.text() == "0"


def _summary() -> pd.DataFrame:
    rms = [2.0, 2.5, 10.0]
    return pd.DataFrame(
        {
            "axis": "Z",
            "model": ["dl", "mlr", "none"],
            "selection": ["all", "all", "none"],
            "mode": "static",
            "loco_Mn_rms_um": rms,
            "loco_eta": [1 - r / 10.0 for r in rms],
            "loco_coverage": 1.0,
            "Mn_rms_um": rms,
        }
    )


def test_a_candidates_warnings_reach_its_comparison_row_and_its_child_run_tags():
    results = [_pooled_fit(DL, collinear=True), _pooled_fit(MLR, collinear=False)]
    item = AxisEvaluation("Z", [], [], pd.DataFrame(), results, ranking=None)
    expected = results[0].warnings.text()
    assert re.fullmatch(r"\d+ \(SingularMatrixWarning \d+\)", expected)

    texts = {key: counts.text() for key, counts in item.warnings.items()}
    decision = choose_champion(_summary(), "Z", "loco", 0.1)
    table = score_table(_summary(), decision, warnings=texts).splitlines()
    assert table[0].endswith("| warnings |")
    rows = {line.split(" | ")[0].strip("|* "): line for line in table[2:]}
    assert rows["dl"].endswith(f"| {expected} |")
    assert rows["mlr"].endswith("| 0 |") and rows["none"].endswith("| 0 |")

    fitted = json.loads(json.dumps(fitted_record([item])))  # as track reads the file
    key = ("Z", "dl", "all", "static")
    inputs = records.ChildInputs(
        scores={key: []},
        summaries={},
        groups={},
        units={},
        fits=records.fits_by_candidate(fitted),
        ranked_by={},
        heatmaps={},
    )
    (child,) = records.child_records(inputs)
    assert child.tags[records.WARNINGS_TAG] == expected
    assert "rank-deficient" in child.tags[records.FIRST_WARNINGS_TAG]
    assert child.tables[records.FITS_TABLE][0]["warnings"] == expected


def _pid_after(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


@pytest.fixture
def workers_at_once(monkeypatch):
    """Every call of ``run_jobs`` with more than one job process uses the worker processes."""
    monkeypatch.setattr(progress, "SERIAL_UNDER_S", 0.0)


def test_a_short_loop_runs_in_this_process_and_a_long_one_goes_to_the_workers(monkeypatch):
    monkeypatch.setattr(progress, "_WORKERS", {"started": False})
    quick = run_jobs([delayed(_pid_after)(0.0) for _ in range(6)], 2, "quick")
    assert quick == [os.getpid()] * 6
    assert progress._WORKERS["started"] is False
    monkeypatch.setattr(progress, "SERIAL_UNDER_S", 0.3)
    pids = run_jobs([delayed(_pid_after)(0.1) for _ in range(8)], 2, "slow")
    # the first job here: the other seven (0.7 s) are projected past 0.3 s, so the workers run them
    assert pids[0] == os.getpid() and os.getpid() not in pids[1:]
    assert progress._WORKERS["started"] is True
    assert os.getpid() not in run_jobs([delayed(_pid_after)(0.0)], 2, "again")
    assert run_jobs([delayed(_pid_after)(0.0)], 1, "serial") == [os.getpid()]


def test_a_dask_scheduler_that_does_not_answer_stops_the_loop_with_what_to_do(monkeypatch):
    address = f"tcp://127.0.0.1:{free_port()}"
    monkeypatch.setenv(cluster.SCHEDULER_VARIABLE, address)
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(ClusterUnreachableError) as raised:
        run_jobs([delayed(_pid_after)(0.0) for _ in range(3)], 2, "cluster")
    message = str(raised.value)
    assert f"{cluster.SCHEDULER_VARIABLE}={address}" in message
    assert f"dask worker {address}" in message and "unset" in message
    # one job process: the loop runs here, whatever cluster is named
    assert run_jobs([delayed(_pid_after)(0.0)], 1, "serial") == [os.getpid()]


def test_fits_in_worker_processes_bring_their_warnings_back(workers_at_once):
    series = _series(collinear=True)
    unit = training_units(series)[-1]
    jobs = [
        delayed(fit_and_score)(DL, unit, series, make_model("dl", lag=1), ["T1", "T2"])
        for _ in range(2)
    ]
    with captured() as total:
        results = run_jobs(jobs, 2, "test fits")
    each = [r.warnings.by_category.get("SingularMatrixWarning", 0) for r in results]
    assert min(each) >= 1
    assert total.by_category == {"SingularMatrixWarning": sum(each)}
    assert (total.fits, total.fits_warned) == (2, 2)


def _stage(fits: int):
    @summarise_warnings(details="reports/model_comparison.md")
    def main() -> int:
        for _ in range(fits):
            _pooled_fit(DL, collinear=True)
        _pooled_fit(MLR, collinear=False)
        x = np.arange(10.0)  # a fit of the stage's own, outside the counted fits
        sm.OLS(x**2, np.column_stack([np.ones(10), x, 2 * x])).fit()
        return 0

    return main


def test_a_stage_logs_one_summary_line_and_no_raw_warning(caplog):
    with caplog.at_level(logging.INFO), warnings.catch_warnings(record=True) as escaped:
        warnings.simplefilter("always")
        assert _stage(fits=2)() == 0
    assert escaped == []
    (line,) = [r.getMessage() for r in caplog.records if "warnings" in r.getMessage()]
    assert caplog.records[-1].name == __name__  # the stage module's logger
    assert re.fullmatch(
        r"(\d+) warnings captured \(SingularMatrixWarning \1\); 2 of 3 fits warned, "
        r"per candidate in reports/model_comparison\.md",
        line,
    )
    assert int(line.split()[0]) >= 3  # two fits and the stage's own


def test_every_stage_logs_its_warnings_summary():
    stages = [module for module, _ in COMMANDS.values() if module.startswith("pipeline.stages.")]
    assert len(stages) == 10
    for module in stages:
        main = importlib.import_module(module).main
        assert main.__wrapped__.__module__ == module, module


class _Clock:
    def __init__(self, step: float) -> None:
        self.now, self.step = 0.0, step

    def __call__(self) -> float:
        return self.now


def _count(progress: Progress, clock: _Clock, n: int) -> None:
    for _ in range(n):
        clock.now += clock.step
        progress.update()
    progress.close()


def test_progress_logs_plain_lines_when_stderr_is_not_a_terminal(caplog):
    clock, stream = _Clock(step=2.0), io.StringIO()
    logger = logging.getLogger("test.progress")
    with caplog.at_level(logging.INFO, logger="test.progress"):
        _count(
            Progress("evaluate, axis Z", 40, logger=logger, stream=stream, clock=clock), clock, 40
        )
    lines = [r.getMessage() for r in caplog.records]
    assert stream.getvalue() == ""
    assert all(re.fullmatch(r"evaluate, axis Z: \d+/40 fits \(\d+ %\), .+", x) for x in lines)
    assert lines[0].startswith(f"evaluate, axis Z: {int(QUIET_FOR_S / 2)}/40 fits")
    assert lines[-1] == "evaluate, axis Z: 40/40 fits (100 %), 1 min 20 s"
    assert 4 <= len(lines) <= 11  # every tenth, not every fit


def test_a_short_loop_logs_nothing_and_a_terminal_gets_a_bar(caplog):
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    clock, terminal = _Clock(step=0.1), Terminal()
    with caplog.at_level(logging.INFO):
        _count(Progress("select", 20, "units", stream=io.StringIO(), clock=clock), clock, 20)
        assert caplog.records == []
        _count(Progress("select", 20, "units", stream=terminal, clock=clock), clock, 20)
    assert caplog.records == []
    assert "select:" in terminal.getvalue() and "/20 [" in terminal.getvalue()  # tqdm's bar


@pytest.mark.parametrize(
    ("seconds", "text"), [(12.4, "12 s"), (100, "1 min 40 s"), (7500, "2 h 05 min")]
)
def test_durations_read_as_people_say_them(seconds, text):
    from pipeline.progress import duration_text

    assert duration_text(seconds) == text

"""The compensation runtime: the training code's prediction run incrementally, bounded offsets,
fallbacks when a sensor fails, hold and decay when the source stalls, refused writes survived."""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.compensation.axis import bound
from pipeline.compensation.bundle import read_bundle, write_bundle
from pipeline.compensation.cli import SigtermStop, StoppableSource, StopRequested
from pipeline.compensation.files import CsvTailSource, FileSink, MemorySink, TableSource
from pipeline.compensation.guard import bad_inputs
from pipeline.compensation.replay import replay_axis, replay_run
from pipeline.compensation.report import summary_record
from pipeline.compensation.runtime import CompensationRuntime, EventLog
from pipeline.errors import ParamsError
from pipeline.settings.base import parse_section
from pipeline.settings.compensation import AxisLimits, CompensationSettings
from tests.helpers.compensation_bundle import SENSORS, campaign, fitted_bundle, offline_prediction

ROOT = Path(__file__).resolve().parents[1]
LOOSE = CompensationSettings(
    limits={"default": AxisLimits(max_offset_um=1e6, max_rate_um_per_s=1e6)}
)
HELD_OUT = 9  # a campaign the bundle was not fitted on


@pytest.fixture(scope="module")
def bundle():
    return fitted_bundle()


def _replay(bundle, table, settings, sink=None, **kwargs):
    columns = ["elapsed_s", "rpm", *SENSORS]
    runtime = CompensationRuntime(
        [bundle],
        settings,
        TableSource(table[columns]),
        sink or MemorySink(),
        EventLog(None),
        **kwargs,
    )
    runtime.run()
    return runtime


def test_each_offset_is_the_training_codes_prediction_of_the_run_so_far(bundle):
    table = campaign(HELD_OUT)
    runtime = _replay(bundle, table, LOOSE)
    written = np.array([s.offset_um for s in runtime.steps])
    offline = offline_prediction(bundle, table)
    ready = np.isfinite(offline)
    assert ready[5:].all() and (~ready).sum() <= 3  # the model's lags: a few samples to start
    np.testing.assert_allclose(written[ready][1:], -offline[ready][1:], atol=1e-9)
    assert {s.mode for s in runtime.steps[ready.argmax() + 1 :]} == {"champion"}


def test_the_offset_never_exceeds_its_size_and_rate_limits(bundle):
    table = campaign(HELD_OUT)
    limits = AxisLimits(max_offset_um=20.0, max_rate_um_per_s=0.01)
    runtime = _replay(bundle, table, CompensationSettings(limits={"Z": limits}))
    offsets = np.array([0.0] + [s.offset_um for s in runtime.steps])
    t = table["elapsed_s"].to_numpy()
    assert np.abs(offsets).max() <= 20.0 + 1e-9
    assert (np.abs(np.diff(offsets))[1:] <= 0.01 * np.diff(t) + 1e-9).all()
    assert any(s.limited for s in runtime.steps)  # the limits did bind on this campaign
    assert bound(0.0, 100.0, 10.0, limits) == pytest.approx(0.1)
    assert bound(19.99, 100.0, 1e6, limits) == pytest.approx(20.0)


@pytest.mark.parametrize("fault", [85.0, -127.0, np.nan, 200.0])
def test_a_sensor_lost_mid_run_moves_to_its_fallback_in_the_same_cycle(bundle, fault):
    table = campaign(HELD_OUT)
    lost_at = 80
    table.loc[lost_at:, "T1"] = fault
    settings = CompensationSettings(limits={"default": AxisLimits(max_rate_um_per_s=0.5)})
    runtime = _replay(bundle, table, settings)
    steps = runtime.steps
    assert steps[lost_at - 1].mode == "champion"
    assert steps[lost_at].mode == "fallback" and steps[lost_at].model == "without_T1"
    assert all(s.model == "without_T1" for s in steps[lost_at:])
    fallback = offline_prediction(bundle, campaign(HELD_OUT).drop(columns="T1"), "without_T1")
    late = range(lost_at + 5, len(table))  # past the slew after the switch
    np.testing.assert_allclose([steps[k].offset_um for k in late], -fallback[list(late)], atol=1e-6)
    jumps = np.abs(np.diff([s.offset_um for s in steps]))
    assert jumps.max() <= 0.5 * 60.0 + 1e-9


def test_after_the_sensor_recovers_the_champion_returns_after_the_good_cycles(bundle):
    table = campaign(HELD_OUT)
    table.loc[60:62, "T2"] = np.nan
    runtime = _replay(bundle, table, LOOSE)
    modes = [s.mode for s in runtime.steps]
    assert modes[60:63] == ["fallback"] * 3
    assert modes[63:65] == ["fallback"] * 2 and modes[65] == "champion"  # recover_cycles = 3


def test_two_sensors_lost_hold_the_last_offset_then_decay_it_to_zero(bundle):
    table = campaign(HELD_OUT)
    table.loc[90:, ["T1", "T2"]] = 85.0
    settings = LOOSE.model_copy(update={"hold_s": 600.0, "decay_s": 600.0})
    runtime = _replay(bundle, table, settings)
    steps = runtime.steps
    held = steps[89].offset_um
    assert steps[90].mode == "hold" and steps[90].offset_um == pytest.approx(held)
    assert steps[99].mode == "hold" and steps[101].mode == "decay"
    decayed = steps[-1].offset_um
    elapsed = table["elapsed_s"].iloc[-1] - table["elapsed_s"].iloc[89] - 600.0
    assert decayed == pytest.approx(held * np.exp(-elapsed / 600.0), rel=1e-9)
    assert abs(decayed) < abs(held)


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_a_stalled_source_holds_then_decays_on_the_wall_clock(bundle):
    table = campaign(HELD_OUT).head(60)
    clock = _Clock()
    settings = LOOSE.model_copy(update={"stall_s": 30.0, "hold_s": 120.0, "decay_s": 100.0})
    runtime = CompensationRuntime(
        [bundle],
        settings,
        TableSource(table[["elapsed_s", "rpm", *SENSORS]]),
        MemorySink(),
        EventLog(None),
        clock=clock,
    )
    for _ in range(len(table)):
        runtime.cycle(runtime.source.poll(0.0))
    last = runtime.steps[-1].offset_um
    clock.now += 10.0
    assert runtime.check_stall() == []  # not yet stalled
    clock.now += 50.0
    (step,) = runtime.check_stall()
    assert step.mode == "hold" and step.offset_um == pytest.approx(last)
    clock.now += 200.0
    (step,) = runtime.check_stall()
    assert step.mode == "decay"
    assert step.offset_um == pytest.approx(last * np.exp(-(260.0 - 120.0) / 100.0))
    assert runtime.counts.stalls == 2


class _RefusingSink(MemorySink):
    def __init__(self, refuse):
        super().__init__()
        self.refuse = refuse  # set of call numbers to refuse
        self.calls = 0

    def write(self, t_s, offsets):
        self.calls += 1
        if self.calls in self.refuse or self.refuse == "all":
            raise ConnectionError("BadNotWritable")
        super().write(t_s, offsets)


def test_a_refused_write_is_retried_and_reported_never_a_crash(bundle):
    table = campaign(HELD_OUT).head(40)
    sink = _RefusingSink({10, 11})
    runtime = _replay(bundle, table, LOOSE, sink=sink, sleep=lambda s: None)
    assert len(sink.writes) == 40 and runtime.counts.refused == 2 and runtime.counts.failed == 0
    refused = [e for e in runtime.log.events if e["event"] == "write_refused"]
    assert [e["attempt"] for e in refused] == [1, 2] and "BadNotWritable" in refused[0]["error"]

    never = _RefusingSink("all")
    runtime = _replay(bundle, table, LOOSE, sink=never, sleep=lambda s: None)
    assert never.writes == [] and runtime.counts.failed == 40
    assert runtime.counts.refused == 40 * (1 + LOOSE.write_retries)
    assert all(axis.offset_um == 0.0 for axis in runtime.axes.values())  # nothing was written


def test_stuck_and_out_of_range_readings_are_bad_inputs(bundle):
    table = campaign(HELD_OUT)[["elapsed_s", "rpm", *SENSORS]]
    stuck = table.copy()
    stuck.loc[20:, "T2"] = stuck.loc[20, "T2"]
    checks = bundle.checks
    found = bad_inputs(stuck.head(90), list(SENSORS), checks)
    assert list(found) == ["T2"] and "stuck" in found["T2"]
    assert bad_inputs(stuck.head(60), list(SENSORS), checks) == {}  # 40 samples, 40 min: not yet
    hot = table.head(30).copy()
    hot.loc[29, "T1"] = hot.loc[0, "T1"] + 40.0
    found = bad_inputs(hot, list(SENSORS), checks, ranges=bundle.input_ranges)
    assert list(found) == ["T1"] and "range seen in training" in found["T1"]


def test_a_growing_csv_is_read_row_by_row_and_a_half_written_line_waits(tmp_path):
    path = tmp_path / "logger.csv"
    path.write_text("elapsed_s,rpm,T1\n0,1000,20.5\n60,1000,20.6\n60")
    source = CsvTailSource(path, follow=True, poll_s=0.01)
    first = source.poll(0.0)
    assert [r.t_s for r in first] == [0.0, 60.0] and first[1].values == {"rpm": 1000.0, "T1": 20.6}
    assert source.poll(0.05) == []
    with path.open("a") as handle:
        handle.write(",1000,\n")
    (row,) = source.poll(0.0)
    assert row.t_s == 60.0 and np.isnan(row.values["T1"])  # an empty cell is a missing reading


def test_settings_name_the_wrong_key_path_and_the_keys_allowed():
    with pytest.raises(
        ParamsError,
        match=r"compensation\.limits\.Z\.max_rate: unknown key \(did you mean "
        r"'max_rate_um_per_s'\?\); allowed here: max_offset_um, max_rate_um_per_s",
    ):
        parse_section(CompensationSettings, "compensation", {"limits": {"Z": {"max_rate": 1.0}}})
    with pytest.raises(ParamsError, match=r"compensation\.hold_s = -1; input should be greater"):
        parse_section(CompensationSettings, "compensation", {"hold_s": -1})
    with pytest.raises(ParamsError, match=r"compensation\.offset_sign = 2; use -1 \(write the"):
        parse_section(CompensationSettings, "compensation", {"offset_sign": 2})
    settings = parse_section(
        CompensationSettings, "compensation", {"limits": {"Z": {"max_offset_um": 50.0}}}
    )
    assert settings.limits_of("Z").max_offset_um == 50.0
    assert settings.limits_of("X") == AxisLimits()


def test_thermal_compensate_runs_a_bundle_on_a_logger_file(bundle, tmp_path):
    folder = tmp_path / "bundle" / "Z"
    write_bundle(folder, bundle)
    assert read_bundle(folder).fallbacks[0].name == "without_T1"
    table = campaign(HELD_OUT).head(50)
    table.loc[30:, "T3"] = -127.0
    logger = tmp_path / "logger.csv"
    table[["elapsed_s", "rpm", *SENSORS]].to_csv(logger, index=False)
    out, events = tmp_path / "offsets.csv", tmp_path / "events.jsonl"
    result = subprocess.run(
        [
            str(ROOT / "bin" / "thermal"),
            "compensate",
            "--bundle",
            str(folder),
            "--source",
            f"csv:{logger}",
            "--no-follow",
            "--sink",
            f"csv:{out}",
            "--log",
            str(events),
            "--params",
            str(tmp_path / "none.yaml"),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "50 cycles, 50 writes" in result.stdout and "fallback 20" in result.stdout
    written = pd.read_csv(out)
    assert len(written) == 50 and set(written["axis"]) == {"Z"}
    logged = [json.loads(line) for line in events.read_text().splitlines()]
    modes = [e for e in logged if e["event"] == "mode"]
    assert [(e["mode"], e["model"]) for e in modes] == [
        ("champion", "champion"),
        ("fallback", "without_T3"),
    ]
    assert modes[1]["t_s"] == 30 * 60.0 and "-127" in modes[1]["reason"]
    assert sum(e["event"] == "write" for e in logged) == 50
    sink = FileSink(tmp_path / "offsets.jsonl")
    sink.write(1.0, {"Z": -2.5})
    sink.close()
    assert json.loads((tmp_path / "offsets.jsonl").read_text())["offsets_um"] == {"Z": -2.5}


def test_a_campaign_late_in_a_run_is_replayed_with_the_runs_past_read_first(bundle):
    first, second = campaign(HELD_OUT), campaign(HELD_OUT + 1)
    second["elapsed_s"] += first["elapsed_s"].iloc[-1] + 60.0
    run = pd.concat([first, second], ignore_index=True)
    run = run.assign(run_elapsed_s=run["elapsed_s"])
    scored = np.arange(len(run)) >= len(first)
    every = replay_run(bundle, run, LOOSE)
    late = replay_run(bundle, run, LOOSE, scored=scored)
    assert list(late.index) == list(run.index[scored])
    np.testing.assert_allclose(late["offset_um"], every.loc[scored, "offset_um"], atol=1e-9)
    assert set(late["mode"]) == {"champion"}


class _FlakySource(TableSource):
    def __init__(self, table, failures):
        super().__init__(table)
        self.failures = failures

    def poll(self, timeout_s):
        if self.failures:
            self.failures -= 1
            raise ConnectionError("BadConnectionClosed")
        return super().poll(timeout_s)


def test_a_failing_source_is_logged_and_the_runtime_goes_on(bundle):
    table = campaign(HELD_OUT).head(10)[["elapsed_s", "rpm", *SENSORS]]
    runtime = CompensationRuntime(
        [bundle],
        LOOSE,
        _FlakySource(table, 2),
        MemorySink(),
        EventLog(None),
        sleep=lambda s: None,
    )
    runtime.run()
    assert runtime.counts.source_errors == 2 and runtime.counts.writes == 10
    errors = [e for e in runtime.log.events if e["event"] == "source_error"]
    assert len(errors) == 2 and "BadConnectionClosed" in errors[0]["error"]


class _StopOnWrite(MemorySink):
    """A sink during whose ``at``-th write SIGTERM comes (its handler is called)."""

    def __init__(self, stop: SigtermStop, at: int) -> None:
        super().__init__()
        self.stop, self.at = stop, at

    def write(self, t_s, offsets):
        super().write(t_s, offsets)
        if len(self.writes) == self.at:
            self.stop.request(signal.SIGTERM, None)


class _StopWhileWaiting(TableSource):
    """A source during whose wait after ``at`` readings SIGTERM comes."""

    def __init__(self, table, stop: SigtermStop, at: int) -> None:
        super().__init__(table)
        self.stop, self.at, self.given = stop, at, 0

    def poll(self, timeout_s):
        if self.given == self.at:
            self.stop.request(signal.SIGTERM, None)  # raises: the runtime was waiting
        readings = super().poll(timeout_s)
        self.given += len(readings)
        return readings


def test_sigterm_ends_a_wait_at_once_and_a_cycle_only_after_its_write(bundle):
    table = campaign(HELD_OUT).head(10)[["elapsed_s", "rpm", *SENSORS]]
    during_cycle = SigtermStop()
    sink = _StopOnWrite(during_cycle, at=3)
    runtime = CompensationRuntime(
        [bundle], LOOSE, StoppableSource(TableSource(table), during_cycle), sink, EventLog(None)
    )
    with pytest.raises(StopRequested):
        runtime.run()
    assert len(sink.writes) == 3 and runtime.counts.writes == 3  # the third cycle wrote
    assert runtime.log.events[-1]["event"] == "stop"

    while_waiting = SigtermStop()
    source = StoppableSource(_StopWhileWaiting(table, while_waiting, at=4), while_waiting)
    runtime = CompensationRuntime([bundle], LOOSE, source, MemorySink(), EventLog(None))
    with pytest.raises(StopRequested):
        runtime.run()
    assert runtime.counts.cycles == 4 and not while_waiting.waiting
    assert runtime.log.events[-1]["event"] == "stop"


def test_an_axis_without_held_out_campaigns_has_an_empty_proof_that_says_so(bundle):
    rows = campaign(HELD_OUT).assign(campaign_id="C9", run_id="C9", season="winter")
    proof = replay_axis(bundle, rows, {}, pd.DataFrame(), LOOSE)
    assert proof.table.empty and proof.traces.empty and proof.summary == {}
    assert list(proof.traces.groupby("campaign_id")) == []
    record = summary_record(bundle, proof, {"linear": False}, {})
    assert record["headline"] == "dl/test/static: no held-out campaign to replay"


def test_the_runtime_benchmark_times_a_cycle_after_each_run_length():
    from benchmarks.runtime_bench import cycle_times, report_lines

    times = cycle_times(samples=(30, 90), repeats=2)
    assert [t["samples"] for t in times] == [30, 90]
    assert [t["hours"] for t in times] == pytest.approx([30 * 20 / 3600, 90 * 20 / 3600])
    assert all(t["ms_per_cycle"] > 0 for t in times)
    assert len(report_lines(times)) == 3 and "0.5 h" in report_lines(times)[2]

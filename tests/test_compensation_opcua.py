"""A real OPC UA controller stand-in: a held-out campaign replayed into its sensor nodes, the
runtime (``thermal compensate``, its own process) writing offsets back, a sensor going bad."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from asyncua import ua
from asyncua.sync import Client

from pipeline.compensation.axis import bound
from pipeline.compensation.bundle import write_bundle
from pipeline.compensation.opcua import NodeMap, OpcUaSource
from pipeline.settings.compensation import CompensationSettings
from tests.helpers.compensation_bundle import SENSORS, campaign, fitted_bundle, offline_prediction
from tests.helpers.processes import free_port, stop_group

ROOT = Path(__file__).resolve().parents[1]
HELD_OUT, LOST_AT, LOST = 9, 70, "T1"


def _start(command: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen(
        command, cwd=ROOT, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True
    )


def _wait_for(predicate, timeout_s: float, what: str, logs: list[Path]) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.01)
    text = "\n".join(f"--- {p.name}\n{p.read_text()[-3000:]}" for p in logs if p.is_file())
    raise AssertionError(f"timed out waiting for {what}\n{text}")


def _double(value: float, status=ua.StatusCodes.Good) -> ua.DataValue:
    return ua.DataValue(ua.Variant(float(value), ua.VariantType.Double), ua.StatusCode(status))


def _replay(client: Client, table, logs: list[Path]) -> list[float]:
    nodes = {name: client.get_node(f"ns=2;s={name}") for name in (*SENSORS, "rpm", "elapsed_s")}
    offset = client.get_node("ns=2;s=offset_Z")
    answered = client.get_node("ns=2;s=compensation_t_s")
    inputs = [nodes[name] for name in (*SENSORS, "rpm")]
    written = []
    for k, row in enumerate(table.itertuples()):
        values = []
        for name in (*SENSORS, "rpm"):
            bad = name == LOST and k >= LOST_AT
            status = ua.StatusCodes.BadSensorFailure if bad else ua.StatusCodes.Good
            values.append(_double(getattr(row, name), status))
        client.write_values(inputs, values)  # one request, as a controller's cycle writes them
        t = float(row.elapsed_s) + 1.0  # the server's variables start at 0.0
        nodes["elapsed_s"].write_value(_double(t))
        _wait_for(lambda t=t: answered.read_value() == t, 20.0, f"the write of t={t}", logs)
        written.append(float(offset.read_value()))
    return written


def _expected(bundle, table) -> np.ndarray:
    """The offline predictions, champion then fallback from the loss, through the limits."""
    champion = offline_prediction(bundle, table)
    fallback = offline_prediction(bundle, table.drop(columns=LOST), f"without_{LOST}")
    predicted = np.where(np.arange(len(table)) < LOST_AT, champion, fallback)
    limits, out, previous = CompensationSettings().limits_of("Z"), [], 0.0
    t = table["elapsed_s"].to_numpy()
    target = 0.0
    for k in range(len(table)):
        target = -predicted[k] if np.isfinite(predicted[k]) else target
        previous = bound(previous, target, t[k] - t[k - 1] if k else 0.0, limits)
        out.append(previous)
    return np.array(out)


@pytest.mark.slow
def test_the_runtime_compensates_a_replayed_campaign_through_a_real_opcua_server(tmp_path):
    bundle = fitted_bundle()
    folder = tmp_path / "Z"
    write_bundle(folder, bundle)
    table = campaign(HELD_OUT, n=120)
    port = free_port()
    url = f"opc.tcp://127.0.0.1:{port}/controller"
    server_log, runtime_log, events = (
        tmp_path / "server.log",
        tmp_path / "runtime.log",
        tmp_path / "events.jsonl",
    )
    logs = [server_log, runtime_log]
    server = _start(
        [sys.executable, "-m", "tests.helpers.opcua_controller", str(port), *SENSORS], server_log
    )
    runtime = None
    try:
        _wait_for(lambda: "ready ns=2" in server_log.read_text(), 30.0, "the server", logs)
        runtime = _start(
            [
                str(ROOT / "bin" / "thermal"),
                "compensate",
                "--bundle",
                str(folder),
                "--source",
                url,
                "--sink",
                url,
                "--log",
                str(events),
                "--params",
                str(tmp_path / "none.yaml"),
            ],
            runtime_log,
        )
        client = Client(url, timeout=4)
        client.connect()
        try:
            _wait_for(
                lambda: events.is_file() and "start" in events.read_text(),
                60.0,
                "the runtime",
                logs,
            )
            written = _replay(client, table, logs)
        finally:
            client.disconnect()
        os.killpg(runtime.pid, 15)
        # it waits up to cycle_s (10 s) for the next reading: SIGTERM ends that wait at once
        assert runtime.wait(timeout=8) == 0, runtime_log.read_text()
    finally:
        for process in (runtime, server):
            if process is not None:
                stop_group(process)
    np.testing.assert_allclose(written, _expected(bundle, table), atol=1e-6)
    step = np.abs(np.diff([0.0, *written]))
    assert step.max() <= 0.5 * 60.0 + 1e-9
    logged = [json.loads(line) for line in events.read_text().splitlines()]
    modes = [(e["t_s"], e["mode"], e["model"]) for e in logged if e["event"] == "mode"]
    t_lost = float(table["elapsed_s"].iloc[LOST_AT]) + 1.0
    assert modes == [(1.0, "champion", "champion"), (t_lost, "fallback", f"without_{LOST}")]
    assert sum(e["event"] == "write" for e in logged) == len(table)
    output = runtime_log.read_text()
    assert "120 cycles, 120 writes, 0 refused" in output and "stopped by SIGTERM" in output
    assert "asyncua" not in output  # its chatter (two lines per cycle) is not the user's


@pytest.mark.slow
def test_the_time_found_at_connection_is_not_a_reading_whenever_its_notification_comes(tmp_path):
    port = free_port()
    url = f"opc.tcp://127.0.0.1:{port}/controller"
    log = tmp_path / "server.log"
    server = _start([sys.executable, "-m", "tests.helpers.opcua_controller", str(port), "T1"], log)
    try:
        _wait_for(lambda: "ready ns=2" in log.read_text(), 30.0, "the server", [log])
        source = OpcUaSource(url, NodeMap.defaults(["T1"], ["Z"], speed=False), publishing_ms=20)
        client = Client(url, timeout=4)
        client.connect()
        try:
            time.sleep(0.5)  # the subscription's first notification (t = 0.0) has come
            assert source.poll(0.2) == []
            client.get_node("ns=2;s=T1").write_value(_double(21.5))
            client.get_node("ns=2;s=elapsed_s").write_value(_double(1.0))
            readings = source.poll(5.0)
        finally:
            client.disconnect()
            source.close()
    finally:
        stop_group(server)
    assert [(r.t_s, r.values) for r in readings] == [(1.0, {"T1": 21.5})]


@pytest.mark.slow
def test_a_controller_refusing_the_offset_is_reported_and_the_runtime_keeps_running(tmp_path):
    read_only = "Z"
    bundle = fitted_bundle()
    folder = tmp_path / "Z"
    write_bundle(folder, bundle)
    port = free_port()
    url = f"opc.tcp://127.0.0.1:{port}/controller"
    server_log, events = tmp_path / "server.log", tmp_path / "events.jsonl"
    server = _start(
        [
            sys.executable,
            "-m",
            "tests.helpers.opcua_controller",
            str(port),
            *SENSORS,
            "--read-only-axis",
            read_only,
        ],
        server_log,
    )
    try:
        _wait_for(lambda: "ready ns=2" in server_log.read_text(), 30.0, "the server", [server_log])
        logger = tmp_path / "logger.csv"
        campaign(HELD_OUT, n=5)[["elapsed_s", "rpm", *SENSORS]].to_csv(logger, index=False)
        params = tmp_path / "params.yaml"
        params.write_text("compensation:\n  retry_wait_s: 0.01\n")
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
                url,
                "--log",
                str(events),
                "--params",
                str(params),
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    finally:
        stop_group(server)
    assert result.returncode == 0, result.stderr
    assert "5 cycles, 0 writes, 20 refused, 5 failed" in result.stdout
    logged = [json.loads(line) for line in events.read_text().splitlines()]
    refused = [e for e in logged if e["event"] == "write_refused"]
    assert len(refused) == 20 and "BadUserAccessDenied" in refused[0]["error"]


@pytest.mark.slow
def test_a_controller_that_restarts_stalls_the_runtime_which_reconnects(tmp_path):
    bundle = fitted_bundle()
    folder = tmp_path / "Z"
    write_bundle(folder, bundle)
    table = campaign(HELD_OUT, n=20)
    params = tmp_path / "params.yaml"
    params.write_text("compensation:\n  stall_s: 1.0\n  cycle_s: 0.2\n  retry_wait_s: 0.05\n")
    port = free_port()
    url = f"opc.tcp://127.0.0.1:{port}/controller"
    logs = [tmp_path / "server.log", tmp_path / "runtime.log"]
    events = tmp_path / "events.jsonl"
    command = [sys.executable, "-m", "tests.helpers.opcua_controller", str(port), *SENSORS]
    server = _start(command, logs[0])
    runtime = None
    try:
        _wait_for(lambda: "ready ns=2" in logs[0].read_text(), 30.0, "the server", logs)
        runtime = _start(
            [
                str(ROOT / "bin" / "thermal"),
                "compensate",
                "--bundle",
                str(folder),
                "--source",
                url,
                "--sink",
                url,
                "--log",
                str(events),
                "--params",
                str(params),
            ],
            logs[1],
        )
        _wait_for(
            lambda: events.is_file() and "start" in events.read_text(), 60.0, "the runtime", logs
        )
        for part in (table.iloc[:10], table.iloc[10:]):
            client = Client(url, timeout=4)
            client.connect()
            try:
                _replay(client, part, logs)
            finally:
                client.disconnect()
            if part.index[0] == 0:
                stop_group(server)
                _wait_for(lambda: "source_error" in events.read_text(), 30.0, "a stall", logs)
                server = _start(command, logs[0])
                _wait_for(lambda: logs[0].read_text().count("ready") == 1, 30.0, "restart", logs)
        os.killpg(runtime.pid, 15)
        assert runtime.wait(timeout=30) == 0, logs[1].read_text()
    finally:
        for process in (runtime, server):
            if process is not None:
                stop_group(process)
    logged = [json.loads(line) for line in events.read_text().splitlines()]
    kinds = [e["event"] for e in logged]
    assert "source_error" in kinds and kinds.count("write") >= 20
    assert kinds.index("source_error") < max(i for i, k in enumerate(kinds) if k == "write")

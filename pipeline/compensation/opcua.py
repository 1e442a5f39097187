"""OPC UA source and sink of the compensation runtime (``asyncua``'s synchronous client).

A controller (or the PLC in front of it) publishes the machine's temperatures, spindle speed
and, ideally, a time node, and takes per-axis offsets. The node ids come from a node map (YAML,
``--nodes``), by default ``ns=2;s=<name>``:

.. code-block:: yaml

    sensors: {T1: "ns=2;s=T1", T2: "ns=2;s=T2"}  # every sensor the models read
    rpm: "ns=2;s=rpm"
    time: "ns=2;s=elapsed_s"      # optional: a reading is taken when it changes
    offsets: {Z: "ns=2;s=offset_Z"}
    cycle: "ns=2;s=compensation_t_s"  # optional: the machine time each write answers

- :class:`OpcUaSource`: with a ``time`` node, a subscription on it; each change is one reading
  (every sensor node read at once, a value with a bad status counts as missing). The time found
  when the runtime first connects is not a change: the first reading is the next machine time,
  whether the subscription's first notification comes before or after it. Without one,
  the nodes are read every ``cycle_s`` and the reading's time is the wall clock.
- :class:`OpcUaSink`: writes each axis' offset (Double, um) to its node, then the cycle node; a
  refused write raises, and the runtime retries and reports it.
"""

from __future__ import annotations

import logging
import queue
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml
from asyncua import ua
from asyncua.sync import Client

from pipeline.compensation.runtime import Reading
from pipeline.errors import InputDataError

LOGGER = logging.getLogger(__name__)
DEFAULT_NAMESPACE = 2


def default_node(name: str) -> str:
    """Return the default node id of a variable named ``name`` (``ns=2;s=<name>``)."""
    return f"ns={DEFAULT_NAMESPACE};s={name}"


@dataclass(frozen=True)
class NodeMap:
    """Node ids of the inputs and outputs.

    Attributes
    ----------
    sensors : dict of str to str
        Sensor -> node id (degC).
    rpm : str or None
        Spindle speed node (rpm).
    time : str or None
        Machine time node (s); None: readings on the wall clock every cycle.
    offsets : dict of str to str
        Axis -> node id the offset (um) is written to.
    cycle : str or None
        Node the machine time of each write goes to, after the offsets.
    """

    sensors: dict[str, str]
    rpm: str | None
    time: str | None
    offsets: dict[str, str]
    cycle: str | None = None

    @classmethod
    def defaults(cls, sensors: list[str], axes: list[str], speed: bool) -> NodeMap:
        """Return the default map: ``ns=2;s=<name>``, ``offset_<axis>``, ``elapsed_s``."""
        return cls(
            {s: default_node(s) for s in sensors},
            default_node("rpm") if speed else None,
            default_node("elapsed_s"),
            {a: default_node(f"offset_{a}") for a in axes},
            default_node("compensation_t_s"),
        )

    @classmethod
    def from_file(cls, path: Path, sensors: list[str], axes: list[str], speed: bool) -> NodeMap:
        """Read a YAML node map; entries it leaves out take the defaults.

        Raises
        ------
        InputDataError
            For an unknown key or a sensor or axis the models need and the map cannot name.
        """
        record = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
        allowed = {"sensors", "rpm", "time", "offsets", "cycle"}
        unknown = sorted(set(record) - allowed)
        if unknown:
            raise InputDataError(
                f"{path}: unknown key(s) {unknown}; a node map has {sorted(allowed)}"
            )
        base = cls.defaults(sensors, axes, speed)
        return cls(
            {**base.sensors, **(record.get("sensors") or {})},
            record.get("rpm", base.rpm),
            record.get("time", base.time),
            {**base.offsets, **(record.get("offsets") or {})},
            record.get("cycle", base.cycle),
        )


def _dropped(client: Client) -> None:
    """Disconnect a lost connection as far as it still can; return None (reopened later)."""
    try:
        client.disconnect()
    except Exception:  # already gone: nothing to release
        LOGGER.debug("disconnecting a lost OPC UA connection failed", exc_info=True)


class _TimeHandler:
    """Subscription handler: each new value of the time node goes to a queue."""

    def __init__(self) -> None:
        self.times: queue.Queue = queue.Queue()

    def datachange_notification(self, node, value, data) -> None:
        """Queue the new machine time."""
        self.times.put(value)


class OpcUaSource:
    """Readings from an OPC UA server (see the module docstring).

    Parameters
    ----------
    url : str
        ``opc.tcp://host:port/...``.
    nodes : NodeMap
    publishing_ms : float
        Requested publishing interval of the subscription, ms.
    """

    def __init__(self, url: str, nodes: NodeMap, publishing_ms: float = 50.0) -> None:
        self.url, self.nodes, self.publishing_ms = url, nodes, publishing_ms
        self._names = list(nodes.sensors) + (["rpm"] if nodes.rpm else [])
        self._ids = list(nodes.sensors.values()) + ([nodes.rpm] if nodes.rpm else [])
        self._handler = _TimeHandler()
        self._last_time: float | None = None
        self.client: Client | None = None
        self._connect()

    def _connect(self) -> None:
        """Connect, and subscribe to the time node when there is one."""
        self.client = Client(self.url, timeout=4)
        self.client.connect()
        self._nodes = [self.client.get_node(node_id) for node_id in self._ids]
        self._subscription = None
        if self.nodes.time:
            time_node = self.client.get_node(self.nodes.time)
            if self._last_time is None:
                found = time_node.read_value()
                self._last_time = float(found) if isinstance(found, int | float) else None
            self._subscription = self.client.create_subscription(self.publishing_ms, self._handler)
            self._subscription.subscribe_data_change(time_node)

    @property
    def exhausted(self) -> bool:
        """A server never runs out."""
        return False

    def poll(self, timeout_s: float) -> list[Reading]:
        """Return a reading per change of the time node (or one per call without a time node).

        A connection found lost is reopened first; a failure raises (the runtime logs it and
        counts the source as silent).
        """
        if self.client is None:
            self._connect()
        try:
            self.client.check_connection()
        except Exception:
            self.client = _dropped(self.client)
            raise
        if self._subscription is None:
            time.sleep(timeout_s)
            return [Reading(time.time(), self._read(), None)]
        times = []
        try:
            times.append(self._handler.times.get(timeout=timeout_s))
            while True:
                times.append(self._handler.times.get_nowait())
        except queue.Empty:
            pass
        fresh = [float(t) for t in times if t is not None and float(t) != self._last_time]
        if not fresh:
            return []
        self._last_time = fresh[-1]
        return [Reading(fresh[-1], self._read(), None)]

    def _read(self) -> dict[str, float]:
        values = self.client.read_attributes(self._nodes, ua.AttributeIds.Value)
        out = {}
        for name, value in zip(self._names, values, strict=True):
            good = value.StatusCode is None or value.StatusCode.is_good()
            number = value.Value.Value if good and value.Value is not None else None
            out[name] = float(number) if isinstance(number, int | float) else float("nan")
        return out

    def close(self) -> None:
        """Delete the subscription and disconnect."""
        if self.client is None:
            return
        try:
            if self._subscription is not None:
                self._subscription.delete()
        finally:
            self.client.disconnect()


class OpcUaSink:
    """Per-axis offsets written to an OPC UA server (Double, um).

    A write that fails on a lost connection drops it; the next write reconnects.
    """

    def __init__(self, url: str, nodes: NodeMap) -> None:
        self.url, self.nodes = url, nodes
        self.client: Client | None = None
        self._connect()

    def _connect(self) -> None:
        self.client = Client(self.url, timeout=4)
        self.client.connect()
        self._offsets = {a: self.client.get_node(n) for a, n in self.nodes.offsets.items()}
        self._cycle = self.client.get_node(self.nodes.cycle) if self.nodes.cycle else None

    def write(self, t_s: float, offsets: Mapping[str, float]) -> None:
        """Write every axis' offset, then the cycle node; raises when the server refuses."""
        missing = [axis for axis in offsets if axis not in self.nodes.offsets]
        if missing:
            raise InputDataError(f"no offset node for axis {missing}; add it to the node map")
        if self.client is None:
            self._connect()
        try:
            self.client.check_connection()
        except Exception:
            self.client = _dropped(self.client)
            raise
        for axis, offset in offsets.items():
            self._offsets[axis].write_value(
                ua.DataValue(ua.Variant(float(offset), ua.VariantType.Double))
            )
        if self._cycle is not None:
            self._cycle.write_value(ua.DataValue(ua.Variant(float(t_s), ua.VariantType.Double)))

    def close(self) -> None:
        """Disconnect."""
        if self.client is not None:
            self.client.disconnect()

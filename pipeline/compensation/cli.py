"""``thermal compensate``: run the compensation between a source of readings and a sink.

Examples::

    # a logger's CSV file as it grows -> offsets logged to a CSV file
    thermal compensate --source csv:logger/today.csv --sink csv:offsets.csv
    # a controller's OPC UA server, both ways, models of the MLflow registry's @champion
    thermal compensate --source opc.tcp://10.0.0.5:4840 --sink opc.tcp://10.0.0.5:4840 \
        --registry --nodes nodes.yaml

Models: each axis' bundle of the machine under ``data/models/compensation/<machine>/<axis>/``
(written by ``dvc repro``), ``--bundle DIR`` for bundles copied elsewhere, or ``--registry``: the
version of ``<registered model>-<machine>-<axis>`` under the alias ``champion`` (its run's
``compensation/bundle`` artifacts), from ``$MLFLOW_TRACKING_URI`` or ``params.yaml``
``tracking``. ``--machine`` names the machine compensated; it may be left out when the pipeline
(or the registry) has one machine only. Limits and fallback
timing: ``params.yaml`` ``compensation`` (``--params``), else the defaults
(:class:`pipeline.settings.compensation.CompensationSettings`). Every event goes to ``--log``
(JSON lines).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import tempfile
from pathlib import Path

from pipeline import paths
from pipeline.compensation.bundle import AxisBundle, bundle_axes, read_bundle
from pipeline.compensation.files import CsvTailSource, FileSink
from pipeline.compensation.opcua import NodeMap, OpcUaSink, OpcUaSource
from pipeline.compensation.runtime import CompensationRuntime, EventLog, Reading, Source
from pipeline.config import load_section
from pipeline.errors import MissingInputError, ParamsError
from pipeline.machines import machine_key, one_machine
from pipeline.settings.base import load_settings, parse_section
from pipeline.settings.compensation import CompensationSettings
from pipeline.settings.track import TrackSettings
from pipeline.settings.tracking import TrackingSettings
from pipeline.tracking.champion_model import download_bundle, registered_targets
from pipeline.tracking.location import resolve_tracking_uri

LOGGER = logging.getLogger(__name__)
OPCUA_SCHEME = "opc.tcp://"
DEFAULT_LOG = Path("reports/compensation_events.jsonl")
"""The event log when ``--log`` is not given (not a stage output; git-ignored)."""


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="thermal compensate",
        description="Read the machine's inputs, write each axis' bounded thermal offset.",
    )
    parser.add_argument(
        "--source", required=True, help="csv:<file a logger appends to> or opc.tcp://host:port"
    )
    parser.add_argument(
        "--sink", required=True, help="csv:<file>, jsonl:<file> or opc.tcp://host:port"
    )
    models = parser.add_mutually_exclusive_group()
    models.add_argument("--bundle", action="append", type=Path, help="a bundle folder (repeat)")
    models.add_argument("--registry", action="store_true", help="the registry's @champion")
    parser.add_argument("--machine", help="the machine compensated (needed when there are several)")
    parser.add_argument("--axis", action="append", help="only these axes (repeat)")
    parser.add_argument("--alias", default="champion", help="registry alias (champion)")
    parser.add_argument("--nodes", type=Path, help="OPC UA node map (YAML)")
    parser.add_argument(
        "--params", type=Path, default=Path("params.yaml"), help="limits: its compensation section"
    )
    parser.add_argument("--log", type=Path, default=DEFAULT_LOG, help="event log (JSON lines)")
    parser.add_argument(
        "--no-follow", action="store_true", help="csv source: stop at the end of the file"
    )
    parser.add_argument("--max-cycles", type=int, help="stop after this many cycles")
    return parser.parse_args(argv)


def runtime_settings(params: Path) -> CompensationSettings:
    """Return the ``compensation`` section of ``params`` if the file has one, else the defaults.

    Raises
    ------
    ParamsError
        If the section is there and anything in it is wrong.
    """
    if not params.is_file():
        return CompensationSettings()
    try:
        section = load_section("compensation", params)
    except ParamsError:
        return CompensationSettings()
    return parse_section(CompensationSettings, "compensation", section, params)


def load_bundles(args: argparse.Namespace, workdir: Path) -> list[AxisBundle]:
    """Return the bundles asked for (``--bundle``, ``--registry`` or the pipeline's), per axis."""
    if args.bundle:
        bundles = [read_bundle(folder) for folder in args.bundle]
    elif args.registry:
        bundles = registry_bundles(args, workdir)
    else:
        machine = one_machine(args.machine, pipeline_machines(), "the pipeline's bundles")
        root = paths.COMPENSATION_BUNDLES / machine_key(machine)
        axes = bundle_axes(root)
        if not axes:
            raise MissingInputError(
                f"no bundle under {root}; run `dvc repro` first, or give --bundle DIR or --registry"
            )
        bundles = [read_bundle(root / axis) for axis in axes]
    if args.axis:
        bundles = [b for b in bundles if b.axis in args.axis]
    if not bundles:
        raise MissingInputError(f"no bundle for axis {args.axis}")
    return bundles


def pipeline_machines() -> list[str]:
    """Return the machines with a bundle under ``data/models/compensation/``, by folder name."""
    root = paths.COMPENSATION_BUNDLES
    return sorted(p.name for p in root.iterdir() if p.is_dir()) if root.is_dir() else []


def registry_bundles(args: argparse.Namespace, workdir: Path) -> list[AxisBundle]:
    """Download the bundle of each axis of the machine's ``--alias`` versions in the registry."""
    tracking, track = TrackingSettings(), TrackSettings()
    if args.params.is_file():
        tracking = load_settings(TrackingSettings, "tracking", args.params)
        track = load_settings(TrackSettings, "track", args.params)
    uri = resolve_tracking_uri(tracking)
    targets = registered_targets(uri, track.registered_model)
    machine = one_machine(args.machine, sorted({t[0] for t in targets}), f"the registry at {uri}")
    names = {axis: name for owner, axis, name in targets if owner == machine}
    axes = args.axis or sorted(names)
    missing = [axis for axis in axes if axis not in names]
    if missing:
        raise MissingInputError(
            f"machine {machine} has no registered model for axis {', '.join(missing)} in {uri} "
            f"(axes: {', '.join(sorted(names)) or 'none'})"
        )
    return [
        read_bundle(download_bundle(uri, names[axis], args.alias, workdir / axis)) for axis in axes
    ]


def _connected(kind, url: str, nodes: NodeMap):
    try:
        return kind(url, nodes)
    except (OSError, TimeoutError) as error:
        raise MissingInputError(
            f"{url}: cannot connect ({error!r}); check the address and that the OPC UA server "
            "runs and accepts anonymous connections without security"
        ) from None


def open_source(text: str, nodes: NodeMap | None, follow: bool):
    """Open the source named by ``--source``."""
    if text.startswith(OPCUA_SCHEME):
        return _connected(OpcUaSource, text, nodes)
    if text.startswith("csv:"):
        return CsvTailSource(Path(text[4:]), follow=follow)
    raise ParamsError(f"--source {text!r}: use csv:<file> or opc.tcp://host:port")


def open_sink(text: str, nodes: NodeMap | None):
    """Open the sink named by ``--sink``."""
    if text.startswith(OPCUA_SCHEME):
        return _connected(OpcUaSink, text, nodes)
    for prefix in ("csv:", "jsonl:"):
        if text.startswith(prefix):
            return FileSink(Path(text[len(prefix) :]))
    raise ParamsError(f"--sink {text!r}: use csv:<file>, jsonl:<file> or opc.tcp://host:port")


def node_map(args: argparse.Namespace, bundles: list[AxisBundle]) -> NodeMap:
    """Return the OPC UA node map: ``--nodes`` over the defaults."""
    sensors = list(dict.fromkeys(s for b in bundles for s in b.sensors))
    axes = [b.axis for b in bundles]
    speed = any(b.needs_speed for b in bundles)
    if args.nodes:
        return NodeMap.from_file(args.nodes, sensors, axes, speed)
    return NodeMap.defaults(sensors, axes, speed)


class StopRequested(BaseException):
    """SIGTERM came while the runtime waited for its source (not an error of the source)."""


class SigtermStop:
    """SIGTERM's handler: the runtime stops at once when it waits for its source.

    A stop that comes while a cycle computes or writes waits for the cycle's end, so that no
    axis is left with half its offsets written; one that comes before the first wait (models
    loading, connecting) stops at that wait. Waiting is up to ``cycle_s`` (10 s by default):
    without this a stop would wait that long.
    """

    def __init__(self) -> None:
        self.requested, self.waiting = False, False

    def request(self, signum, frame) -> None:
        """Handle SIGTERM: stop now when waiting, else before the next wait."""
        self.requested = True
        if self.waiting:
            raise StopRequested


class StoppableSource:
    """A source whose wait for readings a :class:`SigtermStop` may end."""

    def __init__(self, source: Source, stop: SigtermStop) -> None:
        self.source, self.stop = source, stop

    @property
    def exhausted(self) -> bool:
        """Whether the wrapped source has no more readings."""
        return self.source.exhausted

    def poll(self, timeout_s: float) -> list[Reading]:
        """Return the wrapped source's readings; raise :class:`StopRequested` once SIGTERM came."""
        if self.stop.requested:
            raise StopRequested
        self.stop.waiting = True
        try:
            return self.source.poll(timeout_s)
        finally:
            self.stop.waiting = False

    def close(self) -> None:
        """Close the wrapped source."""
        self.source.close()


def main(argv: list[str] | None = None) -> int:
    """Run the runtime until the source ends, ``--max-cycles``, SIGTERM or Ctrl-C; return 0."""
    args = _parse_args(argv)
    settings = runtime_settings(args.params)
    # asyncua logs every publish and read (INFO) and each limit the server revised (WARNING);
    # a lost connection or refused write reaches the runtime as an error, which logs it
    logging.getLogger("asyncua").setLevel(logging.ERROR)
    stop = SigtermStop()
    signal.signal(signal.SIGTERM, stop.request)
    with tempfile.TemporaryDirectory(prefix="thermal-bundle-") as workdir:
        bundles = load_bundles(args, Path(workdir))
        nodes = node_map(args, bundles)
        source = StoppableSource(open_source(args.source, nodes, not args.no_follow), stop)
        sink = open_sink(args.sink, nodes)
        log = EventLog(args.log)
        runtime = CompensationRuntime(bundles, settings, source, sink, log)
        try:
            runtime.run(args.max_cycles)
        except StopRequested:
            LOGGER.info("stopped by SIGTERM")
        except KeyboardInterrupt:
            LOGGER.info("stopped by Ctrl-C")
        finally:
            source.close()
            sink.close()
            log.close()
    counts = runtime.counts
    sys.stdout.write(
        f"thermal compensate: {counts.cycles} cycles, {counts.writes} writes, "
        f"{counts.refused} refused, {counts.failed} failed, {counts.stalls} stalled; modes "
        + "; ".join(
            f"{axis}: " + ", ".join(f"{m} {n}" for m, n in sorted(modes.items()))
            for axis, modes in counts.modes.items()
        )
        + f"; events in {args.log}\n"
    )
    return 0

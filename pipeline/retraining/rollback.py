"""``thermal rollback --axis X [--machine M]``: move an axis' ``@champion`` back to ``@previous``.

The two aliases swap, so a second rollback undoes the first. The registered model is
``<track.registered_model>-<machine>-<axis>`` in the store of ``params.yaml`` ``tracking`` (or
``$MLFLOW_TRACKING_URI``), as the ``track`` stage logs it; ``--machine`` may be left out when the
store holds the models of one machine only.
"""

from __future__ import annotations

import argparse
import logging
import sys

from pipeline.config import DEFAULT_PARAMS
from pipeline.errors import UserError
from pipeline.machines import one_machine, registered_name
from pipeline.settings.base import load_settings
from pipeline.settings.track import TrackSettings
from pipeline.settings.tracking import TrackingSettings

LOGGER = logging.getLogger(__name__)


def main(argv: list[str] | None = None) -> int:
    """Roll back one axis; print what moved."""
    parser = argparse.ArgumentParser(prog="thermal rollback", description=__doc__.splitlines()[0])
    parser.add_argument("--axis", required=True, help="displacement axis, e.g. Z")
    parser.add_argument("--machine", help="the machine (needed when the store has several)")
    parser.add_argument("--params", default=str(DEFAULT_PARAMS), help="params file (params.yaml)")
    args = parser.parse_args(argv)
    prefix = load_settings(TrackSettings, "track", args.params).registered_model
    tracking = load_settings(TrackingSettings, "tracking", args.params)
    from pipeline.tracking.champion_model import registered_targets
    from pipeline.tracking.location import absolute_store_uri, resolve_tracking_uri
    from pipeline.tracking.promotion import rollback
    from pipeline.tracking.store import make_client

    uri = resolve_tracking_uri(tracking)
    targets = registered_targets(absolute_store_uri(uri), prefix)
    machine = one_machine(args.machine, sorted({t[0] for t in targets}), f"the store at {uri}")
    name = registered_name(prefix, machine, args.axis)
    try:
        before, now = rollback(make_client(absolute_store_uri(uri)), name)
    except LookupError as error:
        raise UserError(str(error)) from None
    sys.stdout.write(f"{name}: @champion v{before} -> v{now} (@previous is now v{before})\n")
    return 0

"""Write the workshop run as a data logger's wide table, the way real campaigns arrive.

A logger records one long run in one table: a timestamp column, the spindle speed, the probe
channels ``ch1..ch3`` (um; X, Y, Z here) and the temperature channels ``t1..t16`` (degC),
one row per sample, no campaigns and no roles. ``thermal simulate --preset workshop
--logger-table FILE`` writes this table instead of campaign folders, so that ``thermal import
logger`` can be tried (and tested) on a realistic file without real data; the channel names
follow the twin's T1..T16 and X, Y, Z in order (``docs/examples/logger-mapping.yaml`` maps
them back).
"""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import pandas as pd

from pipeline.twin.workshop import WorkshopRun

PROBE_CHANNELS = {"X": "ch1", "Y": "ch2", "Z": "ch3"}
"""Logger channel of each probe of the workshop run."""


def logger_table(run: WorkshopRun, hours: float | None = None) -> pd.DataFrame:
    """Return the run's readings as one wide table.

    Parameters
    ----------
    run : WorkshopRun
        The simulated run (:func:`pipeline.twin.workshop.simulate_workshop`).
    hours : float, optional
        Keep only the samples of the first ``hours`` hours (default: the whole run).

    Returns
    -------
    DataFrame
        ``timestamp`` (local time, ``YYYY-MM-DD HH:MM:SS``), ``rpm`` (1/min), ``ch1..ch3``
        (um) and ``t1..t16`` (degC), one row per sample.
    """
    parts = []
    for campaign in run.campaigns:
        offset_s = (campaign.info.start - run.plan.start).total_seconds()
        elapsed = campaign.temperature["elapsed_s"].to_numpy() + offset_s
        part = pd.DataFrame(
            {
                "timestamp": [run.plan.start + timedelta(seconds=float(s)) for s in elapsed],
                "rpm": campaign.spindle["rpm"].to_numpy(),
            }
        )
        for axis, channel in PROBE_CHANNELS.items():
            part[channel] = campaign.displacement[axis].to_numpy()
        for sensor in [c for c in campaign.temperature.columns if c != "elapsed_s"]:
            part[sensor.lower()] = campaign.temperature[sensor].to_numpy()
        parts.append(part)
    table = pd.concat(parts, ignore_index=True)
    if hours is not None:
        table = table[table["timestamp"] < run.plan.start + timedelta(hours=hours)]
    return table.reset_index(drop=True)


def write_logger_table(table: pd.DataFrame, path: Path) -> None:
    """Write ``table`` as a comma-separated file with a header row (parents created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    out = table.copy()
    out["timestamp"] = pd.to_datetime(out["timestamp"]).dt.strftime("%Y-%m-%d %H:%M:%S")
    out.to_csv(path, index=False, float_format="%.4f", lineterminator="\n")

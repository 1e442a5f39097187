"""Proof on replay: each held-out campaign fed through the runtime, as ISO 230-3 tests drift.

ISO 230-3:2020 ("Test code for machine tools -- Part 3: Determination of thermal effects")
reports a thermal distortion test as the drift of the tool against the workpiece over the test
(largest drift, drift range) with the machine's own thermal compensation on or off. Here, for
every campaign the champion was scored on without having seen it (its held-out campaigns, as
in ``data/models/champion/<axis>/heldout.parquet``), the campaign's record is replayed into
the compensation runtime (:class:`pipeline.compensation.runtime.CompensationRuntime`: the same
input checks, the same incremental preparation, the default size and rate limits, fallbacks and
hold) with the fit that did not see it, one sample per cycle; the offset written is subtracted
from the measured drift:

- *before*: the measured thermal error (um), what an uncompensated machine shows;
- *offset*: what the runtime wrote (with the limits applied);
- *after*: the residual drift, measured - (offset_sign x offset).

Per campaign: largest |drift| before and after over the test, drift range (max - min) before
and after, RMS before and after, and the offline held-out RMS of the same samples (the
champion's cross-campaign prediction, no runtime). A campaign that is part of a longer record
(a run) is replayed with the run's earlier samples read first as its past
(:meth:`~pipeline.compensation.runtime.CompensationRuntime.warm_up`): rises and speed responses
count from the run's start, as for a runtime that had been running since then.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.compensation.bundle import AxisBundle, ModelEntry, input_ranges
from pipeline.compensation.files import MemorySink, TableSource
from pipeline.compensation.runtime import CompensationRuntime, EventLog
from pipeline.fit_statistics import root_mean_square
from pipeline.plots import campaign_label, new_figure, save_figure, wrap_text
from pipeline.separation.features import InputSpec
from pipeline.settings.compensation import CompensationSettings

PROOF_COLUMNS = [
    "axis",
    "campaign_id",
    "season",
    "unit",
    "n_samples",
    "max_drift_before_um",
    "max_drift_after_um",
    "range_before_um",
    "range_after_um",
    "rms_before_um",
    "rms_after_um",
    "offline_rms_um",
    "limited_share",
    "fallback_cycles",
]
TRACE_COLUMNS = [
    "campaign_id",
    "season",
    "elapsed_s",
    "before_um",
    "offset_um",
    "mode",
    "limited",
    "unit",
    "after_um",
    "offline_predicted_um",
    "offline_um",
]


@dataclass(frozen=True)
class AxisProof:
    """The replay of one axis' held-out campaigns.

    Attributes
    ----------
    axis : str
    table : DataFrame
        One row per campaign, :data:`PROOF_COLUMNS`.
    traces : DataFrame
        Per sample: ``campaign_id``, ``elapsed_s`` (s), ``before_um``, ``offset_um``,
        ``after_um``, ``offline_um`` (the offline held-out prediction), ``mode``.
    summary : dict
        Means over campaigns (``rms_after_um``, ``offline_rms_um``, ``rms_before_um``, the
        largest drifts) and ``ratio`` = replayed / offline RMS.
    """

    axis: str
    table: pd.DataFrame
    traces: pd.DataFrame
    summary: dict


def unit_bundle(base: AxisBundle, fit: Mapping, rows: pd.DataFrame, spec: InputSpec) -> AxisBundle:
    """Return the bundle of a held-out fit: its estimator and inputs, its training ranges."""
    unit_spec = replace(spec, inputs=tuple(fit["inputs"]))
    trained = rows[rows["campaign_id"].isin(fit.get("trained_on") or [])]
    entry = ModelEntry("champion", unit_spec, fit["estimator"])
    return replace(
        base, champion=entry, fallbacks=(), input_ranges=input_ranges(trained, [unit_spec])
    )


def replay_run(
    bundle: AxisBundle,
    run_rows: pd.DataFrame,
    settings: CompensationSettings,
    scored: np.ndarray | None = None,
) -> pd.DataFrame:
    """Replay one run's samples (time order) through the runtime.

    Parameters
    ----------
    bundle : AxisBundle
    run_rows : DataFrame
        The run's rows of the separated table, in time order (``run_elapsed_s``, ``rpm``, the
        sensors in degC).
    settings : CompensationSettings
    scored : ndarray of bool, optional
        Rows whose offsets are wanted; the rows before the first of them are the run's past,
        read by :meth:`CompensationRuntime.warm_up` (a runtime that had been running since the
        run's start would be tracking by then). None: every row is a cycle.

    Returns
    -------
    DataFrame
        ``offset_um``, ``mode`` and ``limited`` of each cycle, on the rows from the first
        scored one (``run_rows``' index).
    """
    spec = bundle.champion.spec
    columns = ["elapsed_s", *(["rpm"] if spec.needs_speed else []), *spec.sensors]
    table = run_rows.assign(elapsed_s=run_rows["run_elapsed_s"])[columns]
    first = 0 if scored is None or not scored.any() else int(np.argmax(scored))
    source = TableSource(table)
    runtime = CompensationRuntime(
        [bundle], settings, source, MemorySink(), EventLog(None, echo=False)
    )
    runtime.warm_up([source.poll(0.0)[0] for _ in range(first)])
    runtime.run()
    steps = runtime.steps
    return pd.DataFrame(
        {
            "offset_um": [s.offset_um for s in steps],
            "mode": [s.mode for s in steps],
            "limited": [s.limited for s in steps],
        },
        index=run_rows.index[first:],
    )


def replay_axis(
    base: AxisBundle,
    rows: pd.DataFrame,
    fits: Mapping[str, Mapping],
    heldout: pd.DataFrame,
    settings: CompensationSettings,
) -> AxisProof:
    """Replay every held-out campaign of an axis with the fit that did not see it.

    Parameters
    ----------
    base : AxisBundle
        The axis' bundle (card, input checks); its estimator is replaced by each unit's.
    rows : DataFrame
        The axis' rows of the separated table (every campaign, ``run_id``, ``run_elapsed_s``).
    fits : mapping
        Unit -> ``{"estimator", "inputs", "campaigns", "trained_on"}``
        (:func:`pipeline.protocol.evaluation.held_out_fits`).
    heldout : DataFrame
        The champion's offline held-out predictions (``heldout.parquet``).
    settings : CompensationSettings
    """
    traces = []
    for unit, fit in fits.items():
        bundle = unit_bundle(base, fit, rows, base.champion.spec)
        scored = rows[rows["campaign_id"].isin(fit["campaigns"])]
        for run_id in pd.unique(scored["run_id"]):
            run = rows[rows["run_id"] == run_id].sort_values("run_elapsed_s")
            last = run["run_elapsed_s"][run["campaign_id"].isin(fit["campaigns"])].max()
            run = run[run["run_elapsed_s"] <= last].reset_index(drop=True)
            mine = run["campaign_id"].isin(fit["campaigns"]).to_numpy()
            written = replay_run(bundle, run, settings, scored=mine)
            frame = run[["campaign_id", "season", "elapsed_s", "thermal_error_um"]].join(
                written, how="inner"
            )
            traces.append(frame[frame["campaign_id"].isin(fit["campaigns"])].assign(unit=unit))
    if not traces:
        return AxisProof(
            base.axis, pd.DataFrame(columns=PROOF_COLUMNS), pd.DataFrame(columns=TRACE_COLUMNS), {}
        )
    trace = pd.concat(traces, ignore_index=True).rename(columns={"thermal_error_um": "before_um"})
    trace["after_um"] = trace["before_um"] - settings.offset_sign * trace["offset_um"]
    offline = heldout.rename(columns={"predicted_um": "offline_predicted_um"})
    trace = trace.merge(
        offline[["campaign_id", "elapsed_s", "offline_predicted_um"]],
        on=["campaign_id", "elapsed_s"],
        how="left",
    )
    trace["offline_um"] = trace["before_um"] - trace["offline_predicted_um"]
    table = proof_table(base.axis, trace)
    return AxisProof(base.axis, table, trace, proof_summary(table))


def proof_table(axis: str, trace: pd.DataFrame) -> pd.DataFrame:
    """Per campaign: drift before and after, RMS, the offline RMS on the same samples."""
    rows = []
    for campaign_id, part in trace.groupby("campaign_id", sort=True):
        common = part[np.isfinite(part["offline_um"])]
        before, after = part["before_um"].to_numpy(), part["after_um"].to_numpy()
        rows.append(
            {
                "axis": axis,
                "campaign_id": campaign_id,
                "season": part["season"].iloc[0],
                "unit": part["unit"].iloc[0],
                "n_samples": len(common),
                "max_drift_before_um": float(np.nanmax(np.abs(before))),
                "max_drift_after_um": float(np.nanmax(np.abs(after))),
                "range_before_um": float(np.nanmax(before) - np.nanmin(before)),
                "range_after_um": float(np.nanmax(after) - np.nanmin(after)),
                "rms_before_um": root_mean_square(common["before_um"].to_numpy()),
                "rms_after_um": root_mean_square(common["after_um"].to_numpy()),
                "offline_rms_um": root_mean_square(common["offline_um"].to_numpy()),
                "limited_share": float(part["limited"].mean()),
                "fallback_cycles": int((part["mode"] != "champion").sum()),
            }
        )
    return pd.DataFrame(rows, columns=PROOF_COLUMNS)


def proof_summary(table: pd.DataFrame) -> dict:
    """Means over campaigns and the ratio of replayed to offline RMS."""
    if table.empty:
        return {}
    means = {
        name: float(table[name].mean())
        for name in (
            "rms_before_um",
            "rms_after_um",
            "offline_rms_um",
            "max_drift_before_um",
            "max_drift_after_um",
            "range_before_um",
            "range_after_um",
        )
    }
    offline = means["offline_rms_um"]
    means["ratio"] = means["rms_after_um"] / offline if offline > 0 else float("nan")
    means["n_campaigns"] = len(table)
    return means


def proof_figure(axis: str, campaign: pd.DataFrame, out: Path) -> None:
    """Measured drift, the offset written and the residual drift of one replayed campaign."""
    fig = new_figure(9.0, 4.2)
    ax = fig.add_subplot()
    minutes = campaign["elapsed_s"].to_numpy(dtype=float) / 60.0
    ax.plot(
        minutes, campaign["before_um"], color="tab:red", label="measured drift (no compensation)"
    )
    ax.plot(
        minutes, campaign["offset_um"], color="tab:blue", label="offset written (limits applied)"
    )
    ax.plot(minutes, campaign["after_um"], color="black", label="residual drift after compensation")
    ax.axhline(0.0, color="grey", linewidth=0.6)
    ax.set_xlabel("time since the campaign's start (min)")
    ax.set_ylabel(f"axis {axis} (um)")
    label = campaign_label(str(campaign["campaign_id"].iloc[0]), str(campaign["season"].iloc[0]))
    title = (
        f"Replay of held-out campaign {label}, axis {axis}: largest drift "
        f"{np.nanmax(np.abs(campaign['before_um'])):.1f} um before, "
        f"{np.nanmax(np.abs(campaign['after_um'])):.1f} um after"
    )
    ax.set_title(wrap_text(fig, title, 11.0), fontsize=11.0)
    ax.legend(fontsize=8.5, loc="best")
    save_figure(fig, out)

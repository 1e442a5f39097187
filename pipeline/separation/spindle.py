"""Spindle thermal drift: thermal error = displacement minus its value at the run's reference.

The PCDL paper (Miao et al. 2016, section 3) measures the Z drift of the spindle nose with an
eddy-current probe every 3 min from a cold start; the thermal error is the change from the cold
state, the first sample. Real records are not always like that, so here:

- **every displacement axis** the campaigns declare (X, Y, Z) is separated, one block of rows
  per axis (``axis`` column), unless ``separate.displacement_axis`` lists fewer;
- **the reference is the run's, not the campaign's**: campaigns cut from one record without a
  break form a run (:mod:`pipeline.separation.runs`); the error of every campaign of a run is
  counted from the run's first sample (or the mean of its first N: ``cold_reference``, ``cold_n``),
  the cold start when the run starts cold. A displacement jump across a contiguous cut (a re-zeroed
  probe) is stitched. A run declared warm (``start_state: warm``) has no cold sample: its error
  is counted from its first sample, and the ``reference`` column says so;
- the **model inputs** are computed over the whole run by
  :func:`pipeline.separation.features.run_inputs`, the function the registered model uses too:
  temperature rises from the same reference and the responses of first-order lags to the spindle
  speed, from rest at the run's start;
- campaigns sampled faster than ``resample_s`` are averaged into windows of that length (a
  logger's few-second samples; thermal time constants are minutes to hours).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.separation.features import (
    SpeedResponses,
    reference_value,
    resample,
    run_inputs,
)
from pipeline.separation.runs import (
    DECLARED,
    Run,
    build_runs,
    candidate_links,
    spans_from_tables,
    stitch,
    temperature_jump,
)
from pipeline.settings.separate import RunSettings, SeparateSettings
from schemas.vocabulary import DISPLACEMENT_AXES, displacement_column

LOGGER = logging.getLogger(__name__)


@dataclass(frozen=True)
class SeparationSettings:
    """``params.yaml`` ``separate`` as the spindle separation uses it.

    Attributes
    ----------
    axes : tuple of str or None
        Displacement axes to model; None: every axis a campaign declares.
    reference : str
        ``first_sample`` or ``mean_first_n``.
    n : int
        Samples averaged for ``mean_first_n``.
    resample_s : float or None, s
        Average campaigns sampled faster than this into windows of this length.
    runs : RunSettings
    speed : SpeedResponses or None
    """

    axes: tuple[str, ...] | None = None
    reference: str = "first_sample"
    n: int = 1
    resample_s: float | None = None
    runs: RunSettings = field(default_factory=RunSettings)
    speed: SpeedResponses | None = None

    @classmethod
    def from_settings(cls, settings: SeparateSettings) -> SeparationSettings:
        """Build from the ``separate`` section of params.yaml, checked."""
        speed = settings.speed_responses
        return cls(
            axes=settings.displacement_axis,
            reference=settings.cold_reference,
            n=settings.cold_n,
            resample_s=settings.resample_s or None,
            runs=settings.runs,
            speed=(
                SpeedResponses(speed.time_constants_min, speed.exponents)
                if speed is not None and speed.time_constants_min
                else None
            ),
        )


def modelled_axes(campaigns: pd.DataFrame, wanted: Sequence[str] | None) -> list[str]:
    """Axes to separate: those the campaigns declare, restricted to ``wanted`` (may be empty)."""
    declared: set[str] = set()
    for text in campaigns["displacement_json"]:
        declared |= set(json.loads(text or "{}"))
    order = [a for a in DISPLACEMENT_AXES if a in declared] + sorted(
        declared - set(DISPLACEMENT_AXES)
    )
    if wanted is None:
        axes = order
    else:
        missing = [a for a in wanted if a not in declared]
        if missing:
            LOGGER.warning(
                "params.yaml separate.displacement_axis lists %s, which no valid campaign "
                "declares; separating %s",
                missing,
                [a for a in order if a in wanted],
            )
        axes = [a for a in order if a in wanted]
    return axes


def _sensors(meta: Mapping) -> list[str]:
    return list(json.loads(meta["sensors_json"]))


def _reference_text(run: Run, position: int, reference: str, n: int) -> str:
    sample = "first sample" if reference == "first_sample" else f"mean of the first {n} samples"
    head = run.run_id
    if not run.cold_start:
        return (
            f"{sample} of {head} (declared warm start: the cold state is not in the data, the "
            "error is counted from there)"
        )
    if len(run.campaigns) == 1:
        return f"{sample} of {head} (cold start)"
    if position == 0:
        return f"{sample} of {head}, the cold start of run {head} ({', '.join(run.campaigns)})"
    return f"{sample} of {head}: this campaign continues run {head} without a break and starts warm"


@dataclass
class _RunTables:
    rows: dict[str, pd.DataFrame]
    t_run: dict[str, np.ndarray]


def _run_tables(run: Run, samples: dict[str, pd.DataFrame]) -> _RunTables:
    rows = {c: samples[c] for c in run.campaigns}
    t_run = {
        c: rows[c]["elapsed_s"].to_numpy(dtype=float) + offset
        for c, offset in zip(run.campaigns, run.offsets_s, strict=True)
    }
    return _RunTables(rows, t_run)


def _stitched_displacement(
    run: Run, tables: _RunTables, axis: str, settings: RunSettings
) -> tuple[dict[str, np.ndarray], list[dict]]:
    """Displacement of every campaign of the run along ``axis``, stitched across the links."""
    column = displacement_column(axis)
    values = {
        c: tables.rows[c][column].to_numpy(dtype=float)
        if column in tables.rows[c]
        else np.full(len(tables.rows[c]), np.nan)
        for c in run.campaigns
    }
    record = []
    for link in run.links:
        result = stitch(
            tables.t_run[link.previous],
            values[link.previous],
            tables.t_run[link.campaign],
            values[link.campaign],
            link.contiguous,
            settings.min_stitch_um,
        )
        values[link.campaign] = values[link.campaign] + result.offset_um
        record.append(
            {
                "axis": axis,
                "previous": link.previous,
                "campaign": link.campaign,
                "jump_um": None if np.isnan(result.jump_um) else round(result.jump_um, 4),
                "offset_um": round(result.offset_um, 4),
            }
        )
    return values, record


def find_runs(
    campaigns: pd.DataFrame, samples: dict[str, pd.DataFrame], settings: RunSettings
) -> tuple[list[Run], dict[str, float]]:
    """Find the runs of the campaigns; detected links whose temperatures jump are dropped.

    Returns the runs and, per linked campaign, the temperature jump across its cut (degC).
    """
    combined = pd.concat(samples.values(), ignore_index=True)
    spans = spans_from_tables(campaigns, combined)
    links, notes = candidate_links(spans, settings)
    sensors = {str(m["campaign_id"]): _sensors(m) for m in campaigns.to_dict("records")}
    kept, jumps = [], {}
    for link in links:
        before = samples[link.previous].reindex(columns=sensors[link.previous])
        after = samples[link.campaign].reindex(columns=sensors[link.campaign])
        jump = temperature_jump(before, after)
        if link.how != DECLARED:
            if not jump <= settings.max_temperature_jump_degC:
                notes.append(
                    f"{link.campaign} starts {link.gap_s:.0f} s after {link.previous} ends but "
                    f"its temperatures jump by {jump:.2f} degC (median): not linked"
                )
                continue
        kept.append(link)
        jumps[link.campaign] = jump
    return build_runs(spans, kept, notes), jumps


def spindle_thermal_error(
    campaigns: pd.DataFrame, samples: pd.DataFrame, settings: SeparationSettings
) -> tuple[pd.DataFrame, dict]:
    """Thermal error and model inputs of every spindle-drift campaign, for every axis.

    Parameters
    ----------
    campaigns : DataFrame
        Validated spindle campaigns (``campaign_id``, ``machine``, ``start``, ``split``,
        ``season``, ``synthetic``, ``sensors_json``, ``displacement_json``, ``start_state``,
        ``follows``).
    samples : DataFrame
        Validated spindle samples (``disp_<axis>`` in um, one column per sensor in degC,
        ``rpm``).
    settings : SeparationSettings

    Returns
    -------
    table : DataFrame
        One row per (axis, sample) of each campaign that measured the axis: ``axis``,
        ``campaign_id``, ``run_id``, ``source_row``, ``elapsed_s``, ``run_elapsed_s``,
        ``campaign_start`` (the campaign's ``start``), ``rpm``, ``split``, ``season``,
        ``synthetic``, ``warm_start``, ``reference`` (in words), ``displacement_um``
        (stitched), ``thermal_error_um``, each sensor (degC), ``rise_<sensor>`` (K) and the
        speed responses.
    record : dict
        JSON-ready: settings, runs (campaigns, links with gaps, temperature jumps and
        displacement stitches, notes) and each campaign's run, position and reference; with
        nothing to separate (no valid spindle campaign, or none measured a wanted axis) the
        table is empty and ``note`` says why.
    """
    axes = modelled_axes(campaigns, settings.axes) if len(campaigns) else []
    meta = {str(m["campaign_id"]): m for m in campaigns.to_dict("records")}
    per_campaign = {
        cid: resample(rows.sort_values("elapsed_s").reset_index(drop=True), settings.resample_s)
        for cid, rows in samples.groupby("campaign_id", sort=True)
        if cid in meta
    }
    runs, jumps = (
        find_runs(
            campaigns[campaigns["campaign_id"].isin(per_campaign)], per_campaign, settings.runs
        )
        if per_campaign and axes
        else ([], {})
    )
    frames, record = [], {"axes": axes, "runs": [], "campaigns": {}}
    for run in runs:
        tables = _run_tables(run, per_campaign)
        inputs, notes = _inputs_of_run(run, tables, meta, settings)
        stitches = []
        for axis in axes:
            axis_frames, stitched = _axis_frames(axis, run, tables, inputs, meta, settings)
            frames += axis_frames
            stitches += stitched
        record["runs"].append(_run_record(run, jumps, stitches, notes))
        for position, cid in enumerate(run.campaigns):
            record["campaigns"][cid] = {
                "run_id": run.run_id,
                "position": position,
                "warm_start": position > 0 or not run.cold_start,
                "reference": _reference_text(run, position, settings.reference, settings.n),
            }
    record["settings"] = {
        "cold_reference": settings.reference,
        "cold_n": settings.n,
        "resample_s": settings.resample_s,
        "speed_responses": None if settings.speed is None else settings.speed.to_dict(),
        "runs": vars(settings.runs),
    }
    if not frames:
        wanted = "any axis" if settings.axes is None else f"the axes {list(settings.axes)}"
        record["axes"] = []
        record["note"] = (
            f"no valid spindle_drift campaign has displacement readings along {wanted}: there "
            "is no spindle thermal error to model (check reports/validation.json and "
            "params.yaml separate.displacement_axis)"
        )
        return empty_table(), record
    return pd.concat(frames, ignore_index=True), record


def empty_table() -> pd.DataFrame:
    """Return the separated table with its columns and no row (nothing to separate)."""
    columns = {
        "axis": "str",
        "campaign_id": "str",
        "run_id": "str",
        "source_row": "int64",
        "elapsed_s": "float64",
        "run_elapsed_s": "float64",
        "campaign_start": "datetime64[ns]",
        "rpm": "float64",
        "split": "str",
        "season": "str",
        "synthetic": "bool",
        "warm_start": "bool",
        "reference": "str",
        "displacement_um": "float64",
        "thermal_error_um": "float64",
    }
    return pd.DataFrame({name: pd.Series(dtype=dtype) for name, dtype in columns.items()})


def _inputs_of_run(
    run: Run, tables: _RunTables, meta: Mapping, settings: SeparationSettings
) -> tuple[pd.DataFrame, list[str]]:
    """Model inputs of a whole run, on its rows (campaigns in order), and what was left out.

    Every input is referenced at the run's first campaign: a sensor with no reading in it gets
    no rise in this run (its first reading would be a warm one); a run with a campaign without
    any spindle speed gets no speed responses (the speed history is broken there).
    """
    sensors = list(dict.fromkeys(s for c in run.campaigns for s in _sensors(meta[c])))
    frame = pd.concat([tables.rows[c].reindex(columns=sensors) for c in run.campaigns])
    rpm = [tables.rows[c]["rpm"].to_numpy(dtype=float) for c in run.campaigns]
    notes = []
    speed = settings.speed
    silent = [c for c, r in zip(run.campaigns, rpm, strict=True) if not np.isfinite(r).any()]
    if speed is not None and silent and len(silent) < len(run.campaigns):
        notes.append(
            f"no spindle speed in {', '.join(silent)}: no speed responses in run {run.run_id}"
        )
        speed = None
    inputs = run_inputs(
        np.concatenate([tables.t_run[c] for c in run.campaigns]),
        frame,
        np.concatenate(rpm),
        features="temperature_rise",
        reference=settings.reference,
        n=settings.n,
        speed=speed,
    )
    if speed is None and settings.speed is not None:
        for name in settings.speed.names():
            inputs[name] = np.nan
    first = tables.rows[run.campaigns[0]]
    late = [s for s in sensors if s not in first or not first[s].notna().any()]
    for sensor in late:
        inputs[f"rise_{sensor}"] = np.nan
    if late:
        notes.append(
            f"{', '.join(late)} not read in {run.run_id}, the run's first campaign: no "
            f"rise in run {run.run_id}"
        )
    return inputs, notes


def _axis_frames(
    axis: str,
    run: Run,
    tables: _RunTables,
    inputs: pd.DataFrame,
    meta: Mapping,
    settings: SeparationSettings,
) -> tuple[list[pd.DataFrame], list[dict]]:
    """Rows of one axis for every campaign of the run that measured it, and the stitches.

    The reference is the axis' first reading in the run's first campaign; when that campaign
    did not measure the axis, the axis' first reading later in the run, which is a warm one,
    and the ``reference`` column says so.
    """
    displacement, stitches = _stitched_displacement(run, tables, axis, settings.runs)
    head = next((c for c in run.campaigns if np.isfinite(displacement[c]).any()), None)
    if head is None:
        return [], stitches
    cold = reference_value(displacement[head], settings.reference, settings.n)
    bounds = np.cumsum([0, *(len(tables.rows[c]) for c in run.campaigns)])
    frames = []
    for position, cid in enumerate(run.campaigns):
        if not np.isfinite(displacement[cid]).any():
            continue
        reference = _reference_text(run, position, settings.reference, settings.n)
        if head != run.run_id:
            reference = (
                f"first reading of {axis} in {head}: {run.run_id}, the run's first campaign, "
                f"did not measure {axis}, so this reference is a warm one"
            )
        frames.append(
            _campaign_frame(
                axis,
                cid,
                run,
                tables,
                displacement[cid] - cold,
                displacement[cid],
                inputs.iloc[bounds[position] : bounds[position + 1]],
                meta[cid],
                warm=position > 0 or not run.cold_start or head != run.run_id,
                reference=reference,
            )
        )
    return frames, stitches


def _campaign_frame(
    axis: str,
    campaign_id: str,
    run: Run,
    tables: _RunTables,
    error: np.ndarray,
    displacement: np.ndarray,
    inputs: pd.DataFrame,
    meta: Mapping,
    *,
    warm: bool,
    reference: str,
) -> pd.DataFrame:
    rows = tables.rows[campaign_id]
    frame = pd.DataFrame(
        {
            "axis": axis,
            "campaign_id": campaign_id,
            "run_id": run.run_id,
            "source_row": rows["source_row"].to_numpy(dtype=np.int64),
            "elapsed_s": rows["elapsed_s"].to_numpy(dtype=float),
            "run_elapsed_s": tables.t_run[campaign_id],
            "campaign_start": pd.Timestamp(meta["start"]),
            "rpm": rows["rpm"].to_numpy(dtype=float),
            "split": meta["split"],
            "season": meta["season"],
            "synthetic": bool(meta["synthetic"]),
            "warm_start": warm,
            "reference": reference,
            "displacement_um": displacement,
            "thermal_error_um": error,
        }
    )
    own = _sensors(meta)
    for sensor in own:
        frame[sensor] = rows[sensor].to_numpy(dtype=float) if sensor in rows else np.nan
    columns = [f"rise_{s}" for s in own] + [c for c in inputs.columns if not c.startswith("rise_")]
    return pd.concat([frame, inputs[columns].reset_index(drop=True)], axis=1)


def _run_record(
    run: Run, jumps: Mapping[str, float], stitches: list[dict], notes: list[str]
) -> dict:
    links = []
    for link in run.links:
        jump = jumps[link.campaign]
        links.append(
            {
                "previous": link.previous,
                "campaign": link.campaign,
                "how": link.how,
                "gap_s": round(link.gap_s, 1),
                "contiguous": link.contiguous,
                "temperature_jump_degC": None if np.isnan(jump) else round(jump, 4),
                "displacement": [s for s in stitches if s["campaign"] == link.campaign],
            }
        )
    return {
        "run_id": run.run_id,
        "campaigns": list(run.campaigns),
        "cold_start": run.cold_start,
        "links": links,
        "notes": [*run.notes, *notes],
    }

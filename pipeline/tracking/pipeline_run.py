"""One machine's part of a pipeline execution logged to MLflow: records, runs, champions.

Each machine is its own pipeline run (its own parent run, run identity, champions and views):
:func:`prepare` reads the machine's part of the evaluate outputs and its provenance
(:mod:`pipeline.tracking.stage_outputs`, :mod:`pipeline.tracking.identity`) and builds the
parent and child run records (:mod:`pipeline.tracking.records`) before MLflow is imported;
:func:`log_pipeline_run` logs them (:mod:`pipeline.tracking.store`) unless a finished parent of
the same run identity is there, registers each axis' champion from its child run as
``<track.registered_model>-<machine>-<axis>``, shares the views and links the machine's
discrepancy run. The ``track`` stage writes the records it returns, by machine.
"""

from __future__ import annotations

import importlib.util
import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from pipeline.errors import MissingInputError
from pipeline.machines import MACHINE_COLUMN, machine_key, registered_name, resolved_names
from pipeline.paths import (
    AXIS_MODEL_METRICS,
    CANDIDATE_SCORES,
    CHAMPION_CARD_FILE,
    CHAMPION_HELDOUT_FILE,
    CROSS_SEASON_METRICS,
    FITTED_MODELS,
    GROUP_SCORES,
    INGESTED_CAMPAIGNS,
    RAW,
    SCORES_LONG,
    SELECTED,
    SPINDLE_THERMAL_ERROR,
    TRACKING_RECORD,
)
from pipeline.settings.track import TrackSettings
from pipeline.settings.tracking import TrackingSettings
from pipeline.tracking import guide, records, store, views
from pipeline.tracking import identity as ident
from pipeline.tracking.location import absolute_store_uri, local_artifact_location
from pipeline.tracking.stage_outputs import (
    artifact_files,
    champion_cards,
    champion_folder,
    child_inputs,
    discrepancy_run_id,
    machine_entry,
)

logger = logging.getLogger(__name__)


DVC_LOCK = Path("dvc.lock")


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    return Path(next(iter(spec.submodule_search_locations)))


def _load_params(path: Path) -> dict[str, Any]:
    with path.open(encoding="utf-8") as handle:
        return yaml.safe_load(handle) or {}


@dataclass(frozen=True)
class Prepared:
    """Everything to log of one machine, computed before MLflow is imported."""

    machine: str
    identity: ident.RunIdentity
    synthetic: str
    git_commit: str
    parent: records.RunRecord
    children: list[records.RunRecord]
    champions: dict[str, dict]


def machine_raw_folders(machine: str) -> list[Path]:
    """Return the ``data/raw`` folders of the machine's campaigns (from ingest's campaigns)."""
    if not INGESTED_CAMPAIGNS.is_file():
        raise MissingInputError(
            f"{INGESTED_CAMPAIGNS} not found: the run identity hashes each machine's raw "
            "campaigns; run `dvc repro ingest` first"
        )
    campaigns = pd.read_parquet(INGESTED_CAMPAIGNS)
    ids = campaigns.loc[resolved_names(campaigns) == machine, "campaign_id"].astype(str)
    return [RAW / campaign_id for campaign_id in sorted(ids)]


def machine_score_parts(machine: str, cards: dict[str, dict]) -> list[tuple[str, bytes]]:
    """Return the machine's rows and entries of the evaluate outputs and its cards, as bytes."""
    parts = []
    for path in (SCORES_LONG, CANDIDATE_SCORES, GROUP_SCORES):
        table = pd.read_csv(path, dtype={MACHINE_COLUMN: str}) if path.is_file() else None
        rows = b"missing" if table is None else table.loc[table[MACHINE_COLUMN] == machine]
        parts.append((path.as_posix(), rows if isinstance(rows, bytes) else rows.to_csv().encode()))
    for path in (CROSS_SEASON_METRICS, FITTED_MODELS, SELECTED, AXIS_MODEL_METRICS):
        entry = _entry_or_none(path, machine)
        parts.append((path.as_posix(), json.dumps(entry, sort_keys=True).encode()))
    folder = champion_folder(machine)
    parts += [
        ((folder / axis).as_posix(), (folder / axis / CHAMPION_CARD_FILE).read_bytes())
        for axis in sorted(cards)
    ]
    return parts


def _entry_or_none(path: Path, machine: str) -> Any:
    """Return the machine's entry of a ``{"machines": ...}`` output; None without the file."""
    return machine_entry(path, machine) if path.is_file() else None


def prepare(params_path: Path, machine: str) -> Prepared:
    """Read the machine's outputs and provenance, compute its identity, build the run records."""
    all_params = _load_params(params_path)
    cross_season = _entry_or_none(CROSS_SEASON_METRICS, machine) or {}
    selected = (_entry_or_none(SELECTED, machine) or {}).get("axes", {})
    axis_model = _entry_or_none(AXIS_MODEL_METRICS, machine) or {}

    code_dirs = [_package_dir("pipeline"), _package_dir("schemas")]
    cards = champion_cards(machine)
    run_identity = ident.compute_identity(
        code_dirs, all_params, machine_raw_folders(machine), machine_score_parts(machine, cards)
    )
    synthetic = ident.synthetic_flag(RAW)
    commit = ident.git_commit()
    dvc_hashes = ident.dvc_lock_hashes(ident.read_dvc_lock(DVC_LOCK), RAW.as_posix())
    own = f":{TRACKING_RECORD.as_posix()}"  # the previous run's record: stale, not data
    dvc_hashes = {key: md5 for key, md5 in dvc_hashes.items() if not key.endswith(own)}
    tags = records.provenance_tags(
        run_identity.value, run_identity.parts, commit, dvc_hashes, synthetic
    )
    tags[MACHINE_COLUMN] = machine
    tags[records.NOTE_TAG] = guide.parent_description(commit, synthetic, run_identity.value, cards)
    for axis, card in cards.items():
        tags[records.safe_key(records.RANKED_BY_TAG, axis)] = str(card.get("chosen_on") or "-")
        label = "/".join(str(card[k]) for k in records.KEY_COLUMNS[1:])
        tags[records.safe_key(records.CHAMPION_TAG, axis)] = f"{axis}/{label}"
    children = records.child_records(
        child_inputs(machine, cards), {"synthetic": synthetic, MACHINE_COLUMN: machine}
    )
    parent = records.parent_record(
        f"pipeline-{machine_key(machine)}-{run_identity.value[:12]}",
        cross_season,
        all_params,
        tags,
        selected,
        axis_model,
    )
    return Prepared(machine, run_identity, synthetic, commit, parent, children, cards)


def champion_hook(tracking_uri: str, prefix: str, machine: str, cards: dict[str, dict]):
    """Return a callback that logs and registers each axis' champion from its child run.

    ``None`` (with a warning) when evaluate wrote no champion for the machine.
    """
    folder = champion_folder(machine)
    if not cards:
        logger.warning("%s/<axis>/ not found: no champion model to register", folder)
        return None

    def register(record: records.RunRecord, run_id: str) -> None:
        axis = record.tags.get("axis")
        if record.tags.get(records.CHAMPION_TAG) != "true" or axis not in cards:
            return
        from pipeline.tracking.champion_model import log_and_register

        name = registered_name(prefix, machine, axis)
        log_and_register(tracking_uri, run_id, name, folder / axis)

    return register


def log_pipeline_run(
    prepared: Prepared,
    store_settings: TrackingSettings,
    settings: TrackSettings,
    uri: str,
    n_metrics: int,
    gate: GateInputs | None = None,
) -> dict[str, Any]:
    """Log ``prepared`` to the store at ``uri`` unless it is there, gate; return the run record.

    Parameters
    ----------
    prepared : Prepared
        The records of :func:`prepare`.
    store_settings : TrackingSettings
        The ``tracking`` section of ``params.yaml`` (the local artifact folder).
    settings : TrackSettings
        The ``track`` section: experiment, registered model, promotion gate.
    uri : str
        Tracking URI (:func:`pipeline.tracking.location.resolve_tracking_uri`).
    n_metrics : int
        Metrics in the records, for the log line.
    gate : GateInputs, optional
        What the promotion gate scores on (:func:`gate_inputs`); None: the gate does not run
        and no alias moves.

    Returns
    -------
    dict
        ``reports/mlflow_run.json``: store, experiment, parent run, identity, champions, views,
        and ``promotion``: the gate's decision per axis.
    """
    client = store.make_client(absolute_store_uri(uri))
    experiment = settings.experiment
    artifact_dir = store_settings.local_artifact_dir
    experiment_id = store.ensure_experiment(
        client, experiment, local_artifact_location(uri, artifact_dir, experiment)
    )
    prefix = settings.registered_model
    target = _Target(client, experiment_id, experiment, uri, prefix)
    parent_id, reused = _log_parent(target, prepared, n_metrics)
    decisions = [] if gate is None else _gate(target, parent_id, prepared, gate)
    store.describe_experiment(client, experiment_id, guide.experiment_description(experiment))
    ranked_by = {
        axis: str(card.get("chosen_on") or "") for axis, card in prepared.champions.items()
    }
    shared = views.shared_views(parent_id, prepared.children, ranked_by, prepared.machine)
    store.share_views(client, experiment_id, shared)
    discrepancy = discrepancy_run_id(prepared.machine)
    linked = discrepancy is not None and store.link_runs(
        client, parent_id, discrepancy, "discrepancy"
    )
    return {
        "machine": prepared.machine,
        "tracking_uri": store.public_uri(uri),
        "experiment": experiment,
        "experiment_id": experiment_id,
        "parent_run_id": parent_id,
        "run_identity": prepared.identity.value,
        "identity_parts": prepared.identity.parts,
        "reused": reused,
        "child_runs": len(prepared.children),
        "champions": _registered_champions(target, prepared),
        "git_commit": prepared.git_commit,
        "synthetic": prepared.synthetic,
        "discrepancy_run_id": discrepancy if linked else None,
        "views": {key: views.view_path(experiment_id, key) for key in shared},
        "promotion": [decision.to_dict() for decision in decisions],
    }


@dataclass(frozen=True)
class GateInputs:
    """What the promotion gate scores on.

    Attributes
    ----------
    table : DataFrame
        ``data/separated/spindle_thermal_error.parquet``.
    heldout : dict of str to DataFrame
        Axis -> the challenger's held-out predictions (``heldout.parquet``).
    margin : float
        ``track.promotion.min_improvement``.
    """

    table: pd.DataFrame
    heldout: dict[str, pd.DataFrame]
    margin: float


def gate_inputs(machine: str, axes: Sequence[str], margin: float) -> GateInputs | None:
    """Read the machine's separated rows and each axis' held-out predictions of its champion.

    None when no axis has a champion (nothing to gate).

    Raises
    ------
    MissingInputError
        If the separated table is missing.
    """
    if not axes:
        return None
    if not SPINDLE_THERMAL_ERROR.is_file():
        raise MissingInputError(
            f"{SPINDLE_THERMAL_ERROR} not found: the promotion gate scores the champions on it; "
            "run `dvc repro separate_spindle` first"
        )
    table = pd.read_parquet(SPINDLE_THERMAL_ERROR)
    table = table.loc[table[MACHINE_COLUMN] == machine].reset_index(drop=True)
    folder = champion_folder(machine)
    heldout = {
        axis: pd.read_parquet(folder / axis / CHAMPION_HELDOUT_FILE)
        for axis in axes
        if (folder / axis / CHAMPION_HELDOUT_FILE).is_file()
    }
    return GateInputs(table, heldout, margin)


def _gate(target: _Target, parent_id: str, prepared: Prepared, gate: GateInputs) -> list:
    """Run the promotion gate on the versions this execution registered (or reused)."""
    from pipeline.tracking.promotion import run_gate

    names = {
        axis: registered_name(target.prefix, prepared.machine, axis) for axis in prepared.champions
    }
    found = store.parent_versions(
        target.client, target.experiment_id, parent_id, list(names.values())
    )
    challengers = {axis: found.get(name) for axis, name in names.items()}
    return run_gate(target.client, names, challengers, gate.table, gate.heldout, gate.margin)


@dataclass(frozen=True)
class _Target:
    """Where a pipeline run goes: client, experiment, store URI, registered-model prefix."""

    client: Any
    experiment_id: str
    experiment: str
    uri: str
    prefix: str


def _log_parent(target: _Target, prepared: Prepared, n_metrics: int) -> tuple[str, bool]:
    """Log the parent and child runs, or reuse a finished parent of the same identity.

    Returns
    -------
    parent_id : str
    reused : bool
        True when the store already held this run identity (nothing logged; the champion
        aliases restored).
    """
    client, experiment_id, uri = target.client, target.experiment_id, target.uri
    for deleted in store.discard_incomplete(client, experiment_id, prepared.identity.value):
        logger.info("deleted the incomplete earlier attempt %s (same run identity)", deleted)
    existing = store.find_parent(client, experiment_id, prepared.identity.value)
    if existing is not None:
        parent_id = existing.info.run_id
        logger.info(
            "machine %s: run identity %s already logged as parent run %s in experiment '%s' "
            "(%s): code, params, its raw data and scores unchanged, nothing logged",
            prepared.machine,
            prepared.identity.value[:12],
            parent_id,
            target.experiment,
            store.public_uri(uri),
        )
        return parent_id, True
    hook = champion_hook(
        absolute_store_uri(uri), target.prefix, prepared.machine, prepared.champions
    )
    parent_id = store.log_pipeline(
        client,
        experiment_id,
        prepared.parent,
        prepared.children,
        artifact_files(),
        hook,
    )
    logger.info(
        "machine %s: logged parent run %s with %d child runs and %d metrics to experiment "
        "'%s' (%s)",
        prepared.machine,
        parent_id,
        len(prepared.children),
        n_metrics,
        target.experiment,
        store.public_uri(uri),
    )
    return parent_id, False


def _registered_champions(target: _Target, prepared: Prepared) -> dict[str, dict]:
    """Each axis' registered champion: model name, version, URI, candidate, compensate."""
    entries = {}
    for axis, card in prepared.champions.items():
        name = registered_name(target.prefix, prepared.machine, axis)
        version = store.champion_version(target.client, name, "champion")
        entries[axis] = {
            "registered_model": name,
            "version": version,
            "uri": f"models:/{name}@champion" if version else None,
            "model": "/".join(str(card[k]) for k in records.KEY_COLUMNS[1:]),
            "compensate": card["compensate"],
        }
    return entries

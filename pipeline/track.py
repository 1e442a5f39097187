"""The ``track`` stage: log the cross-season scores of one pipeline execution to MLflow.

``thermal track`` (run from the repository root) reads the select and evaluate outputs
(``reports/selection/selected.json``, ``reports/fitted_models.json``,
``reports/cross_season_scores.csv``, ``metrics/cross_season.json``,
``data/models/champion/<axis>/``) and logs

- one parent run per pipeline execution: overall scores
  ``<axis>.<model>.<selection>.<mode>.<scheme>.<key>`` (um) and each axis' champion
  (``<axis>.champion.*``), the whole ``params.yaml`` and every selection's inputs
  (``selected.<axis>.<method>.<unit>``) as parameters, tags ``run_identity``, ``git_commit``,
  ``synthetic``, ``dvc.*`` (md5 hashes from ``dvc.lock``), ``skipped.<axis>.<candidate>`` (why
  a candidate was not scored), the report files (comparison report, matrices, selection
  evidence) as artifacts;
- one child run per candidate (axis, model, selection, mode) with its summary scores, every
  cross-campaign score and what each fit decided (see :mod:`pipeline.tracking.records`); the
  child of each axis' champion (tag ``champion: true``) also holds the champion model, with
  its signature and an input example, registered as ``<track.registered_model>-<axis>`` with
  the alias ``champion``.

The store is ``$MLFLOW_TRACKING_URI`` when set, else ``track.default_tracking_uri``
(``sqlite:///mlflow.db`` in the working directory, artifacts in ``mlartifacts/`` beside it).
When the store already holds a finished parent with the same run identity (see
:mod:`pipeline.tracking.identity`) nothing is logged. ``reports/mlflow_run.json`` records
where the run is.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import pandera.pandas as pa
import yaml

from pipeline.config import DEFAULT_PARAMS, load_section
from pipeline.errors import InputDataError, MissingInputError, ParamsError
from pipeline.paths import (
    AXIS_MODEL_METRICS,
    AXIS_MODEL_PLOT,
    AXIS_MODEL_REPORT,
    CANDIDATE_SCORES,
    CHAMPION,
    CHAMPION_CARD_FILE,
    CHAMPION_ESTIMATOR_FILE,
    COMPARISON_FIGURES,
    CROSS_SEASON_METRICS,
    DISCREPANCY_RECORD,
    FITTED_MODELS,
    GROUP_SCORES,
    MATRICES,
    MATRIX_CSV,
    MODEL_COMPARISON,
    RAW,
    SCORES_LONG,
    SELECTED,
    SELECTION,
    SEPARATION_PLOTS,
    TRACKING_RECORD,
    VALIDATION_REPORT,
)
from pipeline.tracking import guide, records, store, views
from pipeline.tracking import identity as ident
from schemas.evaluated import CrossSeasonScoresModel

logger = logging.getLogger(__name__)

DVC_LOCK = Path("dvc.lock")
ENV_TRACKING_URI = "MLFLOW_TRACKING_URI"
DEFAULT_TRACKING_URI = "sqlite:///mlflow.db"
DEFAULT_ARTIFACT_DIR = "mlartifacts"
SCORE_FILES = (
    SCORES_LONG,
    CANDIDATE_SCORES,
    GROUP_SCORES,
    CROSS_SEASON_METRICS,
    FITTED_MODELS,
    SELECTED,
    AXIS_MODEL_METRICS,
)
DEFAULT_REGISTERED_MODEL = "thermal-error-spindle"


def resolve_tracking_uri(settings: Mapping[str, Any]) -> str:
    """Return ``$MLFLOW_TRACKING_URI`` if set and not empty, else the configured default."""
    return os.environ.get(ENV_TRACKING_URI) or str(
        settings.get("default_tracking_uri") or DEFAULT_TRACKING_URI
    )


def absolute_store_uri(uri: str) -> str:
    """Return ``uri`` with a relative SQLite path made absolute (from the working directory).

    MLflow caches one store per URI string in a process, so a relative ``sqlite:///mlflow.db``
    would keep pointing at the first working directory's file.
    """
    path = store.sqlite_path(uri)
    if path is None or Path(path).is_absolute():
        return uri
    query = uri.split("?", 1)[1] if "?" in uri else ""
    return f"sqlite:///{Path(path).resolve().as_posix()}" + (f"?{query}" if query else "")


def local_artifact_location(uri: str, artifact_dir: str, experiment: str) -> str | None:
    """Artifact root of a new experiment in a local SQLite store, else ``None``.

    Parameters
    ----------
    uri : str
        Tracking URI. For ``sqlite:///<path>`` (relative to the working directory) or
        ``sqlite:////<absolute path>`` the artifacts go to ``<db folder>/<artifact_dir>/
        <experiment>/<run id>/artifacts``; other stores (a tracking server) choose themselves.
    artifact_dir : str
        Folder name beside the database, e.g. ``mlartifacts``.
    experiment : str
        Experiment name, used as sub-folder (unsafe characters replaced by ``_``).

    Returns
    -------
    str or None
        A ``file://`` URI, or ``None`` for non-SQLite or in-memory stores.
    """
    db_path = store.sqlite_path(uri)
    if db_path is None:
        return None
    folder = records.safe_key(experiment).replace("/", "_").replace(" ", "_")
    return (Path(db_path).resolve().parent / artifact_dir / folder).as_uri()


def read_json(path: Path) -> Any:
    """Read a JSON file written by an earlier stage.

    Raises
    ------
    FileNotFoundError
        Naming the file and the stage to run.
    ValueError
        If the file is not valid JSON, with the line and column.
    """
    if not path.is_file():
        raise MissingInputError(
            f"{path} not found: the track stage logs the evaluate outputs; run `dvc repro "
            "evaluate` (or `thermal evaluate`) first"
        )
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as error:
        raise InputDataError(
            f"{path}: invalid JSON at line {error.lineno}, column {error.colno} ({error.msg}); "
            "rerun the evaluate stage"
        ) from None


def _schema_problems(path: Path, errors: pa.errors.SchemaErrors, limit: int = 10) -> str:
    cases = errors.failure_cases
    lines = []
    for check, group in cases.groupby("check", sort=False):
        rows = sorted({int(i) + 1 for i in group["index"].dropna()})
        if (group["schema_context"] == "Column").all():
            for _, case in group.head(limit).iterrows():
                row = "" if pd.isna(case["index"]) else f"data row {int(case['index']) + 1}, "
                value = case["failure_case"]
                lines.append(f"{path}, {row}column '{case['column']}': {value!r} fails {check}")
        else:
            lines.append(f"{path}, data rows {rows[:limit]}: check {check} failed")
    more = f" (and {len(lines) - limit} more)" if len(lines) > limit else ""
    return "; ".join(lines[:limit]) + more


def read_scores(path: Path) -> list[dict[str, Any]]:
    """Read and validate the long score table (``schemas.evaluated.CrossSeasonScoresModel``).

    Returns
    -------
    list of dict
        One dict per data row, in file order: key columns as str, ``n_samples`` int, scores
        float (um, NaN when empty; pandas' default round-trip parsing, equal to ``float``).

    Raises
    ------
    FileNotFoundError
        If the file is missing, naming the stage to run.
    ValueError
        If the table breaks its schema, naming the data rows, columns and checks.
    """
    if not path.is_file():
        raise MissingInputError(
            f"{path} not found: the track stage logs the evaluate outputs; run `dvc repro "
            "evaluate` (or `thermal evaluate`) first"
        )
    text_columns = [
        *records.KEY_COLUMNS, "scheme", "train_unit", "test_campaign", "test_split",
        "test_season", "role",
    ]  # fmt: skip
    nan_text = ["", "nan", "NaN"]
    table = pd.read_csv(
        path,
        dtype=dict.fromkeys(text_columns, "str"),
        keep_default_na=False,
        na_values=dict.fromkeys([*records.SCORE_COLUMNS, "uncompensated_rms_um"], nan_text),
    )
    if table.empty:
        return []
    try:
        table = CrossSeasonScoresModel.validate(table, lazy=True)
    except pa.errors.SchemaErrors as errors:
        raise InputDataError(
            f"{_schema_problems(path, errors)}; rerun the evaluate stage (dvc repro evaluate)"
        ) from None
    return table.to_dict("records")


def artifact_files() -> list[tuple[Path, str]]:
    """Report files that exist, each with the artifact folder that mirrors its own folder."""
    candidates = [
        MODEL_COMPARISON,
        MATRIX_CSV,
        SCORES_LONG,
        CANDIDATE_SCORES,
        FITTED_MODELS,
        CROSS_SEASON_METRICS,
        VALIDATION_REPORT,
        AXIS_MODEL_REPORT,
        AXIS_MODEL_PLOT,
        *sorted(COMPARISON_FIGURES.glob("*.png")),
        *sorted(MATRICES.glob("*.png")),
        *sorted(SELECTION.glob("*")),
        *sorted(SEPARATION_PLOTS.glob("*.png")),
    ]
    return [(path, path.parent.as_posix()) for path in candidates if path.is_file()]


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    return Path(next(iter(spec.submodule_search_locations)))


def _load_params(path: Path) -> dict[str, Any]:
    with path.open(encoding="utf-8") as handle:
        return yaml.safe_load(handle) or {}


def _parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="thermal track",
        description=(
            "Log the evaluate outputs to MLflow: one parent run per pipeline execution, one "
            "child per candidate model/selection/mode, and register the champion. Store: "
            f"${ENV_TRACKING_URI} or {DEFAULT_TRACKING_URI}; writes {TRACKING_RECORD}."
        ),
    )
    parser.add_argument("--params", default=str(DEFAULT_PARAMS), help="params file (params.yaml)")
    return parser.parse_args(argv)


def champion_cards() -> dict[str, dict]:
    """Each axis' champion card (``data/models/champion/<axis>/champion.json``), by axis."""
    if not CHAMPION.is_dir():
        return {}
    return {
        folder.name: read_json(folder / CHAMPION_CARD_FILE)
        for folder in sorted(CHAMPION.iterdir())
        if (folder / CHAMPION_CARD_FILE).is_file() and (folder / CHAMPION_ESTIMATOR_FILE).is_file()
    }


@dataclass(frozen=True)
class Prepared:
    """Everything to log, computed before MLflow is imported."""

    identity: ident.RunIdentity
    synthetic: str
    git_commit: str
    parent: records.RunRecord
    children: list[records.RunRecord]
    champions: dict[str, dict]


def read_table(path: Path, text_columns: list[str]) -> list[dict[str, Any]]:
    """Read an evaluate table (``model_scores.csv``, ``heldout_scores.csv``) as rows.

    Raises
    ------
    MissingInputError
        If the file is missing, naming the stage to run.
    """
    if not path.is_file():
        raise MissingInputError(
            f"{path} not found: the track stage logs the evaluate outputs; run `dvc repro "
            "evaluate` (or `thermal evaluate`) first"
        )
    missing = {column: ["", "nan", "NaN"] for column in _numeric(path, text_columns)}
    table = pd.read_csv(
        path, dtype=dict.fromkeys(text_columns, "str"), keep_default_na=False, na_values=missing
    )
    return table.to_dict("records")


def _numeric(path: Path, text_columns: list[str]) -> list[str]:
    header = path.read_text(encoding="utf-8").split("\n", 1)[0].strip().split(",")
    return [column for column in header if column not in text_columns]


def heatmaps() -> dict[records.ChildKey, str]:
    """Each candidate's heat-map (``reports/matrices/<axis>__<model>__<selection>__<mode>.png``)."""
    found = {}
    for path in sorted(MATRICES.glob("*.png")):
        key = tuple(path.stem.split("__"))
        if len(key) == len(records.KEY_COLUMNS):
            found[key] = str(path)
    return found


def discrepancy_run_id() -> str | None:
    """Return the MLflow run the discrepancy stage logged in this ``dvc repro``, if any."""
    if not DISCREPANCY_RECORD.is_file():
        return None
    try:
        run_id = json.loads(DISCREPANCY_RECORD.read_text(encoding="utf-8")).get("run_id")
    except (json.JSONDecodeError, AttributeError):
        logger.warning(
            "%s is not a JSON object: the discrepancy run is not linked", DISCREPANCY_RECORD
        )
        return None
    return str(run_id) if run_id else None


def child_inputs(cards: Mapping[str, Mapping[str, Any]]) -> records.ChildInputs:
    """Read the evaluate outputs every child record is built from."""
    keys = list(records.KEY_COLUMNS)
    text = [*keys, "ineligible_reason", "eligible", "champion"]
    return records.ChildInputs(
        scores=records.rows_by_child(read_scores(SCORES_LONG)),
        summaries=records.summaries_by_child(read_table(CANDIDATE_SCORES, text)),
        groups=records.groups_by_child(
            read_table(GROUP_SCORES, [*keys, "scheme", "split", "held_out", "name"])
        ),
        units=records.unit_tables(read_json(CROSS_SEASON_METRICS)),
        fits=records.fits_by_candidate(read_json(FITTED_MODELS)),
        ranked_by={axis: str(card.get("chosen_on") or "") for axis, card in cards.items()},
        heatmaps=heatmaps(),
        champions=frozenset(
            (axis, *(str(card[k]) for k in records.KEY_COLUMNS[1:])) for axis, card in cards.items()
        ),
    )


def prepare(params_path: Path) -> Prepared:
    """Read the evaluate outputs and provenance, compute the identity, build the run records."""
    all_params = _load_params(params_path)
    cross_season = read_json(CROSS_SEASON_METRICS)
    selected = read_json(SELECTED)["axes"]
    axis_model = read_json(AXIS_MODEL_METRICS) if AXIS_MODEL_METRICS.is_file() else {}

    code_dirs = [_package_dir("pipeline"), _package_dir("schemas")]
    cards = champion_cards()
    card_files = [CHAMPION / axis / CHAMPION_CARD_FILE for axis in cards]
    run_identity = ident.compute_identity(code_dirs, all_params, RAW, [*SCORE_FILES, *card_files])
    synthetic = ident.synthetic_flag(RAW)
    commit = ident.git_commit()
    dvc_hashes = ident.dvc_lock_hashes(ident.read_dvc_lock(DVC_LOCK), RAW.as_posix())
    own = f":{TRACKING_RECORD.as_posix()}"  # the previous run's record: stale, not data
    dvc_hashes = {key: md5 for key, md5 in dvc_hashes.items() if not key.endswith(own)}
    tags = records.provenance_tags(
        run_identity.value, run_identity.parts, commit, dvc_hashes, synthetic
    )
    tags[records.NOTE_TAG] = guide.parent_description(commit, synthetic, run_identity.value, cards)
    for axis, card in cards.items():
        tags[records.safe_key(records.RANKED_BY_TAG, axis)] = str(card.get("chosen_on") or "-")
        label = "/".join(str(card[k]) for k in records.KEY_COLUMNS[1:])
        tags[records.safe_key(records.CHAMPION_TAG, axis)] = f"{axis}/{label}"
    children = records.child_records(child_inputs(cards), {"synthetic": synthetic})
    parent = records.parent_record(
        f"pipeline-{run_identity.value[:12]}",
        cross_season,
        all_params,
        tags,
        selected,
        axis_model,
    )
    return Prepared(run_identity, synthetic, commit, parent, children, cards)


def registered_name(prefix: str, axis: str) -> str:
    """Return the registered model name of an axis' champion, e.g. ``thermal-error-spindle-Z``."""
    return f"{prefix}-{axis}"


def champion_hook(tracking_uri: str, prefix: str, cards: dict[str, dict]):
    """Return a callback that logs and registers each axis' champion from its child run.

    ``None`` (with a warning) when evaluate wrote no champion.
    """
    if not cards:
        logger.warning("%s/<axis>/ not found: no champion model to register", CHAMPION)
        return None

    def register(record: records.RunRecord, run_id: str) -> None:
        axis = record.tags.get("axis")
        if record.tags.get(records.CHAMPION_TAG) != "true" or axis not in cards:
            return
        from pipeline.tracking.champion_model import log_and_register

        log_and_register(tracking_uri, run_id, registered_name(prefix, axis), CHAMPION / axis)

    return register


def main(argv: list[str] | None = None) -> int:
    """Run the track stage; return the exit code (0 on success)."""
    args = _parse_args(list(argv or []))
    started = time.perf_counter()
    settings = load_section("track", args.params)
    experiment = str(settings.get("experiment") or "thermal-error")
    batch_size = int(settings.get("batch_size", 1000))
    if not 1 <= batch_size <= 1000:
        raise ParamsError(
            f"{args.params}: track.batch_size = {batch_size}; MLflow accepts 1 to 1000 metrics "
            "per log_batch call, set a value in that range"
        )
    prepared = prepare(Path(args.params))
    n_metrics = records.count_metrics([prepared.parent, *prepared.children])
    ready = time.perf_counter()
    uri = resolve_tracking_uri(settings)
    try:
        record = _log(prepared, settings, uri, experiment, batch_size, n_metrics)
    except store.UNREACHABLE as error:
        raise SystemExit(unreachable_message(uri, error)) from error
    finished = time.perf_counter()
    logger.info(
        "track took %.2f s (reading and hashing %.2f s, MLflow %.2f s)",
        finished - started,
        ready - started,
        finished - ready,
    )
    record["metrics"] = n_metrics
    TRACKING_RECORD.parent.mkdir(parents=True, exist_ok=True)
    TRACKING_RECORD.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return 0


def unreachable_message(uri: str, error: BaseException) -> str:
    """Return the message of a track stage that could not log: nothing lost, how to log later."""
    return (
        f"thermal track: the MLflow tracking store {store.public_uri(uri)} cannot be used "
        f"({str(error).strip()[:300]}). Nothing is lost: the scores, reports and champion models "
        "of this pipeline execution are DVC outputs (reports/, metrics/, data/models/champion/) "
        "and stay as they are. When the store can be reached (start the server, or fix "
        "MLFLOW_TRACKING_URI; unset it to log to the local store sqlite:///mlflow.db), run "
        "'bin/thermal track' from the repository root, or 'dvc repro' (.venv/bin/dvc), which "
        "reruns only this stage: the execution is logged once, and a partly logged attempt of "
        "it is deleted, not duplicated."
    )


def _log(
    prepared: Prepared,
    settings: Mapping[str, Any],
    uri: str,
    experiment: str,
    batch_size: int,
    n_metrics: int,
) -> dict[str, Any]:
    """Log ``prepared`` to the store at ``uri`` unless it is there; return the run record."""
    client = store.make_client(absolute_store_uri(uri))
    artifact_dir = str(settings.get("local_artifact_dir") or DEFAULT_ARTIFACT_DIR)
    experiment_id = store.ensure_experiment(
        client, experiment, local_artifact_location(uri, artifact_dir, experiment)
    )
    prefix = str(settings.get("registered_model") or DEFAULT_REGISTERED_MODEL)
    for deleted in store.discard_incomplete(client, experiment_id, prepared.identity.value):
        logger.info("deleted the incomplete earlier attempt %s (same run identity)", deleted)
    existing = store.find_parent(client, experiment_id, prepared.identity.value)
    if existing is not None:
        parent_id = existing.info.run_id
        logger.info(
            "run identity %s already logged as parent run %s in experiment '%s' (%s): "
            "code, params, raw data and scores unchanged, nothing logged",
            prepared.identity.value[:12],
            parent_id,
            experiment,
            store.public_uri(uri),
        )
        names = [registered_name(prefix, axis) for axis in prepared.champions]
        store.restore_champions(client, experiment_id, parent_id, names, "champion")
    else:
        parent_id = store.log_pipeline(
            client, experiment_id, prepared.parent, prepared.children, artifact_files(),
            batch_size, champion_hook(absolute_store_uri(uri), prefix, prepared.champions),
        )  # fmt: skip
        logger.info(
            "logged parent run %s with %d child runs and %d metrics to experiment '%s' (%s)",
            parent_id,
            len(prepared.children),
            n_metrics,
            experiment,
            store.public_uri(uri),
        )
    store.describe_experiment(client, experiment_id, guide.experiment_description(experiment))
    ranked_by = {
        axis: str(card.get("chosen_on") or "") for axis, card in prepared.champions.items()
    }
    shared = views.shared_views(parent_id, prepared.children, ranked_by)
    store.share_views(client, experiment_id, shared)
    discrepancy = discrepancy_run_id()
    linked = discrepancy is not None and store.link_runs(
        client, parent_id, discrepancy, "discrepancy"
    )
    registered = {axis: registered_name(prefix, axis) for axis in prepared.champions}
    versions = {
        axis: store.champion_version(client, name, "champion") for axis, name in registered.items()
    }
    return {
        "tracking_uri": store.public_uri(uri),
        "experiment": experiment,
        "experiment_id": experiment_id,
        "parent_run_id": parent_id,
        "run_identity": prepared.identity.value,
        "identity_parts": prepared.identity.parts,
        "reused": existing is not None,
        "child_runs": len(prepared.children),
        "champions": {
            axis: {
                "registered_model": name,
                "version": versions[axis],
                "uri": f"models:/{name}@champion" if versions[axis] else None,
                "model": "/".join(
                    str(prepared.champions[axis][k]) for k in records.KEY_COLUMNS[1:]
                ),
                "compensate": prepared.champions[axis]["compensate"],
            }
            for axis, name in registered.items()
        },
        "git_commit": prepared.git_commit,
        "synthetic": prepared.synthetic,
        "discrepancy_run_id": discrepancy if linked else None,
        "views": {key: views.view_path(experiment_id, key) for key in shared},
    }

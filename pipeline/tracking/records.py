"""Turn the evaluate outputs into MLflow run records (pure: no files, no MLflow).

One parent record per pipeline execution (overall scores, all parameters, provenance tags) and
one child record per (model, selection, train campaign) found in ``reports/fitted_models.json``,
``reports/cross_season_scores.csv`` or the ``by_train_campaign`` part of
``metrics/cross_season.json``. A child's metrics are every cross-campaign score of its rows,
``rmse_um.<test campaign>`` and ``resid_std_um.<test campaign>`` (um), plus the keys of its
``by_train_campaign`` entry (``S_um``, ``Mn_um``, ``Sd_um``, ...).
"""

from __future__ import annotations

import json
import logging
import math
import posixpath
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

logger = logging.getLogger(__name__)

SCORE_COLUMNS = ("rmse_um", "resid_std_um")
KEY_COLUMNS = ("model", "selection", "train_campaign")
REQUIRED_SCORE_COLUMNS = (*KEY_COLUMNS, "test_campaign", *SCORE_COLUMNS)
IDENTITY_TAG = "run_identity"
PARENT_RUN_TAG = "mlflow.parentRunId"
MAX_PARAM_LENGTH = 6000  # MLflow's limit on a parameter value (characters)
MAX_TAG_LENGTH = 8000  # MLflow's limit on a tag value (characters)

_BAD_KEY_CHARS = re.compile(r"[^\w.\- /]")

ChildKey = tuple[str, str, str]


@dataclass(frozen=True)
class RunRecord:
    """What one MLflow run receives.

    Attributes
    ----------
    name : str
        Run name shown in the UI, e.g. ``"mlr/all/K01"``.
    params : dict of str to str
        Parameters (strings of at most 6000 characters).
    metrics : dict of str to float
        Metrics, scores in um.
    tags : dict of str to str
        Tags (the parent-run link is added by the writer).
    """

    name: str
    params: dict[str, str] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    tags: dict[str, str] = field(default_factory=dict)


def safe_key(*parts: str) -> str:
    """Join ``parts`` with ``.`` into a valid MLflow metric/param/tag key.

    Characters other than letters, digits, ``_ - . /`` and space become ``_``; a key that
    would not survive path normalisation (``a//b``, ``../x``) has its slashes replaced too.
    """
    key = ".".join(_BAD_KEY_CHARS.sub("_", str(part)) for part in parts)
    if posixpath.normpath(key) != key or key.startswith(("/", "..")) or key == ".":
        key = key.replace("/", "_")
    return key[:250]


def _text(value: Any, limit: int, what: str) -> str:
    text = value if isinstance(value, str) else json.dumps(value, sort_keys=True, default=str)
    if len(text) > limit:
        logger.warning("%s is %d characters long; truncated to MLflow's %d", what, len(text), limit)
        text = text[: limit - 3] + "..."
    return text


def flatten(mapping: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested mappings into ``{"a.b.c": leaf}``; lists and scalars are leaves."""
    flat: dict[str, Any] = {}
    for key, value in mapping.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping) and value:
            flat.update(flatten(value, name))
        else:
            flat[name] = value
    return flat


def _as_metric(value: Any) -> float | None:
    if isinstance(value, bool) or value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def parse_score(value: Any, source: str, row: int, column: str) -> float:
    """Parse one score cell: a number as is, text as Python ``float`` (empty or ``nan`` is NaN).

    Raises
    ------
    ValueError
        Naming the file, data row and column when the cell is not a number.
    """
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    text = "" if value is None else str(value)
    stripped = text.strip()
    if stripped == "":
        return math.nan
    try:
        return float(stripped)
    except ValueError:
        raise ValueError(
            f"{source}, data row {row}, column '{column}': '{text}' is not a number; "
            "rerun the evaluate stage (dvc repro evaluate) to rewrite the scores"
        ) from None


def scores_by_child(
    rows: Sequence[Mapping[str, Any]], source: str = "cross_season_scores.csv"
) -> dict[ChildKey, dict[str, float]]:
    """Group the long score table into child metrics.

    Parameters
    ----------
    rows : sequence of mapping
        Rows of ``reports/cross_season_scores.csv`` (scores as numbers or text), in file
        order; row ``i`` is data row ``i + 1``.
    source : str
        File name used in error messages.

    Returns
    -------
    dict
        ``{(model, selection, train_campaign): {"rmse_um.<test>": um, "resid_std_um.<test>":
        um, ...}}``.

    Raises
    ------
    ValueError
        If a required column is missing, a score is not a number, or a (model, selection,
        train campaign, test campaign) row appears twice; the message names the row.
    """
    if rows:
        missing = [column for column in REQUIRED_SCORE_COLUMNS if column not in rows[0]]
        if missing:
            raise ValueError(
                f"{source}: missing column(s) {missing} (found {sorted(rows[0])}); "
                "rerun the evaluate stage (dvc repro evaluate)"
            )
    children: dict[ChildKey, dict[str, float]] = {}
    seen: dict[tuple[str, str, str, str], int] = {}
    for number, row in enumerate(rows, start=1):
        key = (row["model"], row["selection"], row["train_campaign"])
        test = row["test_campaign"]
        if (*key, test) in seen:
            raise ValueError(
                f"{source}, data row {number}: model={key[0]} selection={key[1]} "
                f"train_campaign={key[2]} test_campaign={test} already on data row "
                f"{seen[(*key, test)]}; each pair must be scored once, fix the evaluate stage"
            )
        seen[(*key, test)] = number
        metrics = children.setdefault(key, {})
        for column in SCORE_COLUMNS:
            metrics[safe_key(column, test)] = parse_score(row[column], source, number, column)
    return children


def _entry_metrics(entry: Mapping[str, Any]) -> dict[str, float]:
    metrics = {}
    for key, value in entry.items():
        number = _as_metric(value)
        if number is not None:
            metrics[safe_key(key)] = number
    return metrics


def _by_train(cross_season: Mapping[str, Any]) -> dict[ChildKey, Mapping[str, Any]]:
    entries = {}
    for model, selections in cross_season.items():
        for selection, body in (selections or {}).items():
            for train, entry in ((body or {}).get("by_train_campaign") or {}).items():
                entries[(str(model), str(selection), str(train))] = entry or {}
    return entries


def _fitted_by_key(fitted: Mapping[str, Any]) -> dict[ChildKey, Mapping[str, Any]]:
    entries = {}
    for name, entry in fitted.items():
        parts = name.split("/") if len(name.split("/")) == 3 else [None] * 3
        key = tuple(
            str(entry[column]) if entry.get(column) is not None else part
            for column, part in zip(KEY_COLUMNS, parts, strict=True)
        )
        if None in key:
            raise ValueError(
                f"fitted_models.json, entry '{name}': expected 'model/selection/train_campaign' "
                "or the keys model, selection, train_campaign; rerun the evaluate stage"
            )
        entries[key] = entry
    return entries


def child_records(
    fitted: Mapping[str, Any],
    score_rows: Sequence[Mapping[str, Any]],
    cross_season: Mapping[str, Any],
    tags: Mapping[str, str] | None = None,
) -> list[RunRecord]:
    """Build one child record per (model, selection, train campaign).

    Parameters
    ----------
    fitted : mapping
        ``reports/fitted_models.json``: ``{"<model>/<selection>/<train>": {"model",
        "selection", "train_campaign", "sensors": [...], "params": {...}}}``.
    score_rows : sequence of mapping
        Rows of ``reports/cross_season_scores.csv``.
    cross_season : mapping
        ``metrics/cross_season.json``.
    tags : mapping, optional
        Tags added to every child (e.g. ``synthetic``).

    Returns
    -------
    list of RunRecord
        Sorted by (model, selection, train campaign); the union of the keys of the three
        inputs (a key missing from one of them is logged as a warning).
    """
    scores = scores_by_child(score_rows)
    summaries = _by_train(cross_season)
    models = _fitted_by_key(fitted)
    records = []
    for key in sorted(set(scores) | set(summaries) | set(models)):
        model, selection, train = key
        name = "/".join(key)
        for what, table in (
            ("fitted_models.json", models),
            ("cross_season_scores.csv", scores),
            ("cross_season.json by_train_campaign", summaries),
        ):
            if key not in table:
                logger.warning("%s: no entry for %s; its child run lacks that part", what, name)
        entry = models.get(key, {})
        sensors = [str(sensor) for sensor in entry.get("sensors") or []]
        params = {
            "model": model,
            "selection": selection,
            "train_campaign": train,
            "sensors": _text(",".join(sensors), MAX_PARAM_LENGTH, f"{name} sensors"),
            "n_sensors": str(len(sensors)),
            "params": _text(entry.get("params") or {}, MAX_PARAM_LENGTH, f"{name} params"),
        }
        for param, value in flatten(entry.get("params") or {}).items():
            params[safe_key("params", param)] = _text(value, MAX_PARAM_LENGTH, f"{name} {param}")
        metrics = {**scores.get(key, {}), **_entry_metrics(summaries.get(key, {}))}
        child_tags = {
            **(tags or {}),
            "model": model,
            "selection": selection,
            "train_campaign": train,
        }
        records.append(RunRecord(name=name, params=params, metrics=metrics, tags=child_tags))
    return records


def parent_record(
    name: str,
    cross_season: Mapping[str, Any],
    params: Mapping[str, Any],
    tags: Mapping[str, str],
) -> RunRecord:
    """Build the parent record: overall scores, every parameter, provenance tags.

    Parameters
    ----------
    name : str
        Run name.
    cross_season : mapping
        ``metrics/cross_season.json``; each ``overall`` entry becomes metrics
        ``<model>.<selection>.<key>`` (um).
    params : mapping
        The whole parsed ``params.yaml``, flattened to ``<section>.<key>`` parameters.
    tags : mapping
        Provenance tags (identity, git commit, data hashes, synthetic flag).
    """
    metrics = {}
    for model, selections in cross_season.items():
        for selection, body in (selections or {}).items():
            for key, value in ((body or {}).get("overall") or {}).items():
                number = _as_metric(value)
                if number is not None:
                    metrics[safe_key(model, selection, key)] = number
    flat = {
        safe_key(key): _text(value, MAX_PARAM_LENGTH, f"params.yaml {key}")
        for key, value in flatten(params).items()
    }
    clean_tags = {safe_key(k): _text(v, MAX_TAG_LENGTH, f"tag {k}") for k, v in tags.items()}
    return RunRecord(name=name, params=flat, metrics=metrics, tags=clean_tags)


def provenance_tags(
    identity: str,
    identity_parts: Mapping[str, str],
    commit: str,
    dvc_hashes: Mapping[str, str],
    synthetic: str,
) -> dict[str, str]:
    """Tags of the parent run.

    Returns
    -------
    dict of str to str
        ``run_identity``, ``identity.<part>``, ``git_commit`` (and MLflow's
        ``mlflow.source.git.commit`` when known), ``synthetic``, ``dvc.data/raw`` and
        ``dvc.<stage>.<out path>`` (md5 from ``dvc.lock``), and a run description.
    """
    tags = {IDENTITY_TAG: identity, "git_commit": commit, "synthetic": synthetic}
    tags.update({safe_key("identity", part): value for part, value in identity_parts.items()})
    if commit != "unknown":
        tags["mlflow.source.git.commit"] = commit
    for name, value in dvc_hashes.items():
        stage, _, path = name.rpartition(":")
        tags[safe_key("dvc", stage, path) if stage else safe_key("dvc", path)] = value
    tags["mlflow.note.content"] = (
        f"Thermal-error pipeline run: git commit {commit}, synthetic data: {synthetic}, "
        f"identity {identity[:12]}. Child runs: one per model/selection/train campaign."
    )
    return tags


def count_metrics(records: Iterable[RunRecord]) -> int:
    """Total number of metric values in ``records``."""
    return sum(len(record.metrics) for record in records)

"""Turn the evaluate outputs into MLflow run records (pure: no files, no MLflow).

One parent record per pipeline execution (overall scores, all parameters, provenance tags,
each axis' champion) and one child record per candidate (axis, model, selection, mode) found in
``reports/cross_season_scores.csv`` or ``metrics/cross_season.json``, so that the MLflow UI
lists the candidates side by side. A child's metrics are its summary scores (``S_um``,
``Mn_um``, ``Sd_um``, ``Mn_val_um``... of the per-campaign protocol; ``loso.*`` leave one
season out or ``loco.*`` leave one campaign out; ``pooled.*`` built on all training campaigns;
``unit.<unit>.*`` per training unit; ``eta`` the compensation ratio) and every cross-campaign
score ``rmse_um.<train unit>.<test campaign>``, ``resid_std_um.<train unit>.<test campaign>``
(um) and ``eta.<train unit>.<test campaign>``.
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

SCORE_COLUMNS = ("rmse_um", "resid_std_um", "eta")
KEY_COLUMNS = ("axis", "model", "selection", "mode")
REQUIRED_SCORE_COLUMNS = (*KEY_COLUMNS, "train_unit", "test_campaign", *SCORE_COLUMNS)
SCHEME_PREFIX = {"campaign": "", "loso": "loso", "loco": "loco", "pooled": "pooled"}
CHAMPION_TAG = "champion"
IDENTITY_TAG = "run_identity"
PARENT_RUN_TAG = "mlflow.parentRunId"
MAX_PARAM_LENGTH = 6000  # MLflow's limit on a parameter value (characters)
MAX_TAG_LENGTH = 8000  # MLflow's limit on a tag value (characters)

_BAD_KEY_CHARS = re.compile(r"[^\w.\- /]")

ChildKey = tuple[str, ...]


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
        ``{(axis, model, selection, mode): {"rmse_um.<train unit>.<test>": um,
        "resid_std_um.<train unit>.<test>": um, "eta.<train unit>.<test>": 1, ...}}``.

    Raises
    ------
    ValueError
        If a required column is missing, a score is not a number, or an (axis, model,
        selection, mode, train unit, test campaign) row appears twice; the message names the
        row.
    """
    if rows:
        missing = [column for column in REQUIRED_SCORE_COLUMNS if column not in rows[0]]
        if missing:
            raise ValueError(
                f"{source}: missing column(s) {missing} (found {sorted(rows[0])}); "
                "rerun the evaluate stage (dvc repro evaluate)"
            )
    children: dict[ChildKey, dict[str, float]] = {}
    seen: dict[tuple[str, ...], int] = {}
    for number, row in enumerate(rows, start=1):
        key = tuple(str(row[column]) for column in KEY_COLUMNS)
        pair = (*key, str(row["train_unit"]), str(row["test_campaign"]))
        if pair in seen:
            raise ValueError(
                f"{source}, data row {number}: axis={key[0]} model={key[1]} selection={key[2]} "
                f"mode={key[3]} train_unit={pair[4]} test_campaign={pair[5]} already on data "
                f"row {seen[pair]}; each pair must be scored once, fix the evaluate stage"
            )
        seen[pair] = number
        metrics = children.setdefault(key, {})
        for column in SCORE_COLUMNS:
            metrics[safe_key(column, pair[4], pair[5])] = parse_score(
                row[column], source, number, column
            )
    return children


def _entry_metrics(entry: Mapping[str, Any], *prefix: str) -> dict[str, float]:
    metrics = {}
    for key, value in entry.items():
        number = _as_metric(value)
        if number is not None:
            metrics[safe_key(*prefix, key)] = number
    return metrics


def summary_metrics(cross_season: Mapping[str, Any]) -> dict[ChildKey, dict[str, float]]:
    """Summary scores per candidate from ``metrics/cross_season.json``.

    Returns
    -------
    dict
        ``{(axis, model, selection, mode): metrics}``: the ``campaign`` scheme's overall scores
        under their own names (``S_um``, ``Mn_um``...), the other schemes' as
        ``<SCHEME_PREFIX>.<key>``, and every training unit's as ``unit.<unit>.<key>`` (um).
    """
    found: dict[ChildKey, dict[str, float]] = {}
    for axis, body in cross_season.items():
        for model, selections in ((body or {}).get("candidates") or {}).items():
            for selection, modes in (selections or {}).items():
                for mode, schemes in (modes or {}).items():
                    key = (str(axis), str(model), str(selection), str(mode))
                    metrics = found.setdefault(key, {})
                    for scheme, entry in (schemes or {}).items():
                        prefix = SCHEME_PREFIX.get(scheme, scheme)
                        overall = (entry or {}).get("overall") or {}
                        metrics.update(_entry_metrics(overall, *([prefix] if prefix else [])))
                        for unit, scores in ((entry or {}).get("by_train_unit") or {}).items():
                            metrics.update(_entry_metrics(scores or {}, "unit", unit))
    return found


def _fitted_by_candidate(fitted: Mapping[str, Any]) -> dict[tuple[str, ...], list[Mapping]]:
    entries: dict[tuple[str, ...], list[Mapping]] = {}
    for name, entry in fitted.items():
        if not {"axis", "model", "selection", "train_unit"} <= set(entry):
            raise ValueError(
                f"fitted_models.json, entry '{name}': expected the keys axis, model, selection, "
                "train_unit; rerun the evaluate stage"
            )
        key = (str(entry["axis"]), str(entry["model"]), str(entry["selection"]))
        entries.setdefault(key, []).append(entry)
    return entries


def child_records(
    fitted: Mapping[str, Any],
    score_rows: Sequence[Mapping[str, Any]],
    cross_season: Mapping[str, Any],
    tags: Mapping[str, str] | None = None,
    champions: Mapping[str, Mapping[str, Any]] | None = None,
) -> list[RunRecord]:
    """Build one child record per candidate (axis, model, selection, mode).

    Parameters
    ----------
    fitted : mapping
        ``reports/fitted_models.json``: ``{"<axis>/<model>/<selection>/<unit>": {"axis",
        "model", "selection", "train_unit", "scheme", "inputs": [...], "chosen_params":
        {...}}}``.
    score_rows : sequence of mapping
        Rows of ``reports/cross_season_scores.csv``.
    cross_season : mapping
        ``metrics/cross_season.json``.
    tags : mapping, optional
        Tags added to every child (e.g. ``synthetic``).
    champions : mapping, optional
        Axis -> champion card; the champion's child gets the tag ``champion: true``.

    Returns
    -------
    list of RunRecord
        Sorted by (axis, model, selection, mode), named ``<axis>/<model>/<selection>/<mode>``.
        Parameters: ``axis``, ``model``, ``selection``, ``mode``, ``inputs.<unit>`` (chosen
        inputs, comma-separated) and ``chosen.<unit>.<name>`` (what each fit decided: lag
        order, components, penalty...). Metrics: see :func:`summary_metrics` and
        :func:`scores_by_child`.
    """
    scores = scores_by_child(score_rows)
    summaries = summary_metrics(cross_season)
    models = _fitted_by_candidate(fitted)
    winners = {
        (axis, str(card["model"]), str(card["selection"]), str(card["mode"]))
        for axis, card in (champions or {}).items()
    }
    records = []
    for key in sorted(set(scores) | set(summaries)):
        axis, model, selection, mode = key
        name = "/".join(key)
        for what, table in (("cross_season_scores.csv", scores), ("cross_season.json", summaries)):
            if key not in table:
                logger.warning("%s: no entry for %s; its child run lacks that part", what, name)
        params = {"axis": axis, "model": model, "selection": selection, "mode": mode}
        for entry in models.get((axis, model, selection), []):
            unit = str(entry["train_unit"])
            inputs = ",".join(str(sensor) for sensor in entry.get("inputs") or [])
            params[safe_key("inputs", unit)] = _text(inputs or "-", MAX_PARAM_LENGTH, name)
            for param, value in flatten(entry.get("chosen_params") or {}).items():
                params[safe_key("chosen", unit, param)] = _text(value, MAX_PARAM_LENGTH, name)
        metrics = {**scores.get(key, {}), **summaries.get(key, {})}
        child_tags = {
            **(tags or {}), "axis": axis, "model": model, "selection": selection, "mode": mode,
            CHAMPION_TAG: str(key in winners).lower(),
        }  # fmt: skip
        records.append(RunRecord(name=name, params=params, metrics=metrics, tags=child_tags))
    return records


def parent_record(
    name: str,
    cross_season: Mapping[str, Any],
    params: Mapping[str, Any],
    tags: Mapping[str, str],
    selected: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]] | None = None,
    axis_model: Mapping[str, Any] | None = None,
) -> RunRecord:
    """Build the parent record: overall scores, champions, every parameter, provenance tags.

    Parameters
    ----------
    name : str
        Run name.
    cross_season : mapping
        ``metrics/cross_season.json``: per axis, each candidate's schemes' ``overall`` entries
        become metrics ``<axis>.<model>.<selection>.<mode>.<scheme>.<key>`` (um), the
        ``champion`` entry metrics ``<axis>.champion.<key>``, and the ``skipped`` candidates
        tags ``skipped.<axis>.<candidate>`` (the reason).
    params : mapping
        The whole parsed ``params.yaml``, flattened to ``<section>.<key>`` parameters.
    tags : mapping
        Provenance tags (identity, git commit, data hashes, synthetic flag).
    selected : mapping, optional
        ``reports/selection/selected.json`` ``axes``; each method's choice on each training unit
        becomes a parameter ``selected.<axis>.<method>.<unit>`` (comma-separated inputs).
    axis_model : mapping, optional
        ``metrics/axis_model.json`` (linear-axis composite model); each number becomes a metric
        ``axis_model.<key>`` (um).
    """
    metrics = {}
    skipped = {}
    for axis, body in cross_season.items():
        for model, selections in ((body or {}).get("candidates") or {}).items():
            for selection, modes in (selections or {}).items():
                for mode, schemes in (modes or {}).items():
                    for scheme, entry in (schemes or {}).items():
                        for key, value in ((entry or {}).get("overall") or {}).items():
                            number = _as_metric(value)
                            if number is not None:
                                metrics[safe_key(axis, model, selection, mode, scheme, key)] = (
                                    number
                                )
        metrics.update(_entry_metrics((body or {}).get("champion") or {}, axis, "champion"))
        for candidate, reason in ((body or {}).get("skipped") or {}).items():
            skipped[safe_key("skipped", axis, candidate)] = str(reason)
    metrics.update(_entry_metrics(axis_model or {}, "axis_model"))
    flat = {
        safe_key(key): _text(value, MAX_PARAM_LENGTH, f"params.yaml {key}")
        for key, value in flatten(params).items()
    }
    for axis, methods in (selected or {}).items():
        for method, units in (methods or {}).items():
            for unit, choice in (units or {}).items():
                inputs = ",".join(str(s) for s in (choice or {}).get("inputs") or []) or "-"
                flat[safe_key("selected", axis, method, unit)] = _text(
                    inputs, MAX_PARAM_LENGTH, method
                )
    clean_tags = {
        safe_key(k): _text(v, MAX_TAG_LENGTH, f"tag {k}") for k, v in {**tags, **skipped}.items()
    }
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
        f"identity {identity[:12]}. Child runs: one per candidate axis/model/selection/mode; "
        "the tag champion=true marks each axis' champion."
    )
    return tags


def count_metrics(records: Iterable[RunRecord]) -> int:
    """Total number of metric values in ``records``."""
    return sum(len(record.metrics) for record in records)

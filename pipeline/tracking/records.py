"""Turn the evaluate outputs into MLflow run records (pure: no files, no MLflow).

One parent record per pipeline execution and one child record per candidate (axis, model,
selection, mode), so that the MLflow UI lists the candidates side by side and Compare shows
their evidence. Every score has one name everywhere (``model_scores.csv``,
``metrics/cross_season.json``, MLflow): the :func:`pipeline.protocol.scoring.candidate_summary`
column, e.g. ``loso_Mn_rms_um`` (see :mod:`pipeline.tracking.guide` for the vocabulary).

A child carries

- metrics: its headline scores (at most :data:`MAX_CHILD_METRICS`): the summary of every scheme
  and the score per held-out season (or campaign) and validation season
  (:func:`pipeline.protocol.scoring.group_scores`, e.g. ``loso_winter_rms_um``,
  ``loso_winter_eta``);
- tags: ``axis``, ``model``, ``selection``, ``mode``, ``eligible`` (``ineligible_reason`` when
  not), ``rank`` (on the axis' selection score, eligible candidates only), ``champion``,
  ``ranked_by``, ``warnings`` (what its fits warned, e.g. ``3 (ConvergenceWarning 3)``, with
  each category's first message in ``warnings.first``), and a run description
  (``mlflow.note.content``);
- tables (JSON table artifacts under ````): every (training unit, test campaign) score,
  every training unit's summary, the held-out groups, what each fit chose; and its heat-map.

The parent carries each axis' champion scores (``<axis>.champion.<name>``), the whole
``params.yaml``, every selection's inputs, provenance tags and a description.
"""

from __future__ import annotations

import json
import logging
import math
import posixpath
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from pipeline.tracking import guide
from pipeline.warnings_capture import WarningCounts

logger = logging.getLogger(__name__)

SCORE_COLUMNS = ("rmse_um", "resid_std_um", "eta")
KEY_COLUMNS = ("axis", "model", "selection", "mode")
REQUIRED_SCORE_COLUMNS = (*KEY_COLUMNS, "train_unit", "test_campaign", *SCORE_COLUMNS)
CHAMPION_TAG = "champion"
ELIGIBLE_TAG = "eligible"
RANK_TAG = "rank"
RANKED_BY_TAG = "ranked_by"
WARNINGS_TAG = "warnings"
FIRST_WARNINGS_TAG = "warnings.first"
NOTE_TAG = "mlflow.note.content"
MAX_CHILD_METRICS = 100
"""Most metrics on a child run: the headline scores; the rest go to its table artifacts."""
SCORES_TABLE = "scores.json"
UNITS_TABLE = "unit_scores.json"
GROUPS_TABLE = "heldout_scores.json"
FITS_TABLE = "fits.json"
HEATMAP = "cross_season_rms.png"
STANDING_COLUMNS = ("eligible", "ineligible_reason", "rank", "champion")
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
    tables : dict of str to list of dict
        Table artifacts: artifact file (e.g. ``scores.json``) -> rows.
    files : dict of str to str
        Files to log: artifact path (e.g. ``cross_season_rms.png``) -> local path.
    """

    name: str
    params: dict[str, str] = field(default_factory=dict)
    metrics: dict[str, float] = field(default_factory=dict)
    tags: dict[str, str] = field(default_factory=dict)
    tables: dict[str, list[dict]] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)


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


def rows_by_child(
    rows: Sequence[Mapping[str, Any]], source: str = "cross_season_scores.csv"
) -> dict[ChildKey, list[dict[str, Any]]]:
    """Group the long score table by candidate, scores parsed, for the child's table artifact.

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
        ``{(axis, model, selection, mode): [row, ...]}``: each row without the candidate keys,
        ``rmse_um``, ``resid_std_um`` (um) and ``eta`` as float (NaN when empty).

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
    children: dict[ChildKey, list[dict[str, Any]]] = {}
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
        parsed = {name: value for name, value in row.items() if name not in KEY_COLUMNS}
        for column in SCORE_COLUMNS:
            parsed[column] = parse_score(row[column], source, number, column)
        children.setdefault(key, []).append(parsed)
    return children


def _metrics(entry: Mapping[str, Any]) -> dict[str, float]:
    """Return the numeric entries of ``entry`` (booleans and text left out)."""
    metrics = {}
    for key, value in entry.items():
        number = _as_metric(value)
        if number is not None:
            metrics[safe_key(key)] = number
    return metrics


@dataclass(frozen=True)
class Standing:
    """Where a candidate stands in its axis' champion decision (``model_scores.csv``)."""

    eligible: bool
    reason: str
    rank: int
    champion: bool


def _flag(value: Any) -> bool:
    return str(value).strip().lower() in {"true", "1", "1.0"}


def summaries_by_child(
    summary_rows: Sequence[Mapping[str, Any]],
) -> dict[ChildKey, tuple[dict[str, float], Standing]]:
    """Each candidate's summary scores and standing from ``reports/model_scores.csv``.

    Returns
    -------
    dict
        ``{(axis, model, selection, mode): (scores, standing)}``: scores under their column
        names (``S_um``, ``loso_Mn_rms_um``, ``pooled_eta_val``, ``loso_coverage``...; um or
        dimensionless), NaN ones left out.
    """
    found = {}
    for row in summary_rows:
        key = tuple(str(row[column]) for column in KEY_COLUMNS)
        scores = {
            name: value
            for name, value in _metrics(
                {k: v for k, v in row.items() if k not in (*KEY_COLUMNS, *STANDING_COLUMNS)}
            ).items()
            if math.isfinite(value)
        }
        rank = _as_metric(row.get("rank"))
        reason = row.get("ineligible_reason")
        standing = Standing(
            _flag(row.get("eligible")),
            reason if isinstance(reason, str) else "",
            int(rank) if rank is not None and math.isfinite(rank) else 0,
            _flag(row.get("champion")),
        )
        found[key] = (scores, standing)
    return found


def groups_by_child(group_rows: Sequence[Mapping[str, Any]]) -> dict[ChildKey, list[dict]]:
    """Group the rows of ``reports/heldout_scores.csv`` by candidate (keys dropped)."""
    found: dict[ChildKey, list[dict]] = {}
    for row in group_rows:
        key = tuple(str(row[column]) for column in KEY_COLUMNS)
        found.setdefault(key, []).append({k: v for k, v in row.items() if k not in KEY_COLUMNS})
    return found


def group_metrics(groups: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """Per held-out group: ``<name>`` (mean RMS, um) and the same name ending ``_eta``."""
    metrics = {}
    for row in groups:
        name = str(row["name"])
        for key, value in (
            (name, row.get("rms_um")),
            (name.removesuffix("_rms_um") + "_eta", row.get("eta")),
        ):
            number = _as_metric(value)
            if number is not None and math.isfinite(number):
                metrics[safe_key(key)] = number
    return metrics


def unit_tables(cross_season: Mapping[str, Any]) -> dict[ChildKey, list[dict]]:
    """Each candidate's per-training-unit summaries (``metrics/cross_season.json``) as rows."""
    found: dict[ChildKey, list[dict]] = {}
    for axis, body in cross_season.items():
        for model, selections in ((body or {}).get("candidates") or {}).items():
            for selection, modes in (selections or {}).items():
                for mode, entry in (modes or {}).items():
                    key = (str(axis), str(model), str(selection), str(mode))
                    units = (entry or {}).get("by_train_unit") or {}
                    found[key] = [
                        {"train_unit": unit, **{k: _as_metric(v) for k, v in scores.items()}}
                        for unit, scores in units.items()
                    ]
    return found


def fits_by_candidate(fitted: Mapping[str, Any]) -> dict[tuple[str, ...], list[Mapping]]:
    """Group ``reports/fitted_models.json`` entries by (axis, model, selection)."""
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


def fit_rows(entries: Sequence[Mapping[str, Any]]) -> list[dict[str, str]]:
    """Return what each fit of a candidate used, chose and warned: one row per training unit."""
    return [
        {
            "train_unit": str(entry["train_unit"]),
            "inputs": ",".join(str(sensor) for sensor in entry.get("inputs") or []) or "-",
            "chosen_params": json.dumps(entry.get("chosen_params") or {}, sort_keys=True),
            "warnings": WarningCounts.from_dict(entry.get("warnings")).text(),
        }
        for entry in entries
    ]


def warning_tags(entries: Sequence[Mapping[str, Any]], name: str) -> dict[str, str]:
    """Return a candidate's ``warnings`` tags: its fits' warnings, summed over training units.

    Parameters
    ----------
    entries : sequence of mapping
        The candidate's ``reports/fitted_models.json`` entries (``warnings`` in each).
    name : str
        The child run's name, for the message when a tag is cut to MLflow's limit.

    Returns
    -------
    dict
        ``warnings``: ``0`` or e.g. ``3 (SingularMatrixWarning 2, ConvergenceWarning 1)``;
        ``warnings.first`` (when any): each category's first message, one per line.
    """
    counts = WarningCounts()
    for entry in entries:
        counts.add(WarningCounts.from_dict(entry.get("warnings")))
    tags = {WARNINGS_TAG: _text(counts.text(), MAX_TAG_LENGTH, name)}
    if counts.first:
        first = "\n".join(f"{category}: {message}" for category, message in counts.first.items())
        tags[FIRST_WARNINGS_TAG] = _text(first, MAX_TAG_LENGTH, name)
    return tags


def headline(scores: Mapping[str, float], groups: Mapping[str, float], name: str) -> dict:
    """Return the child's metrics: summary scores, then held-out groups within the limit."""
    metrics = dict(scores)
    room = MAX_CHILD_METRICS - len(metrics)
    if len(groups) > room:
        logger.warning(
            "%s: %d per-group scores, room for %d metrics: the rest are in %s only",
            name,
            len(groups),
            max(room, 0),
            GROUPS_TABLE,
        )
    metrics.update(dict(list(groups.items())[: max(room, 0)]))
    return metrics


@dataclass(frozen=True)
class ChildInputs:
    """The evaluate outputs a child record is built from, grouped by candidate."""

    scores: dict[ChildKey, list[dict]]
    summaries: dict[ChildKey, tuple[dict[str, float], Standing]]
    groups: dict[ChildKey, list[dict]]
    units: dict[ChildKey, list[dict]]
    fits: dict[tuple[str, ...], list[Mapping]]
    ranked_by: dict[str, str]
    heatmaps: dict[ChildKey, str]
    champions: frozenset[ChildKey] = frozenset()
    """The candidates registered as champions (from the champion cards, which are registered)."""


def child_records(inputs: ChildInputs, tags: Mapping[str, str] | None = None) -> list[RunRecord]:
    """Build one child record per candidate (axis, model, selection, mode).

    Parameters
    ----------
    inputs : ChildInputs
        The evaluate outputs by candidate (see :func:`child_inputs`).
    tags : mapping, optional
        Tags added to every child (e.g. ``synthetic``).

    Returns
    -------
    list of RunRecord
        Sorted by (axis, model, selection, mode), named ``<axis>/<model>/<selection>/<mode>``.
        Parameters: ``axis``, ``model``, ``selection``, ``mode`` and the inputs and decisions
        of the fit on all training campaigns (``inputs``, ``chosen.<name>``); the fits on the
        other training units are in the table ``fits.json``.
    """
    records = []
    for key in sorted(set(inputs.scores) | set(inputs.summaries)):
        axis, model, selection, mode = key
        name = "/".join(key)
        for what, table in (
            ("cross_season_scores.csv", inputs.scores),
            ("model_scores.csv", inputs.summaries),
        ):
            if key not in table:
                logger.warning("%s: no entry for %s; its child run lacks that part", what, name)
        scores, standing = inputs.summaries.get(key, ({}, Standing(False, "not scored", 0, False)))
        standing = replace(standing, champion=key in inputs.champions)
        groups = inputs.groups.get(key, [])
        fits = inputs.fits.get((axis, model, selection), [])
        params = {"axis": axis, "model": model, "selection": selection, "mode": mode}
        for entry in fits:
            if entry["train_unit"] == "all_training":
                inputs_text = ",".join(str(s) for s in entry.get("inputs") or []) or "-"
                params["inputs"] = _text(inputs_text, MAX_PARAM_LENGTH, name)
                for param, value in flatten(entry.get("chosen_params") or {}).items():
                    params[safe_key("chosen", param)] = _text(value, MAX_PARAM_LENGTH, name)
        ranked_by = inputs.ranked_by.get(axis, "")
        child_tags = {
            **(tags or {}),
            "axis": axis,
            "model": model,
            "selection": selection,
            "mode": mode,
            ELIGIBLE_TAG: str(standing.eligible).lower(),
            RANKED_BY_TAG: ranked_by or "-",
            CHAMPION_TAG: str(standing.champion).lower(),
            **warning_tags(fits, name),
        }
        if standing.rank:
            child_tags[RANK_TAG] = str(standing.rank)
        if not standing.eligible:
            child_tags["ineligible_reason"] = _text(standing.reason, MAX_TAG_LENGTH, name)
        child_tags[NOTE_TAG] = guide.child_description(name, standing, scores, groups, ranked_by)
        tables = {
            SCORES_TABLE: inputs.scores.get(key, []),
            UNITS_TABLE: inputs.units.get(key, []),
            GROUPS_TABLE: groups,
            FITS_TABLE: fit_rows(fits),
        }
        files = {HEATMAP: inputs.heatmaps[key]} if key in inputs.heatmaps else {}
        metrics = headline(scores, group_metrics(groups), name)
        records.append(RunRecord(name, params, metrics, child_tags, tables, files))
    return records


def parent_record(
    name: str,
    cross_season: Mapping[str, Any],
    params: Mapping[str, Any],
    tags: Mapping[str, str],
    selected: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]] | None = None,
    axis_model: Mapping[str, Any] | None = None,
) -> RunRecord:
    """Build the parent record: each axis' champion scores, every parameter, provenance tags.

    Parameters
    ----------
    name : str
        Run name.
    cross_season : mapping
        ``metrics/cross_season.json``: each axis' ``champion`` entry becomes metrics
        ``<axis>.champion.<name>`` (``Z.champion.loso_Mn_rms_um``,
        ``Z.champion.none.loso_Mn_rms_um``, ``Z.champion.compensate``...), the ``skipped``
        candidates tags ``skipped.<axis>.<candidate>`` (the reason). The candidates' own
        scores are on their child runs.
    params : mapping
        The whole parsed ``params.yaml``, flattened to ``<section>.<key>`` parameters.
    tags : mapping
        Provenance tags (identity, git commit, data hashes, synthetic flag), description.
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
        champion = flatten({"champion": (body or {}).get("champion") or {}}, str(axis))
        metrics.update(_metrics(champion))
        for candidate, reason in ((body or {}).get("skipped") or {}).items():
            skipped[safe_key("skipped", axis, candidate)] = str(reason)
    metrics.update(_metrics(flatten(axis_model or {}, "axis_model")))
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
        safe_key(k) if k != NOTE_TAG else k: _text(v, MAX_TAG_LENGTH, f"tag {k}")
        for k, v in {**tags, **skipped}.items()
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
        ``dvc.<stage>.<out path>`` (md5 from ``dvc.lock``).
    """
    tags = {IDENTITY_TAG: identity, "git_commit": commit, "synthetic": synthetic}
    tags.update({safe_key("identity", part): value for part, value in identity_parts.items()})
    if commit != "unknown":
        tags["mlflow.source.git.commit"] = commit
    for name, value in dvc_hashes.items():
        stage, _, path = name.rpartition(":")
        tags[safe_key("dvc", stage, path) if stage else safe_key("dvc", path)] = value
    return tags


def count_metrics(records: Iterable[RunRecord]) -> int:
    """Total number of metric values in ``records``."""
    return sum(len(record.metrics) for record in records)

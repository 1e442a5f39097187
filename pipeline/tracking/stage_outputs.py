"""The DVC outputs the ``track`` stage logs, read and checked.

The evaluate tables (``reports/cross_season_scores.csv`` validated by
:class:`schemas.evaluated.CrossSeasonScoresModel`, ``model_scores.csv``, ``heldout_scores.csv``),
the JSON records (metrics, fitted models, selections), each axis' champion card, the heat-maps,
the report files logged as artifacts and the discrepancy stage's run id. A missing or broken
file raises an error that names it and the stage to rerun.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd
import pandera.pandas as pa

from pipeline.errors import InputDataError, MissingInputError
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
    SCORES_LONG,
    SELECTED,
    SELECTION,
    SEPARATION_PLOTS,
    VALIDATION_REPORT,
)
from pipeline.tracking import records
from schemas.evaluated import CrossSeasonScoresModel

logger = logging.getLogger(__name__)


SCORE_FILES = (
    SCORES_LONG,
    CANDIDATE_SCORES,
    GROUP_SCORES,
    CROSS_SEASON_METRICS,
    FITTED_MODELS,
    SELECTED,
    AXIS_MODEL_METRICS,
)


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
        *records.KEY_COLUMNS,
        "scheme",
        "train_unit",
        "test_campaign",
        "test_split",
        "test_season",
        "role",
    ]
    nan_text = ["", "nan", "NaN"]
    table = pd.read_csv(
        path,
        dtype=dict.fromkeys(text_columns, "str"),
        keep_default_na=False,
        na_values=dict.fromkeys([*records.SCORE_COLUMNS, "uncompensated_rms_um"], nan_text),
    )
    if table.empty:
        return []
    # A column of whole numbers (e.g. eta = 0 of every row when `none` is the only candidate)
    # is read as integers: the scores are floats.
    for column in [*records.SCORE_COLUMNS, "uncompensated_rms_um"]:
        if column in table and pd.api.types.is_integer_dtype(table[column]):
            table[column] = table[column].astype(float)
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


def champion_cards() -> dict[str, dict]:
    """Each axis' champion card (``data/models/champion/<axis>/champion.json``), by axis."""
    if not CHAMPION.is_dir():
        return {}
    return {
        folder.name: read_json(folder / CHAMPION_CARD_FILE)
        for folder in sorted(CHAMPION.iterdir())
        if (folder / CHAMPION_CARD_FILE).is_file() and (folder / CHAMPION_ESTIMATOR_FILE).is_file()
    }


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

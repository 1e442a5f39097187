"""The DVC outputs the ``track`` stage logs, read and checked, one machine's part at a time.

The evaluate tables (``reports/cross_season_scores.csv`` validated by
:class:`schemas.evaluated.CrossSeasonScoresModel`, ``model_scores.csv``, ``heldout_scores.csv``),
the JSON records (metrics, fitted models, selections), each axis' champion card, the heat-maps,
the report files logged as artifacts and the discrepancy stage's run id. Every reader takes the
machine and returns its rows or entry alone (each machine is its own pipeline run). A missing or
broken file raises an error that names it and the stage to rerun.
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
from pipeline.machines import MACHINE_COLUMN, machine_key
from pipeline.paths import (
    AXIS_MODEL_METRICS,
    AXIS_MODEL_PLOTS,
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


def machine_entry(path: Path, machine: str) -> Any:
    """Read a JSON output ``{"machines": {machine: entry}}``; the machine's entry (empty: none).

    A machine without an entry (e.g. one with linear-axis campaigns only has no spindle
    scores) gets an empty one.
    """
    return (read_json(path).get("machines") or {}).get(machine) or {}


def read_scores(path: Path, machine: str | None = None) -> list[dict[str, Any]]:
    """Read and validate the long score table (``schemas.evaluated.CrossSeasonScoresModel``).

    Returns
    -------
    list of dict
        One dict per data row of ``machine`` (None: every row), in file order, without the
        ``machine`` column: key columns as str, ``n_samples`` int, scores float (um, NaN when
        empty; pandas' default round-trip parsing, equal to ``float``).

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
        MACHINE_COLUMN,
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
    return _machine_rows(table, machine).to_dict("records")


def _machine_rows(table: pd.DataFrame, machine: str | None) -> pd.DataFrame:
    """Return the machine's rows without the ``machine`` column (None: every row)."""
    if machine is None or MACHINE_COLUMN not in table:
        return table
    rows = table.loc[table[MACHINE_COLUMN] == machine]
    return rows.drop(columns=MACHINE_COLUMN).reset_index(drop=True)


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
        *sorted(AXIS_MODEL_PLOTS.glob("*.png")),
        *sorted(COMPARISON_FIGURES.glob("*.png")),
        *sorted(MATRICES.glob("*.png")),
        *sorted(SELECTION.glob("*")),
        *sorted(SEPARATION_PLOTS.glob("*.png")),
    ]
    return [(path, path.parent.as_posix()) for path in candidates if path.is_file()]


def champion_folder(machine: str) -> Path:
    """Return ``data/models/champion/<machine>/`` (the machine as ``machine_key`` writes it)."""
    return CHAMPION / machine_key(machine)


def champion_cards(machine: str) -> dict[str, dict]:
    """Each axis' champion card of the machine (``champion/<machine>/<axis>/champion.json``)."""
    folder = champion_folder(machine)
    if not folder.is_dir():
        return {}
    return {
        axis.name: read_json(axis / CHAMPION_CARD_FILE)
        for axis in sorted(folder.iterdir())
        if (axis / CHAMPION_CARD_FILE).is_file() and (axis / CHAMPION_ESTIMATOR_FILE).is_file()
    }


def read_table(
    path: Path, text_columns: list[str], machine: str | None = None
) -> list[dict[str, Any]]:
    """Read an evaluate table (``model_scores.csv``, ``heldout_scores.csv``) as rows.

    Only the rows of ``machine`` (None: every row), without the ``machine`` column.

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
    text_columns = [MACHINE_COLUMN, *text_columns]
    missing = {column: ["", "nan", "NaN"] for column in _numeric(path, text_columns)}
    table = pd.read_csv(
        path, dtype=dict.fromkeys(text_columns, "str"), keep_default_na=False, na_values=missing
    )
    return _machine_rows(table, machine).to_dict("records")


def _numeric(path: Path, text_columns: list[str]) -> list[str]:
    header = path.read_text(encoding="utf-8").split("\n", 1)[0].strip().split(",")
    return [column for column in header if column not in text_columns]


def heatmaps(machine: str) -> dict[records.ChildKey, str]:
    """Each candidate's heat-map of the machine, by child key.

    Files ``reports/matrices/<machine>__<axis>__<model>__<selection>__<mode>.png``.
    """
    found = {}
    for path in sorted(MATRICES.glob(f"{machine_key(machine)}__*.png")):
        key = tuple(path.stem.split("__")[1:])
        if len(key) == len(records.KEY_COLUMNS):
            found[key] = str(path)
    return found


def discrepancy_run_id(machine: str) -> str | None:
    """Return the machine's MLflow run the discrepancy stage logged in this ``dvc repro``."""
    if not DISCREPANCY_RECORD.is_file():
        return None
    try:
        run_ids = json.loads(DISCREPANCY_RECORD.read_text(encoding="utf-8")).get("machines")
        run_id = (run_ids or {}).get(machine)
    except (json.JSONDecodeError, AttributeError):
        logger.warning(
            "%s is not a JSON object: the discrepancy run is not linked", DISCREPANCY_RECORD
        )
        return None
    return str(run_id) if run_id else None


def child_inputs(machine: str, cards: Mapping[str, Mapping[str, Any]]) -> records.ChildInputs:
    """Read the machine's part of the evaluate outputs every child record is built from."""
    keys = list(records.KEY_COLUMNS)
    text = [*keys, "ineligible_reason", "eligible", "champion"]
    return records.ChildInputs(
        scores=records.rows_by_child(read_scores(SCORES_LONG, machine)),
        summaries=records.summaries_by_child(read_table(CANDIDATE_SCORES, text, machine)),
        groups=records.groups_by_child(
            read_table(GROUP_SCORES, [*keys, "scheme", "split", "held_out", "name"], machine)
        ),
        units=records.unit_tables(machine_entry(CROSS_SEASON_METRICS, machine)),
        fits=records.fits_by_candidate(machine_entry(FITTED_MODELS, machine)),
        ranked_by={axis: str(card.get("chosen_on") or "") for axis, card in cards.items()},
        heatmaps=heatmaps(machine),
        champions=frozenset(
            (axis, *(str(card[k]) for k in records.KEY_COLUMNS[1:])) for axis, card in cards.items()
        ),
    )

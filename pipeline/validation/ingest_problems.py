"""Carry the problems ``ingest`` found (``problems.parquet``) into the validation report."""

from __future__ import annotations

import pandas as pd

from pipeline.validation.problems import Problem, row_number


def problems_from_ingest(problems: pd.DataFrame) -> list[Problem]:
    """Turn the rows of ``problems.parquet`` into report problems (one each, text kept).

    Parameters
    ----------
    problems : DataFrame
        ``campaign_id, file, row, column, check, problem, action`` (:class:`schemas.ProblemsModel`).

    Returns
    -------
    list of Problem
        In table order; ``value`` is None, ``message``/``action`` are ingest's text.
    """
    out = []
    for rec in problems.to_dict("records"):
        column = rec.get("column")
        out.append(
            Problem(
                campaign=str(rec["campaign_id"]),
                file=str(rec["file"]),
                row=row_number(rec.get("row")),
                column=None if column is None or pd.isna(column) else str(column),
                check=str(rec["check"]),
                value=None,
                message=str(rec["problem"]),
                action=str(rec["action"]),
            )
        )
    return out

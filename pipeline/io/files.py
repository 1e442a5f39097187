"""Open a raw file of a campaign as text and split a CSV into cells; never raises on content.

Files are read as UTF-8 with or without a byte-order mark and with any line ending (an Excel
export: BOM and CRLF, is read like a plain file). What the contract cannot read is reported
through ``report(file, row, column, check, **fields)`` (the texts are in
:mod:`pipeline.validation.texts`): an empty file, a binary file (zip/xlsx, xls, PDF, random
bytes), text that is not UTF-8, a CSV separated by ';', rows whose number of cells differs from
the header, repeated column names, a header without data rows. Files are only read.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

Report = Callable[..., None]
"""``report(file, row, column, check, problem=None, action=None, **fields)``: record one problem
of a raw file; without ``problem``/``action`` they are worded from the check's text."""

MAGIC_NUMBERS = {
    b"PK\x03\x04": "a zip archive, e.g. an .xlsx workbook",
    b"\xd0\xcf\x11\xe0": "an old Excel .xls / OLE document",
    b"%PDF": "a PDF document",
    b"\x1f\x8b": "a gzip archive",
}
"""File signatures named in the ``binary_file`` problem."""

MAX_REPORTED_ROWS = 20
"""Row-level problems of one kind reported per file and column (the rest repeat them)."""


def read_text(path: Path, report: Report) -> str | None:
    """Return the text of a raw file, or None after reporting why it is not readable text.

    Parameters
    ----------
    path : Path
        The raw file (opened for reading only).
    report : callable
        ``report(file, row, column, check, **fields)``.

    Returns
    -------
    str or None
        The decoded text without a byte-order mark; None for an empty (``empty_file``), binary
        (``binary_file``) or non-UTF-8 (``not_utf8``) file.
    """
    data = path.read_bytes()
    if not data.strip():
        report(path.name, None, None, "empty_file", size=f"{len(data)} bytes, no text")
        return None
    found = binary_kind(data)
    if found is not None:
        report(path.name, None, None, "binary_file", found=found)
        return None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        report(path.name, None, None, "not_utf8", byte=f"0x{data[error.start]:02x}", line=line)
        return None
    if not text.strip():
        report(path.name, None, None, "empty_file", size=f"{len(data)} bytes, no text")
        return None
    return text


def binary_kind(data: bytes) -> str | None:
    """Return what a binary file looks like (None for text): known signatures, NUL bytes."""
    for magic, name in MAGIC_NUMBERS.items():
        if data.startswith(magic):
            return name
    if b"\x00" in data:
        return "NUL bytes, e.g. random or UTF-16 data"
    return None


def read_csv_cells(path: Path, report: Report) -> pd.DataFrame | None:
    """Read a raw CSV as text cells: one column per header name, one row per data row.

    Parameters
    ----------
    path : Path
        The raw CSV file.
    report : callable
        ``report(file, row, column, check, **fields)``; ``row`` is the 1-based data row.

    Returns
    -------
    DataFrame or None
        ``str`` cells, stripped of surrounding blanks (an empty cell is ``""``), column names
        stripped, index 0..n-1 in file order (blank lines skipped). A row with too few cells
        is padded with empty cells, one with too many is cut, and both are reported
        (``field_count``); of a repeated column name only the first column is kept
        (``duplicate_column``). None when the file is not readable text, is separated by ';'
        (``semicolon_separated``), cannot be split (``unreadable_csv``) or has no data row
        (``no_data_rows``).
    """
    text = read_text(path, report)
    if text is None:
        return None
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        rows = [[cell.strip() for cell in row] for row in reader if not _blank(row)]
    except csv.Error as error:
        report(path.name, None, None, "unreadable_csv", line=reader.line_num, error=error)
        return None
    if not rows:
        report(path.name, None, None, "empty_file", size=f"{len(text)} characters, no cells")
        return None
    header, body = rows[0], rows[1:]
    if any(";" in name for name in header):
        report(path.name, None, None, "semicolon_separated", header=repr(";".join(header)[:80]))
        return None
    if not body:
        report(path.name, None, None, "no_data_rows")
        return None
    names = [name or f"unnamed_{position}" for position, name in enumerate(header, start=1)]
    keep = _first_of_each_name(
        names, lambda name: report(path.name, None, name, "duplicate_column")
    )
    uneven = [i for i, row in enumerate(body) if len(row) != len(names)]
    for index in uneven[:MAX_REPORTED_ROWS]:
        report(
            path.name,
            index + 1,
            None,
            "field_count",
            n_fields=len(body[index]),
            n_header=len(names),
        )
    width = len(names)
    cells = [(row + [""] * width)[:width] for row in body]
    frame = pd.DataFrame(cells, columns=names, dtype="str")
    return frame.iloc[:, keep]


def _blank(row: list[str]) -> bool:
    """Return True for a blank line (no cell, or one cell of blanks); ``,,`` is a row."""
    return not row or (len(row) == 1 and not row[0].strip())


def _first_of_each_name(names: list[str], on_repeat: Callable[[str], Any]) -> list[int]:
    """Return the positions of the first column of each name; call ``on_repeat`` once per name."""
    seen: set[str] = set()
    repeated: set[str] = set()
    keep = []
    for position, name in enumerate(names):
        if name in seen:
            if name not in repeated:
                on_repeat(name)
            repeated.add(name)
            continue
        seen.add(name)
        keep.append(position)
    return keep

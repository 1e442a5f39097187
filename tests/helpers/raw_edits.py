"""Corrupt one thing in a raw campaign file (tests of bad input); plain text in, plain text out."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import yaml


def read_table(path: Path) -> tuple[list[str], list[list[str]]]:
    """Return the header and the data rows (cells as text) of a simple comma-separated file."""
    lines = path.read_text().splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def write_table(path: Path, header: list[str], rows: list[list[str]]) -> None:
    """Write a header and rows comma-separated, one line each."""
    path.write_text("\n".join(",".join(cells) for cells in [header, *rows]) + "\n")


def set_cell(path: Path, row: int, column: str, text: str) -> None:
    """Write ``text`` into the cell of 1-based data ``row`` and ``column``."""
    header, rows = read_table(path)
    rows[row - 1][header.index(column)] = text
    write_table(path, header, rows)


def map_column(path: Path, column: str, function: Callable[[float], float], fmt: str) -> None:
    """Replace every number of ``column`` by ``function(number)`` formatted with ``fmt``."""
    header, rows = read_table(path)
    index = header.index(column)
    for cells in rows:
        cells[index] = format(function(float(cells[index])), fmt)
    write_table(path, header, rows)


def drop_column(path: Path, column: str) -> None:
    """Delete ``column`` (header and cells)."""
    header, rows = read_table(path)
    index = header.index(column)
    write_table(
        path,
        header[:index] + header[index + 1 :],
        [cells[:index] + cells[index + 1 :] for cells in rows],
    )


def edit_rows(path: Path, function: Callable[[list[list[str]]], list[list[str]]]) -> None:
    """Replace the data rows by ``function(rows)``."""
    header, rows = read_table(path)
    write_table(path, header, function(rows))


def edit_yaml(path: Path, function: Callable[[dict], None]) -> None:
    """Load campaign.yaml, let ``function`` change the mapping in place, write it back."""
    meta = yaml.safe_load(path.read_text())
    function(meta)
    path.write_text(yaml.safe_dump(meta, sort_keys=False))


def replace_text(path: Path, old: str, new: str) -> None:
    """Replace ``old`` (which must occur) by ``new`` in a text file."""
    text = path.read_text()
    assert old in text, (old, path)
    path.write_text(text.replace(old, new))

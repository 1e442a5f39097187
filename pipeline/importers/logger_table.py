"""Read a data logger's wide table (CSV or XLSX) into contract names and units.

The table has a header row (at ``table.header_row``, optionally followed by
``table.skip_after_header`` lines of units or descriptions) and one row per sample: a time column,
the spindle speed, probe channels and temperature channels, named as the logger names them. The
mapping file (:mod:`pipeline.importers.mapping`) says which column is what. Reading checks the
whole table and raises :class:`TableError` naming the file, the 1-based data row (the header not
counted) and the column, and what to do. Rows whose cells are all empty are skipped. The table is
only opened for reading.
"""

from __future__ import annotations

import logging
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.importers.mapping import LoggerMapping
from pipeline.importers.mapping_file import TIME_UNITS

logger = logging.getLogger(__name__)

CSV_SUFFIXES = (".csv", ".txt")
XLSX_SUFFIXES = (".xlsx", ".xlsm")
MAX_LISTED = 5
"""Bad cells listed in one message."""


class TableError(ValueError):
    """A logger table that cannot be imported; the message names file, row and column."""


@dataclass(frozen=True)
class LoggerRecord:
    """The logger table in contract names and units.

    Attributes
    ----------
    source : Path
        The table file.
    start : pandas.Timestamp
        Local date-time of the first sample.
    elapsed_s : ndarray of shape (n,), s
        Time of every sample since the first one, strictly increasing.
    rpm : ndarray of shape (n,), rpm
        Spindle speed.
    temperatures : DataFrame of shape (n, n_sensors), degC
        One column per contract sensor name, NaN for a missing reading.
    displacement : DataFrame of shape (n, n_axes), um
        One column per contract axis name, NaN for a missing reading.
    data_rows : ndarray of shape (n,)
        1-based data row of every sample in the table.
    """

    source: Path
    start: pd.Timestamp
    elapsed_s: np.ndarray
    rpm: np.ndarray
    temperatures: pd.DataFrame
    displacement: pd.DataFrame
    data_rows: np.ndarray


class _Locator:
    """Words for a cell of the table: file, data row, file line or sheet row, column."""

    def __init__(self, path: Path, before_data: int, rows: np.ndarray, mapping_path: Path) -> None:
        self.path, self.before_data, self.rows = path, before_data, rows
        self.mapping_path = mapping_path
        self.line = "sheet row" if path.suffix.lower() in XLSX_SUFFIXES else "line"

    def row(self, position: int) -> str:
        data_row = int(self.rows[position])
        return f"data row {data_row} ({self.line} {self.before_data + data_row})"

    def fail(self, column: str, positions, problem: str, action: str) -> TableError:
        """Return an error about ``column`` at the given row positions (at most 5 listed)."""
        positions = list(positions)
        where = ", ".join(self.row(p) for p in positions[:MAX_LISTED])
        more = (
            f" and {len(positions) - MAX_LISTED} more rows" if len(positions) > MAX_LISTED else ""
        )
        return TableError(f"{self.path}, column '{column}', {where}{more}: {problem}; {action}")

    def require(self, column: str, values: np.ndarray, what: str, action: str) -> None:
        """Raise :meth:`fail` "the ``what`` is missing" at the rows where ``values`` is NaN."""
        missing = np.flatnonzero(np.isnan(values))
        if missing.size:
            raise self.fail(column, missing, f"the {what} is missing", action)


def read_logger_table(path: Path, mapping: LoggerMapping) -> LoggerRecord:
    """Read the table and convert it with the mapping.

    Parameters
    ----------
    path : Path
        CSV (``.csv``, ``.txt``) or XLSX (``.xlsx``, ``.xlsm``) file.
    mapping : LoggerMapping

    Returns
    -------
    LoggerRecord
        Temperatures in degC (degF converted), displacements in um (mm converted).

    Raises
    ------
    TableError
        Unreadable file, a mapped column missing, a column neither mapped nor ignored, a cell
        that is not a number (or date-time), times not strictly increasing.
    """
    text = _read_text(path, mapping)
    _check_columns(path, text, mapping)
    blank = text.apply(lambda c: c.str.strip() == "").all(axis=1).to_numpy()
    rows = np.flatnonzero(~blank) + 1
    text = text.loc[~blank].reset_index(drop=True)
    if len(text) < 2:
        raise TableError(
            f"{path} has {len(text)} data row(s) under its header; a record needs "
            "at least two samples (check table.header_row in the mapping)"
        )
    before_data = mapping.table.header_row + mapping.table.skip_after_header
    where = _Locator(path, before_data, rows, mapping.path)
    start, elapsed_s = _times(text, mapping, where)
    options = mapping.table
    rpm = _numbers(text[mapping.speed_column], where, options.decimal, options.missing_values)
    cut_by_it = "fill in the speed (rpm): the record is cut by it"
    where.require(mapping.speed_column, rpm, "spindle speed", cut_by_it)
    temperatures = pd.DataFrame(
        {
            s.sensor: _degc(
                _numbers(text[s.column], where, options.decimal, options.missing_values), s.unit
            )
            for s in mapping.sensors
        }
    )
    displacement = pd.DataFrame(
        {
            p.axis: _numbers(text[p.column], where, options.decimal, options.missing_values)
            * p.factor_um
            for p in mapping.probes
        }
    )
    logger.info(
        "read %s: %d samples, %d temperature and %d probe columns",
        path,
        len(text),
        len(mapping.sensors),
        len(mapping.probes),
    )
    return LoggerRecord(path, start, elapsed_s, rpm, temperatures, displacement, rows)


def _read_text(path: Path, mapping: LoggerMapping) -> pd.DataFrame:
    """Every cell as text (empty cells empty), headers stripped."""
    options = mapping.table
    if not path.is_file():
        raise TableError(
            f"logger table {path} does not exist; give the path of the CSV or XLSX export"
        )
    suffix = path.suffix.lower()
    header = options.header_row - 1  # 0-based line of the header
    skip = [*range(header), *range(header + 1, header + 1 + options.skip_after_header)]
    try:
        if suffix in XLSX_SUFFIXES:
            frame = pd.read_excel(
                path,
                sheet_name=options.sheet or 0,
                skiprows=skip,
                dtype=str,
                keep_default_na=False,
                engine="openpyxl",
            )
        elif suffix in CSV_SUFFIXES:
            encoding = (
                "utf-8-sig" if options.encoding.lower() in ("utf-8", "utf8") else options.encoding
            )
            frame = pd.read_csv(
                path,
                sep=options.delimiter,
                dtype=str,
                keep_default_na=False,
                encoding=encoding,
                skiprows=skip,
                skip_blank_lines=False,
            )
        else:
            raise TableError(
                f"{path}: cannot read '{suffix}' files; export the logger table as "
                "CSV (.csv) or Excel workbook (.xlsx)"
            )
    except UnicodeDecodeError as error:
        raise TableError(
            f"{path} is not {options.encoding} text ({error.reason} at byte "
            f"{error.start}); set table: encoding: in {mapping.path} to the export's "
            "encoding (e.g. cp1252)"
        ) from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as error:
        raise TableError(
            f"{path} cannot be read as a table with delimiter "
            f"'{options.delimiter}' and the header at line {options.header_row}: "
            f"{str(error).strip()}; check table: delimiter: and header_row: in "
            f"{mapping.path}"
        ) from None
    except (ValueError, KeyError, zipfile.BadZipFile, OSError) as error:
        raise TableError(
            f"{path} cannot be read as an Excel workbook: {error}; check table: "
            f"sheet: in {mapping.path}, or save the export as .xlsx "
            "again"
        ) from None
    frame.columns = [str(c).strip() for c in frame.columns]
    empty = [
        c
        for c in frame.columns
        if (c == "" or c.startswith("Unnamed: ")) and (frame[c].str.strip() == "").all()
    ]
    return frame.drop(columns=empty)


def _check_columns(path: Path, text: pd.DataFrame, mapping: LoggerMapping) -> None:
    """Check that the mapped columns are present and every other column is ignored."""
    header = list(text.columns)
    duplicated = sorted(
        {c for c in header if header.count(c) > 1}
        | {
            c
            for c in header
            if "." in c and c.rsplit(".", 1)[0] in header and c.rsplit(".", 1)[1].isdigit()
        }
    )
    if duplicated:
        raise TableError(
            f"{path}: the header repeats column name(s) {duplicated}; give every "
            "column its own header in the export"
        )
    absent = [c for c in mapping.mapped_columns() if c not in header]
    if absent:
        raise TableError(
            f"{path}: mapped column(s) {absent} are not in the header {header}; "
            f"correct the column names in {mapping.path} (headers are compared "
            "exactly, case included)"
        )
    known = set(mapping.mapped_columns()) | set(mapping.ignore_columns)
    unmapped = [c for c in header if c not in known]
    if unmapped:
        raise TableError(
            f"{path}: column(s) {unmapped} are neither mapped nor ignored in "
            f"{mapping.path}; map each under probes: or temperatures:, or list them "
            f"under ignore_columns: [{', '.join(unmapped)}]"
        )
    not_there = [c for c in mapping.ignore_columns if c not in header]
    if not_there:
        logger.warning("%s: ignore_columns %s are not in the table", mapping.path, not_there)


def _numbers(
    text: pd.Series, where: _Locator, decimal: str, missing_values: tuple[str, ...]
) -> np.ndarray:
    """Numbers of a text column; empty cells and ``missing_values`` become NaN."""
    cells = text.str.strip()
    absent = (cells == "") | cells.isin(missing_values)
    written = cells.str.replace(",", ".", regex=False) if decimal == "," else cells
    values = pd.to_numeric(written.where(~absent), errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~absent.to_numpy() & ~np.isfinite(values))
    if bad.size:
        first = cells.iloc[bad[0]]
        if decimal == "." and "," in first:
            action = (
                f"the mapping says decimal: '.', but the cell has a comma: set table: "
                f"decimal: ',' in {where.mapping_path}"
            )
        else:
            action = (
                "write a number or leave the cell empty; a logger's code for no reading "
                "can be listed under table: missing_values:"
            )
        raise where.fail(str(text.name), bad, f"'{first}' is not a number", action)
    return values


def _degc(values: np.ndarray, unit: str) -> np.ndarray:
    """Temperatures in degC from ``unit`` (degC or degF)."""
    return (values - 32.0) * 5.0 / 9.0 if unit == "degF" else values


def _times(
    text: pd.DataFrame, mapping: LoggerMapping, where: _Locator
) -> tuple[pd.Timestamp, np.ndarray]:
    """Local date-time of the first sample and seconds since it, strictly increasing."""
    spec = mapping.time
    if spec.unit == "timestamp":
        start, elapsed_s = _timestamps(text, mapping, where)
    else:
        values = _numbers(text[spec.column], where, mapping.table.decimal, ())
        where.require(spec.column, values, "time", "fill in every sample's time, or delete the row")
        seconds = values * TIME_UNITS[spec.unit]
        start = spec.start + pd.Timedelta(seconds=float(seconds[0]))
        elapsed_s = seconds - seconds[0]
    steps = np.diff(elapsed_s)
    back = np.flatnonzero(steps <= 0)
    if back.size:
        column = spec.column
        previous = text[column].iloc[back[0]].strip()
        raise where.fail(
            column,
            back + 1,
            f"the time '{text[column].iloc[back[0] + 1].strip()}' is not after the "
            f"previous row's '{previous}'",
            "sort the table by time and delete repeated rows (a clock set back, e.g. "
            "at the end of daylight saving time, also does this)",
        )
    return start, elapsed_s


def _timestamps(
    text: pd.DataFrame, mapping: LoggerMapping, where: _Locator
) -> tuple[pd.Timestamp, np.ndarray]:
    """Parse a timestamp column (joined to its date column); UTC offsets are kept consistent.

    Timestamps without an offset are taken as local time as written. Timestamps with offsets
    are converted to the offset of the first one, so that a change of offset within the record
    (daylight saving time) does not shift the time base.
    """
    spec = mapping.time
    cells = text[spec.column].str.strip()
    if spec.date_column:
        cells = text[spec.date_column].str.strip() + " " + cells
    fmt = spec.format or "ISO8601"
    try:
        parsed = pd.to_datetime(cells, format=fmt, errors="coerce")
    except ValueError:  # offsets differ between rows
        parsed = pd.to_datetime(cells, format=fmt, errors="coerce", utc=True)
    bad = np.flatnonzero(parsed.isna().to_numpy())
    if bad.size:
        wanted = f"the format '{spec.format}'" if spec.format else "ISO 8601 (2024-03-04 07:12:00)"
        raise where.fail(
            spec.column,
            bad,
            f"'{cells.iloc[bad[0]]}' is not a date-time in {wanted}",
            f"set time: format: in {mapping.path} to the logger's format (strftime "
            'codes, e.g. "%d.%m.%Y %H:%M:%S"), or fill in the missing time',
        )
    if parsed.dt.tz is not None:
        first_offset = pd.to_datetime(cells.iloc[0], format=fmt).tz
        parsed = parsed.dt.tz_convert(first_offset).dt.tz_localize(None)
    elapsed_s = (parsed - parsed.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
    return pd.Timestamp(parsed.iloc[0]), elapsed_s

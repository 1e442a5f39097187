"""Parse one Renishaw ``.rtl`` laser-interferometer export (linear axis) into runs.

What the parser reads
---------------------
A ``.rtl`` file is plain text in sections opened by a line ``NAME::``. Renishaw publishes no
specification of it; the layout below is the one shared by the open-source readers and writers
found (cited in ``docs/import-rtl.md``), and is all this parser accepts::

    HEADER::
    File type  : rtl                       <- required, must say rtl
    TARGET DATA::
    Target-count: 5                        <- required, integer >= 2
    Targets :                              <- required; the positions (mm) follow, any number
    0.000 50.000 100.000 150.000 200.000      per line, until the next "key:" line or section
    Flags: 0 0 2 0                         <- optional; kept as text, meaning unknown
    USER-TEXT::                            <- optional; "key: value" lines, e.g. Date, Axis
    Date:2015-01-12 08:30:00
    Axis:Y
    RUNS::
    Run-count:4                            <- required, integer >= 1
    DEVIATIONS::
    Run Target Data:                       <- required, then Run-count x Target-count lines
    1   1      0.8                         <- run number, target number (1-based index into
    ...                                       Targets), deviation (um)
    EOF::                                  <- optional end marker; nothing may follow it

Other sections (e.g. ``ENVIRONMENT::``, ``EQUIPMENT::``) are accepted and not interpreted.

Rules the parser applies (strict where the sources do not settle a question)
-----------------------------------------------------------------------------
- Target positions are millimetres and deviations micrometres: every source treats a linear
  axis file so, and none shows a unit field. A ``key: value`` line of HEADER, TARGET DATA or
  RUNS whose key has the word "unit(s)" must say ``mm`` or ``metric``; any other unit is
  refused (no conversion is guessed, because no source shows how such a file is written).
- The lines of a run are contiguous, runs are numbered 1..Run-count in file order, and each run
  measures every target exactly once. The order of its lines is the order of measurement.
- A run's direction follows from its target positions in measurement order: strictly increasing
  is ``+``, strictly decreasing is ``-``; anything else is an error.
- ``Date`` (section USER-TEXT) is read only on request (:meth:`RtlFile.measured_at`) and only
  in the form ``YYYY-MM-DD HH:MM[:SS]`` (or with ``T``), the one form seen in the sources.
- Text is decoded as UTF-8 (a byte-order mark is skipped), else as Latin-1; the numbers are
  ASCII either way. A decimal comma is refused.

Not confirmed by any public source (see ``docs/import-rtl.md``): that genuine Renishaw software
always writes this layout; whether a unit field exists and how inch or rotary-axis (angular)
files look -- a rotary file cannot be told from a linear one, so only linear-axis files may be
given; what the ``Flags`` fields mean; the date format of genuine files; the sign convention of
the deviation (copied unchanged).

Every problem raises :class:`RtlFormatError` (a ``ValueError``) naming the file, the line, the
section, what was expected and what to do. The file is only ever opened for reading.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime
from itertools import pairwise
from pathlib import Path

SECTION_RE = re.compile(r"^([A-Z][A-Z0-9 \-]*)::$")
KEY_VALUE_RE = re.compile(r"^([A-Za-z][A-Za-z0-9 \-]*?)\s*:\s*(.*)$")
NUMBER_RE = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
INTEGER_RE = re.compile(r"^\d+$")
DATE_RE = re.compile(r"^(\d{4}-\d{2}-\d{2})[ T](\d{2}:\d{2}(:\d{2})?)$")
REQUIRED_SECTIONS = ("HEADER", "TARGET DATA", "RUNS", "DEVIATIONS")
METRIC_UNITS = frozenset({"mm", "metric"})
UNIT_KEY_RE = re.compile(r"\bunits?\b")
FORMAT_SECTIONS = ("HEADER", "TARGET DATA", "RUNS")
END_SECTION = "EOF"


class RtlFormatError(ValueError):
    """A ``.rtl`` file does not have the layout this parser reads.

    Parameters
    ----------
    path : Path
        The file.
    line : int or None
        1-based line number in the file; None when the problem is the file as a whole.
    section : str
        Section concerned (``HEADER``, ``TARGET DATA``, ...), or ``file``.
    problem : str
        What is wrong (what was expected, what was found).
    action : str
        What the user should do.
    """

    def __init__(self, path: Path, line: int | None, section: str, problem: str, action: str):
        where = f"line {line}" if line is not None else "whole file"
        super().__init__(f"{path} ({where}, section {section}): {problem}; {action}.")
        self.path, self.line, self.section = path, line, section
        self.problem, self.action = problem, action


@dataclass(frozen=True)
class RtlRun:
    """One run of the laser: every target measured once, in one direction.

    Attributes
    ----------
    number : int
        Run number as written in the file (1-based).
    direction : str
        ``+`` (target positions increasing in measurement order) or ``-`` (decreasing).
    target_mm : tuple of float, mm
        Target positions in measurement order.
    deviation_um : tuple of float, um
        Deviation measured at each target, same order.
    line : int
        File line of the run's first deviation.
    """

    number: int
    direction: str
    target_mm: tuple[float, ...]
    deviation_um: tuple[float, ...]
    line: int


@dataclass(frozen=True)
class RtlFile:
    """The content of one ``.rtl`` file.

    Attributes
    ----------
    path : Path
        The file read.
    fields : dict
        ``{section: {key: (value, line)}}`` of the ``key: value`` lines of HEADER, TARGET DATA,
        USER-TEXT and RUNS; keys lower-cased with single spaces (``"file type"``, ``"date"``).
    targets_mm : tuple of float, mm
        The target positions of TARGET DATA, in file order.
    runs : tuple of RtlRun
        The runs in file order.
    sections : tuple of str
        Names of all sections in file order.
    """

    path: Path
    fields: dict[str, dict[str, tuple[str, int]]]
    targets_mm: tuple[float, ...]
    runs: tuple[RtlRun, ...]
    sections: tuple[str, ...]

    @property
    def axis_label(self) -> str | None:
        """The ``Axis`` text of USER-TEXT (free text), or None."""
        value = self.fields.get("USER-TEXT", {}).get("axis")
        return value[0] if value else None

    def measured_at(self) -> datetime:
        """Return the date and time of the measurement from ``Date`` in USER-TEXT.

        Returns
        -------
        datetime
            Local time as written (no time zone).

        Raises
        ------
        RtlFormatError
            When the file has no ``Date`` or it is not ``YYYY-MM-DD HH:MM[:SS]``.
        """
        value = self.fields.get("USER-TEXT", {}).get("date")
        if value is None:
            raise RtlFormatError(
                self.path,
                None,
                "USER-TEXT",
                "no 'Date:' line to take the measurement time from",
                "give the warm-up times with --warmup-min instead of --times-from-header",
            )
        text, line = value
        match = DATE_RE.match(text.strip())
        if match is None:
            raise RtlFormatError(
                self.path,
                line,
                "USER-TEXT",
                f"Date '{text}' is not in the form YYYY-MM-DD HH:MM[:SS], the only form read",
                "give the warm-up times with --warmup-min instead of --times-from-header",
            )
        try:
            return datetime.fromisoformat(f"{match.group(1)}T{match.group(2)}")
        except ValueError as error:
            raise RtlFormatError(
                self.path,
                line,
                "USER-TEXT",
                f"Date '{text}' is not a valid date ({error})",
                "correct the date or give the warm-up times with --warmup-min",
            ) from error


def read_rtl(path: Path) -> RtlFile:
    """Read one ``.rtl`` file (linear axis; targets in mm, deviations in um).

    Parameters
    ----------
    path : Path
        The ``.rtl`` file; opened for reading only.

    Returns
    -------
    RtlFile
        Header fields, target positions (mm) and runs with their directions.

    Raises
    ------
    RtlFormatError
        On any departure from the layout described in the module docstring.
    """
    try:
        raw = path.read_bytes()
    except OSError as error:
        raise RtlFormatError(
            path,
            None,
            "file",
            f"cannot be read ({error.strerror})",
            "check the path and the file permissions",
        ) from error
    sections = _split_sections(path, _decode(raw).splitlines())
    fields = {
        name: _key_values(path, name, sections[name][1], strict=name != "USER-TEXT")
        for name in ("HEADER", "TARGET DATA", "USER-TEXT", "RUNS")
        if name in sections
    }
    _check_file_type(path, fields["HEADER"], sections["HEADER"][0])
    _check_units(path, fields)
    targets = _targets(path, sections["TARGET DATA"], fields["TARGET DATA"])
    run_count = _count(path, "RUNS", fields["RUNS"], "run-count", "Run-count", sections["RUNS"][0])
    runs = _runs(path, sections["DEVIATIONS"], targets, run_count)
    return RtlFile(path, fields, targets, runs, tuple(sections))


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _split_sections(path: Path, lines: list[str]) -> dict[str, tuple[int, list[tuple[int, str]]]]:
    """Return ``{section: (header line, [(line number, stripped text), ...])}``."""
    sections: dict[str, tuple[int, list[tuple[int, str]]]] = {}
    current: list[tuple[int, str]] | None = None
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text:
            continue
        match = SECTION_RE.match(text)
        if END_SECTION in sections:
            raise RtlFormatError(
                path,
                number,
                END_SECTION,
                f"'{text}' follows the end marker EOF::",
                "remove what follows EOF:: or re-export the file",
            )
        if match:
            name = match.group(1).strip()
            if name in sections:
                raise RtlFormatError(
                    path,
                    number,
                    name,
                    f"section {name}:: appears twice",
                    "export each measurement to its own .rtl file",
                )
            current = []
            sections[name] = (number, current)
        elif current is None:
            raise RtlFormatError(
                path,
                number,
                "file",
                f"'{text}' comes before the first section",
                "check that this is a Renishaw .rtl file starting with HEADER::",
            )
        else:
            current.append((number, text))
    if not sections or next(iter(sections)) != "HEADER":
        raise RtlFormatError(
            path,
            1,
            "HEADER",
            "the file does not start with HEADER::",
            "check that this is a Renishaw .rtl text export",
        )
    missing = [name for name in REQUIRED_SECTIONS if name not in sections]
    if missing:
        raise RtlFormatError(
            path,
            None,
            missing[0],
            f"section {missing[0]}:: is missing (sections found: {', '.join(sections)})",
            "the file is incomplete or not a linear-axis .rtl export; re-export it",
        )
    return sections


def _key_values(
    path: Path, section: str, lines: list[tuple[int, str]], strict: bool
) -> dict[str, tuple[str, int]]:
    """Return the ``key: value`` lines of a section; TARGET DATA's number lines are skipped."""
    fields: dict[str, tuple[str, int]] = {}
    for number, text in lines:
        match = KEY_VALUE_RE.match(text)
        if match is None:
            if strict and section != "TARGET DATA":
                raise RtlFormatError(
                    path,
                    number,
                    section,
                    f"'{text}' is not a 'key: value' line",
                    "re-export the file; this line is not in the known layout",
                )
            continue
        key = " ".join(match.group(1).lower().split())
        if key in fields:
            raise RtlFormatError(
                path,
                number,
                section,
                f"'{match.group(1)}' appears twice",
                "keep one value per key or re-export the file",
            )
        fields[key] = (match.group(2).strip(), number)
    return fields


def _check_file_type(path: Path, header: dict[str, tuple[str, int]], line: int) -> None:
    value = header.get("file type")
    if value is None or value[0].lower() != "rtl":
        found = "no 'File type' line" if value is None else f"File type '{value[0]}'"
        raise RtlFormatError(
            path,
            line if value is None else value[1],
            "HEADER",
            f"expected 'File type : rtl', found {found}",
            "give a Renishaw .rtl text export",
        )


def _check_units(path: Path, fields: dict[str, dict[str, tuple[str, int]]]) -> None:
    for section in FORMAT_SECTIONS:
        for key, (value, line) in fields[section].items():
            if UNIT_KEY_RE.search(key) and value.lower() not in METRIC_UNITS:
                raise RtlFormatError(
                    path,
                    line,
                    section,
                    f"the file declares {key} '{value}'; only metric files (targets mm, "
                    "deviations um) are read and no conversion is guessed",
                    "export the measurement in metric units (mm / um)",
                )


def _count(
    path: Path,
    section: str,
    fields: dict[str, tuple[str, int]],
    key: str,
    label: str,
    line: int,
    minimum: int = 1,
) -> int:
    value = fields.get(key)
    if value is None:
        raise RtlFormatError(
            path, line, section, f"no '{label}:' line", "the file is incomplete; re-export it"
        )
    if not INTEGER_RE.match(value[0]) or int(value[0]) < minimum:
        raise RtlFormatError(
            path,
            value[1],
            section,
            f"{label} '{value[0]}' is not an integer >= {minimum}",
            "re-export the file",
        )
    return int(value[0])


def _number(path: Path, line: int, section: str, token: str, what: str) -> float:
    if not NUMBER_RE.match(token):
        hint = " (decimal comma?)" if "," in token else ""
        raise RtlFormatError(
            path,
            line,
            section,
            f"{what} '{token}' is not a number{hint}",
            "correct the value or re-export the file with a decimal point",
        )
    return float(token)


def _targets(
    path: Path, section: tuple[int, list[tuple[int, str]]], fields: dict[str, tuple[str, int]]
) -> tuple[float, ...]:
    """Return the target positions (mm): the tokens after ``Targets :`` up to the next key."""
    header_line, lines = section
    count = _count(path, "TARGET DATA", fields, "target-count", "Target-count", header_line, 2)
    if "targets" not in fields:
        raise RtlFormatError(
            path,
            header_line,
            "TARGET DATA",
            "no 'Targets :' line",
            "the file is incomplete; re-export it",
        )
    targets: list[float] = []
    collecting = False
    for number, text in lines:
        match = KEY_VALUE_RE.match(text)
        if match is not None:
            collecting = " ".join(match.group(1).lower().split()) == "targets"
            tokens = match.group(2).split() if collecting else []
        elif collecting:
            tokens = text.split()
        else:
            raise RtlFormatError(
                path,
                number,
                "TARGET DATA",
                f"'{text}' is not part of Targets",
                "re-export the file; this line is not in the known layout",
            )
        targets += [_number(path, number, "TARGET DATA", t, "target position") for t in tokens]
    if len(targets) != count:
        raise RtlFormatError(
            path,
            fields["targets"][1],
            "TARGET DATA",
            f"Target-count is {count} but {len(targets)} target positions follow",
            "the file is incomplete or edited; re-export it",
        )
    return tuple(targets)


def _runs(
    path: Path,
    section: tuple[int, list[tuple[int, str]]],
    targets: tuple[float, ...],
    run_count: int,
) -> tuple[RtlRun, ...]:
    """Return the runs of DEVIATIONS (run, target number, deviation um per line)."""
    header_line, lines = section
    if not lines or lines[0][1].lower().replace(" ", "") != "runtargetdata:":
        found = f"'{lines[0][1]}'" if lines else "nothing"
        raise RtlFormatError(
            path,
            lines[0][0] if lines else header_line,
            "DEVIATIONS",
            f"expected 'Run Target Data:', found {found}",
            "the file is incomplete or not in the known layout; re-export it",
        )
    rows = [
        _deviation_row(path, number, text, run_count, len(targets)) for number, text in lines[1:]
    ]
    expected = run_count * len(targets)
    if len(rows) < expected:
        last = lines[-1][0]
        raise RtlFormatError(
            path,
            last,
            "DEVIATIONS",
            f"{len(rows)} deviation lines where Run-count x Target-count = {run_count} x "
            f"{len(targets)} = {expected} are expected; the file looks truncated",
            "re-export or re-copy the complete file",
        )
    if len(rows) > expected:
        raise RtlFormatError(
            path,
            rows[expected][0],
            "DEVIATIONS",
            f"more than the {expected} deviation lines of Run-count x Target-count",
            "check Run-count and Target-count or re-export the file",
        )
    size = len(targets)
    return tuple(
        _run(path, number, rows[(number - 1) * size : number * size], targets)
        for number in range(1, run_count + 1)
    )


def _deviation_row(
    path: Path, line: int, text: str, run_count: int, target_count: int
) -> tuple[int, int, int, float]:
    """Return ``(line, run, target number, deviation um)`` of one DEVIATIONS line."""
    tokens = text.split()
    if len(tokens) != 3:
        raise RtlFormatError(
            path,
            line,
            "DEVIATIONS",
            f"'{text}' does not have the 3 fields run, target, deviation",
            "correct the line or re-export the file",
        )
    run, target, deviation = tokens
    for value, label, top in ((run, "run", run_count), (target, "target number", target_count)):
        if not INTEGER_RE.match(value) or not 1 <= int(value) <= top:
            raise RtlFormatError(
                path,
                line,
                "DEVIATIONS",
                f"{label} '{value}' is not an integer from 1 to {top}",
                "correct the line or re-export the file",
            )
    return line, int(run), int(target), _number(path, line, "DEVIATIONS", deviation, "deviation")


def _run(
    path: Path, number: int, rows: list[tuple[int, int, int, float]], targets: tuple[float, ...]
) -> RtlRun:
    """Build run ``number`` from its rows; check it is whole and monotonic."""
    for line, run, _, _ in rows:
        if run != number:
            raise RtlFormatError(
                path,
                line,
                "DEVIATIONS",
                f"run {run} where run {number} is expected (runs must be numbered 1.."
                f"Run-count in order, each with its {len(targets)} targets on consecutive lines)",
                "re-export the file; runs out of order are not read",
            )
    indices = [target for _, _, target, _ in rows]
    if sorted(indices) != list(range(1, len(targets) + 1)):
        raise RtlFormatError(
            path,
            rows[0][0],
            "DEVIATIONS",
            f"run {number} does not measure each target number 1..{len(targets)} "
            f"exactly once (target numbers: {indices})",
            "re-export the file",
        )
    positions = tuple(targets[i - 1] for i in indices)
    steps = [b - a for a, b in pairwise(positions)]
    if all(step > 0 for step in steps):
        direction = "+"
    elif all(step < 0 for step in steps):
        direction = "-"
    else:
        raise RtlFormatError(
            path,
            rows[0][0],
            "DEVIATIONS",
            f"run {number} visits the targets {list(positions)} mm in an order neither "
            "increasing nor decreasing, so its direction is unknown",
            "export runs that move one way along the axis (linear, bidirectional)",
        )
    deviations = tuple(deviation for _, _, _, deviation in rows)
    return RtlRun(number, direction, positions, deviations, rows[0][0])

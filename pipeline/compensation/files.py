"""File and in-memory sources and sinks of the compensation runtime.

- :class:`CsvTailSource`: a CSV file a logger appends to, read as it grows (``tail -f``): a
  header naming ``elapsed_s`` (s) -- or ``time`` (a timestamp) --, the sensors (degC) and
  ``rpm``, then one row per sample; ``campaign_id`` or ``run``, when present, labels runs. A
  campaign's ``temperature.csv`` (``docs/data-contract.md``) is such a file. A line still being
  written (no newline yet) waits for the next poll.
- :class:`TableSource`: a table replayed one row per cycle (the replay proof, tests).
- :class:`FileSink`: every write as a row of a CSV file (``.csv``) or a JSON line (``.jsonl``).
- :class:`MemorySink`: the writes kept in a list.
"""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from pipeline.compensation.runtime import Reading
from pipeline.errors import InputDataError

TIME_COLUMNS = ("elapsed_s", "time")
RUN_COLUMNS = ("campaign_id", "run")


def _reading(row: Mapping[str, str], where: str) -> Reading:
    if "elapsed_s" in row:
        t_s = float(row["elapsed_s"])
    else:
        t_s = pd.Timestamp(row["time"]).timestamp()
    values = {}
    for name, text in row.items():
        if name in TIME_COLUMNS or name in RUN_COLUMNS or name is None:
            continue
        try:
            values[name] = float(text) if str(text).strip() else float("nan")
        except ValueError:
            values[name] = float("nan")
    run = next((str(row[c]) for c in RUN_COLUMNS if row.get(c)), None)
    if t_s != t_s:
        raise InputDataError(f"{where}: no time in column elapsed_s/time; fix the logger file")
    return Reading(t_s, values, run)


class CsvTailSource:
    """Rows of a CSV file as a logger appends them.

    Parameters
    ----------
    path : Path
    follow : bool
        Keep waiting for new rows at the end of the file (False: stop there, a replay).
    poll_s : float, s
        How often the file is looked at while waiting.
    """

    def __init__(self, path: Path, follow: bool = True, poll_s: float = 0.5) -> None:
        self.path, self.follow, self.poll_s = Path(path), follow, poll_s
        self._offset = 0
        self._header: list[str] | None = None
        self._line = 1
        self._at_end = False

    @property
    def exhausted(self) -> bool:
        """True at the end of a file that is not followed."""
        return self._at_end and not self.follow

    def poll(self, timeout_s: float) -> list[Reading]:
        """Return the complete rows added since the last poll (waiting up to ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        while True:
            readings = self._read_new()
            if readings or not self.follow or time.monotonic() >= deadline:
                return readings
            time.sleep(min(self.poll_s, max(deadline - time.monotonic(), 0.0)))

    def _read_new(self) -> list[Reading]:
        if not self.path.is_file():
            return []
        with self.path.open("rb") as handle:
            handle.seek(self._offset)
            chunk = handle.read()
        complete = chunk[: chunk.rfind(b"\n") + 1]
        self._at_end = len(complete) == len(chunk)
        if not complete:
            return []
        self._offset += len(complete)
        lines = complete.decode("utf-8-sig").splitlines()
        if self._header is None:
            self._header = next(csv.reader([lines.pop(0)]))
            if not any(c in self._header for c in TIME_COLUMNS):
                raise InputDataError(
                    f"{self.path}, line 1: no elapsed_s or time column (found {self._header}); "
                    "the runtime needs each sample's time"
                )
        readings = []
        for row in csv.DictReader(io.StringIO("\n".join(lines)), fieldnames=self._header):
            self._line += 1
            readings.append(_reading(row, f"{self.path}, line {self._line}"))
        return readings

    def close(self) -> None:
        """Nothing to release (the file is opened per poll)."""


class TableSource:
    """A table replayed one row per cycle.

    Parameters
    ----------
    table : DataFrame
        ``elapsed_s`` (s), sensors (degC), ``rpm``; optional ``run``.
    """

    def __init__(self, table: pd.DataFrame) -> None:
        self.table = table.reset_index(drop=True)
        self.position = 0
        columns = [c for c in self.table.columns if c not in ("elapsed_s", "run")]
        self._values = self.table[columns].to_numpy(dtype=float)
        self._columns = columns
        self._times = self.table["elapsed_s"].to_numpy(dtype=float)
        self._runs = self.table["run"].astype(str).to_numpy() if "run" in self.table else None

    @property
    def exhausted(self) -> bool:
        """True once every row was replayed."""
        return self.position >= len(self.table)

    def poll(self, timeout_s: float) -> list[Reading]:
        """Return the next row (none at the end)."""
        if self.exhausted:
            return []
        k = self.position
        self.position += 1
        values = dict(zip(self._columns, self._values[k].tolist(), strict=True))
        return [
            Reading(float(self._times[k]), values, None if self._runs is None else self._runs[k])
        ]

    def close(self) -> None:
        """Nothing to release."""


class FileSink:
    """Every write appended to a CSV (``t_s``, ``axis``, ``offset_um``) or JSON-lines file."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.json = self.path.suffix.lower() in (".jsonl", ".json")
        new = not self.path.is_file() or self.path.stat().st_size == 0
        self._file = self.path.open("a", encoding="utf-8", newline="")
        if new and not self.json:
            self._file.write("t_s,wall_time,axis,offset_um\n")

    def write(self, t_s: float, offsets: Mapping[str, float]) -> None:
        """Append the offsets (um) of one cycle."""
        wall = time.time()
        if self.json:
            self._file.write(json.dumps({"t_s": t_s, "wall_time": wall, "offsets_um": offsets}))
            self._file.write("\n")
        else:
            for axis, offset in offsets.items():
                self._file.write(f"{t_s:.3f},{wall:.3f},{axis},{offset:.6f}\n")
        self._file.flush()

    def close(self) -> None:
        """Close the file."""
        self._file.close()


class MemorySink:
    """The writes kept in ``writes``: (t_s, {axis: offset_um})."""

    def __init__(self) -> None:
        self.writes: list[tuple[float, dict[str, float]]] = []

    def write(self, t_s: float, offsets: Mapping[str, float]) -> None:
        """Keep the offsets (um) of one cycle."""
        self.writes.append((t_s, dict(offsets)))

    def close(self) -> None:
        """Nothing to release."""

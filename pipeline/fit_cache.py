"""A content-addressed cache of each machine's fits: a machine's new campaign refits it alone.

DVC reruns a stage when any of its inputs changes, and a stage's inputs hold every machine. A stage
that works machine by machine (:mod:`pipeline.machines`) keys each machine's result by the SHA-256
of everything it is computed from: the machine's own rows and documents, the ``params.yaml``
sections the stage reads, and the code (every source file of the ``pipeline`` and ``schemas``
packages). A machine whose key is in the cache gets its stored result back; the others are computed
and stored. Results are stored with joblib under ``.thermal_cache/<stage>/``
(:data:`pipeline.paths.FIT_CACHE`; not a DVC output: a cache, git-ignored, safe to delete); entries
of a stage that its last run did not use are removed at the end of that run, so the cache holds one
result per machine and stage.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import shutil
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import joblib
import pandas as pd

from pipeline.paths import FIT_CACHE

LOGGER = logging.getLogger(__name__)

VERSION = "1"
PACKAGES = ("pipeline", "schemas")
Result = TypeVar("Result")


@functools.cache
def _code_digest() -> str:
    """Return the SHA-256 of every ``.py`` file of the packages, by relative path."""
    digest = hashlib.sha256(f"fit-cache-v{VERSION}\n".encode())
    here = Path(__file__).resolve().parent.parent
    for package in PACKAGES:
        for path in sorted((here / package).rglob("*.py")):
            digest.update(f"{path.relative_to(here).as_posix()}\n".encode())
            digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def part_bytes(value: Any) -> bytes:
    """Return the bytes a key is made of for one input: a table, a document or a setting.

    A DataFrame counts by its text (CSV: column names and values in row order, floats written
    exactly), not by its dtypes: one machine's rows of a table may change dtype when another
    machine's rows fill an empty column. Anything else counts by its canonical JSON (pydantic
    models by their dump).
    """
    if isinstance(value, pd.DataFrame):
        return value.to_csv(index=False).encode()
    if hasattr(value, "model_dump"):
        value = value.model_dump(mode="json")
    return json.dumps(value, sort_keys=True, default=str).encode()


def cache_key(stage: str, machine: str, parts: Iterable[tuple[str, Any]]) -> str:
    """Return the hex SHA-256 of a stage's inputs for one machine, the code's included."""
    digest = hashlib.sha256(f"{stage}\n{machine}\n{_code_digest()}\n".encode())
    for name, value in parts:
        digest.update(f"{name}\n".encode())
        digest.update(hashlib.sha256(part_bytes(value)).digest())
    return digest.hexdigest()


class StageCache:
    """One stage's cached results of this run, reused or computed machine by machine.

    Parameters
    ----------
    stage : str
        The stage's name (a folder of the cache).
    root : Path, optional
        The cache folder (default :data:`pipeline.paths.FIT_CACHE`).
    """

    def __init__(self, stage: str, root: Path | None = None) -> None:
        self.folder = (root or FIT_CACHE) / stage
        self.stage = stage
        self.used: set[str] = set()
        self.reused: list[str] = []
        self.computed: list[str] = []

    def result(
        self, machine: str, parts: Iterable[tuple[str, Any]], compute: Callable[[], Result]
    ) -> Result:
        """Return the machine's stored result for these inputs, else compute and store it.

        A stored result that cannot be read (an older library's pickle) is computed afresh.
        """
        key = cache_key(self.stage, machine, parts)
        path = self.folder / f"{key}.joblib"
        self.used.add(path.name)
        if path.is_file():
            try:
                value = joblib.load(path)
            except Exception as error:  # noqa: BLE001 - any unreadable entry is recomputed
                LOGGER.warning("%s: cached result unreadable (%s); computing it", path, error)
            else:
                self.reused.append(machine)
                LOGGER.info(
                    "%s, machine %s: its inputs, params and code are unchanged; its results "
                    "reused from %s",
                    self.stage,
                    machine,
                    path,
                )
                return value
        value = compute()
        self.folder.mkdir(parents=True, exist_ok=True)
        scratch = path.with_suffix(".tmp")
        joblib.dump(value, scratch)
        scratch.replace(path)
        self.computed.append(machine)
        return value

    def result_with_files(
        self,
        machine: str,
        parts: Iterable[tuple[str, Any]],
        compute: Callable[[], Result],
        folders: Sequence[Path],
    ) -> Result:
        """Like :meth:`result`, for a computation that also writes the machine's ``folders``.

        The files ``compute`` writes under ``folders`` are stored with its result; on reuse
        each folder is emptied and its files written back as they were (DVC removes a stage's
        outputs before it runs it).
        """
        fresh = []

        def computed() -> tuple[Result, dict[str, bytes]]:
            fresh.append(True)
            value = compute()
            files = {
                path.as_posix(): path.read_bytes()
                for folder in folders
                for path in sorted(Path(folder).rglob("*"))
                if path.is_file()
            }
            return value, files

        value, files = self.result(machine, parts, computed)
        if fresh:  # the files are there, as compute wrote them
            return value
        for folder in folders:
            if Path(folder).is_dir():
                shutil.rmtree(folder)
        for name, content in files.items():
            Path(name).parent.mkdir(parents=True, exist_ok=True)
            Path(name).write_bytes(content)
        return value

    def prune(self) -> None:
        """Remove the stage's entries this run did not use."""
        for path in self.folder.glob("*.joblib") if self.folder.is_dir() else []:
            if path.name not in self.used:
                path.unlink()

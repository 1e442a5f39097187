"""Run identity and provenance of one machine's pipeline execution.

The *run identity* decides whether the ``track`` stage logs a new MLflow parent run for a
machine or reuses the one already in the store. It is the SHA-256 of four parts, each itself a
SHA-256:

- ``code``: every file under the directories of the imported ``pipeline`` and ``schemas``
  packages (``__pycache__`` folders, ``*.pyc`` and hidden files skipped), by relative path;
- ``params``: the parsed content of ``params.yaml`` (all sections, canonical JSON, so comments
  and key order do not count);
- ``data``: every file of the machine's campaign folders in ``data/raw`` (hidden files
  skipped), by folder and relative path;
- ``scores``: the machine's part of the evaluate outputs that ``track`` logs (its rows of the
  score tables, its entries of the metrics, fitted models and selections, its champion cards).

Same code, params, raw data and scores give the same identity, so re-running ``dvc repro`` on
unchanged inputs (the stage is ``always_changed``) does not duplicate runs, and a campaign added
to one machine leaves the other machines' identities, and their runs, as they were.
"""

from __future__ import annotations

import hashlib
import json
import logging
import subprocess
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

logger = logging.getLogger(__name__)

IDENTITY_VERSION = "2"
_CHUNK = 1 << 20
_SKIPPED_DIRS = {"__pycache__"}
_SKIPPED_SUFFIXES = {".pyc", ".pyo"}


@dataclass(frozen=True)
class RunIdentity:
    """Hash of one pipeline execution.

    Attributes
    ----------
    value : str
        Hex SHA-256 (64 characters) of the parts, the tag searched in the store.
    parts : dict of str to str
        Hex SHA-256 of each part: ``code``, ``params``, ``data``, ``scores``.
    """

    value: str
    parts: dict[str, str] = field(default_factory=dict)


def hash_file(path: Path) -> str:
    """Return the hex SHA-256 of a file's bytes, read in 1 MiB chunks."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as handle:
        while chunk := handle.read(_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


def _walk(root: Path) -> Iterable[Path]:
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root).parts
        if any(part in _SKIPPED_DIRS or part.startswith(".") for part in rel):
            continue
        if path.is_file() and path.suffix not in _SKIPPED_SUFFIXES:
            yield path


def hash_tree(root: Path | str) -> str:
    """Return the hex SHA-256 of every file under ``root`` with its relative path.

    Parameters
    ----------
    root : Path or str
        A directory (a missing one hashes as the marker ``missing``) or a single file.

    Returns
    -------
    str
        Hex SHA-256 over sorted ``relative/path<TAB>sha256`` lines; renaming a file changes it.
    """
    root = Path(root)
    digest = hashlib.sha256()
    if root.is_file():
        digest.update(f"{root.name}\t{hash_file(root)}\n".encode())
    elif not root.is_dir():
        digest.update(b"missing\n")
    else:
        for path in _walk(root):
            digest.update(f"{path.relative_to(root).as_posix()}\t{hash_file(path)}\n".encode())
    return digest.hexdigest()


def hash_params(params: Mapping[str, Any]) -> str:
    """Return the hex SHA-256 of a parsed ``params.yaml`` as canonical JSON."""
    text = json.dumps(params, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def compute_identity(
    code_dirs: Iterable[Path | str],
    params: Mapping[str, Any],
    data_dirs: Iterable[Path | str],
    score_parts: Iterable[tuple[str, bytes]],
) -> RunIdentity:
    """Compute the run identity from code, params, raw data and evaluate outputs.

    Parameters
    ----------
    code_dirs : iterable of Path or str
        Source directories, e.g. those of the ``pipeline`` and ``schemas`` packages.
    params : mapping
        The whole parsed ``params.yaml``.
    data_dirs : iterable of Path or str
        The machine's campaign folders of ``data/raw``.
    score_parts : iterable of (str, bytes)
        The machine's part of each evaluate output logged by ``track``, by name.

    Returns
    -------
    RunIdentity
        The combined hash and the hash of each part.
    """
    code = hashlib.sha256()
    for directory in code_dirs:
        code.update(f"{Path(directory).name}\t{hash_tree(directory)}\n".encode())
    scores = hashlib.sha256()
    for name, content in score_parts:
        scores.update(f"{name}\t{hashlib.sha256(content).hexdigest()}\n".encode())
    data = hashlib.sha256()
    for directory in data_dirs:
        data.update(f"{Path(directory).name}\t{hash_tree(directory)}\n".encode())
    parts = {
        "code": code.hexdigest(),
        "params": hash_params(params),
        "data": data.hexdigest(),
        "scores": scores.hexdigest(),
    }
    combined = hashlib.sha256(f"identity-v{IDENTITY_VERSION}\n".encode())
    for name in sorted(parts):
        combined.update(f"{name}\t{parts[name]}\n".encode())
    return RunIdentity(value=combined.hexdigest(), parts=parts)


def git_commit(cwd: Path | str = ".") -> str:
    """Return ``git rev-parse HEAD`` in ``cwd``, or ``"unknown"`` without git or a repository."""
    try:
        result = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
    except (OSError, subprocess.SubprocessError) as error:
        logger.info("git commit unknown: %s", error)
        return "unknown"
    commit = result.stdout.strip()
    if result.returncode != 0 or not commit:
        logger.info("git commit unknown: %s", result.stderr.strip() or "git rev-parse failed")
        return "unknown"
    return commit


def _entry_hash(entry: Mapping[str, Any]) -> str | None:
    for key in ("md5", "checksum", "etag"):
        if entry.get(key):
            return str(entry[key])
    return None


def dvc_lock_hashes(lock: Mapping[str, Any] | None, raw_path: str = "data/raw") -> dict[str, str]:
    """Extract data hashes from a parsed ``dvc.lock``.

    Parameters
    ----------
    lock : mapping or None
        The parsed ``dvc.lock`` (``{"schema": "2.0", "stages": {name: {"deps": [...],
        "outs": [...]}}}``); ``None`` or an unexpected layout gives fewer or no hashes.
    raw_path : str
        The dependency whose hash is the raw-data hash.

    Returns
    -------
    dict of str to str
        ``{"data/raw": md5}`` (from the first stage that depends on it) and ``{"<stage>:<out
        path>": md5}`` for every out of every stage, as found.
    """
    hashes: dict[str, str] = {}
    stages = (lock or {}).get("stages") if isinstance(lock, Mapping) else None
    if not isinstance(stages, Mapping):
        return hashes
    for stage, body in stages.items():
        if not isinstance(body, Mapping):
            continue
        for dep in body.get("deps") or []:
            if isinstance(dep, Mapping) and str(dep.get("path", "")).rstrip("/") == raw_path:
                value = _entry_hash(dep)
                if value and raw_path not in hashes:
                    hashes[raw_path] = value
        for out in body.get("outs") or []:
            if isinstance(out, Mapping) and out.get("path") and _entry_hash(out):
                hashes[f"{stage}:{out['path']}"] = _entry_hash(out)
    return hashes


def read_dvc_lock(path: Path | str) -> dict[str, Any] | None:
    """Parse ``dvc.lock``; ``None`` (logged) when it is missing or unreadable."""
    path = Path(path)
    if not path.is_file():
        logger.info("%s not found: no DVC data hashes in the run tags", path)
        return None
    try:
        with path.open(encoding="utf-8") as handle:
            loaded = yaml.safe_load(handle)
    except (OSError, yaml.YAMLError) as error:
        logger.warning("%s unreadable (%s): no DVC data hashes in the run tags", path, error)
        return None
    return loaded if isinstance(loaded, dict) else None


def synthetic_flag(raw_dir: Path | str) -> str:
    """Say whether the campaigns under ``raw_dir`` are synthetic.

    Parameters
    ----------
    raw_dir : Path or str
        ``data/raw``; each ``<campaign>/campaign.yaml`` is read for its ``synthetic`` key
        (absent means ``false``); unreadable files are skipped.

    Returns
    -------
    str
        ``"true"`` (all synthetic), ``"false"`` (none), ``"mixed"``, or ``"unknown"`` when no
        ``campaign.yaml`` could be read.
    """
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    flags = set()
    for path in sorted(Path(raw_dir).glob("*/campaign.yaml")):
        try:
            with path.open(encoding="utf-8") as handle:
                meta = yaml.load(handle, Loader=loader)  # noqa: S506 - a safe loader
        except (OSError, yaml.YAMLError, UnicodeDecodeError):
            continue
        if isinstance(meta, dict):
            flags.add(meta.get("synthetic") is True)
    if not flags:
        return "unknown"
    if len(flags) == 2:
        return "mixed"
    return "true" if flags.pop() else "false"

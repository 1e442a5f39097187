"""A throw-away copy of the repository for tests and benchmarks that run the pipeline in it."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


def copy_repository(root: Path, destination: Path) -> Path:
    """Copy the tracked and the untracked, not ignored files of ``root`` into a new git repo."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=root,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split("\0")
    for name in filter(None, listed):
        source = root / name
        if source.is_file():
            target = destination / name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)
    for command in (
        ["git", "init", "-q"],
        ["git", "add", "-A"],
        [
            "git",
            "-c",
            "user.name=bench",
            "-c",
            "user.email=bench@localhost",
            "commit",
            "-qm",
            "bench copy",
        ],
    ):
        subprocess.run(command, cwd=destination, check=True)
    return destination

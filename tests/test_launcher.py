"""bin/thermal, the command of every dvc.yaml stage, finds the pipeline whatever is on PATH."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SYSTEM_PATH = "/usr/bin:/bin"


def _fake(path: Path, says: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'#!/bin/sh\necho "{says} $*"\n')
    path.chmod(0o755)


def _repository(tmp_path: Path) -> Path:
    repo = tmp_path / "repo"
    (repo / "bin").mkdir(parents=True)
    shutil.copy2(ROOT / "bin" / "thermal", repo / "bin" / "thermal")
    return repo


def _run(launcher: Path, path: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(launcher), "ingest", "--x"],
        env={"PATH": path},
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=20,
    )


def test_the_repositorys_venv_wins_over_path(tmp_path):
    repo = _repository(tmp_path)
    _fake(repo / ".venv" / "bin" / "thermal", "venv")
    _fake(tmp_path / "other" / "thermal", "other")
    done = _run(repo / "bin" / "thermal", f"{tmp_path / 'other'}:{SYSTEM_PATH}", tmp_path)
    assert done.stdout == "venv ingest --x\n"


def test_without_a_venv_a_thermal_on_path_runs_but_never_the_launcher_itself(tmp_path):
    repo = _repository(tmp_path)
    _fake(tmp_path / "other" / "thermal", "other")
    path = f"{repo / 'bin'}:{tmp_path / 'other'}:{SYSTEM_PATH}"
    assert _run(repo / "bin" / "thermal", path, tmp_path).stdout == "other ingest --x\n"


def test_nothing_installed_is_a_message_not_a_loop(tmp_path):
    repo = _repository(tmp_path)
    done = _run(repo / "bin" / "thermal", f"{repo / 'bin'}:{SYSTEM_PATH}", tmp_path)
    assert done.returncode == 127
    assert f"In {repo} run 'make install'" in done.stderr


def test_a_symlinked_launcher_finds_its_repository(tmp_path):
    repo = _repository(tmp_path)
    _fake(repo / ".venv" / "bin" / "thermal", "venv")
    (tmp_path / "link").symlink_to(repo / "bin" / "thermal")
    assert _run(tmp_path / "link", SYSTEM_PATH, tmp_path).stdout == "venv ingest --x\n"

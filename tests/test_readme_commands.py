"""The README's commands work exactly as written, from a fresh clone, with no activated env.

The fast tests read every command the README shows (code blocks and inline code) and check
that what it calls exists: the executable in the virtual environment, the ``thermal``
sub-command, the ``make`` target, and that no command relies on a ``PATH`` the user must set.
The slow test runs the README's own-data walkthrough block line by line with ``bash``, in a
fresh copy of the repository, with ``PATH`` holding only the system's directories. Its ``.venv``
is a link to the environment running the tests, so its ``make install`` finds the environment
up to date: the installation itself is what ``.ci/run`` (``make test`` on a fresh clone) tests.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from mlflow.tracking import MlflowClient

from pipeline.cli import COMMANDS
from tests.helpers.repository import copy_repository

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
VENV_BIN = Path(sys.executable).parent
WALKTHROUGH_MARK = "<!-- walkthrough: own data -->"


def _code_lines() -> list[str]:
    """Every line of a fenced block and every inline code span of the README."""
    lines = []
    for block in re.findall(r"```(?:bash|sh)?\n(.*?)```", README, flags=re.DOTALL):
        lines += [line for line in block.splitlines() if line.strip()]
    without_blocks = re.sub(r"```.*?```", "", README, flags=re.DOTALL)
    lines += re.findall(r"`([^`\n]+)`", without_blocks)
    return lines


def _commands() -> list[list[str]]:
    """The README's shell commands (lines that call .venv/bin/..., make, git), as words."""
    commands = []
    for line in _code_lines():
        code = line.split("  #", 1)[0].strip()
        if not re.match(r"^(\S+=\S+ )*(\.venv/bin/|make |git )", code):
            continue
        commands.append(shlex.split(code.replace("[", "").replace("]", "")))
    return commands


def test_the_readme_shows_commands():
    assert len(_commands()) >= 10


def test_no_readme_command_needs_a_path_set_by_hand():
    for words in _commands():
        assert not any(w.startswith("PATH=") for w in words), words


def test_every_executable_and_thermal_command_of_the_readme_exists():
    for words in _commands():
        words = [w for w in words if not re.match(r"^[A-Z_]+=", w)]
        if words[0].startswith(".venv/bin/"):
            executable = words[0].removeprefix(".venv/bin/")
            assert (VENV_BIN / executable).is_file(), words
            if executable == "thermal" and len(words) > 1 and not words[1].startswith("-"):
                assert words[1] in COMMANDS, words


def test_every_make_target_of_the_readme_exists():
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    targets = set(re.findall(r"^([a-z][a-z-]*):", makefile, flags=re.MULTILINE))
    for words in _commands():
        if words[0] == "make":
            assert set(words[1:]) <= targets, words


def _walkthrough() -> list[str]:
    """The commands of the README's own-data walkthrough block, in order."""
    after = README.split(WALKTHROUGH_MARK, 1)[1]
    block = re.search(r"```bash\n(.*?)```", after, flags=re.DOTALL)
    assert block is not None, f"no bash block after {WALKTHROUGH_MARK}"
    return [line for line in block.group(1).splitlines() if line.strip()]


@pytest.mark.slow
def test_the_own_data_walkthrough_runs_as_written_and_ends_in_mlflow(tmp_path):
    work = copy_repository(ROOT, tmp_path / "clone")
    (work / ".venv").symlink_to(VENV_BIN.parent, target_is_directory=True)
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": str(tmp_path), "LANG": "C.UTF-8"}
    for line in _walkthrough():
        done = subprocess.run(
            ["bash", "-c", line], cwd=work, env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, f"{line}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        assert "Traceback" not in done.stderr, done.stderr

    validation = json.loads((work / "reports" / "validation.json").read_text())
    imported = sorted(p.name for p in (work / "data" / "raw").iterdir())
    assert validation["summary"]["quarantined"] == []
    assert sorted(validation["summary"]["valid"]) == imported and len(imported) >= 2
    scores = pd.read_csv(work / "reports" / "cross_season_scores.csv")
    assert set(scores["test_campaign"]) == set(imported)
    (record,) = json.loads((work / "reports" / "mlflow_run.json").read_text())["machines"].values()
    client = MlflowClient(tracking_uri=f"sqlite:///{work / 'mlflow.db'}")
    children = client.search_runs(
        [record["experiment_id"]],
        filter_string=f"tags.mlflow.parentRunId = '{record['parent_run_id']}'",
    )
    models = {run.data.params["model"] for run in children}
    assert {"none", "mlr"} <= models
    assert all(run.info.status == "FINISHED" for run in children)
    assert not os.path.exists(work / "data" / "raw" / "K01")

"""`thermal retrain`'s pull step against a real DVC folder remote, in a fresh clone.

The S3-compatible remote is exercised by ``tests/test_retrain_weeks.py`` (a real
``moto_server``); a folder on a shared drive is the other remote a shop uses.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.errors import UserError
from pipeline.retraining.retrain import pull, tracked_data

pytestmark = pytest.mark.slow

DVC = str(Path(sys.executable).parent / "dvc")
GIT = ["git", "-c", "user.name=shop", "-c", "user.email=shop@localhost"]


def _run(command: list[str], cwd: Path) -> None:
    done = subprocess.run(command, cwd=cwd, capture_output=True, text=True)
    assert done.returncode == 0, f"{command}\n{done.stdout}\n{done.stderr}"


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """A repository whose data/raw is DVC-tracked and pushed to a folder remote.

    Shared by the tests, which only clone it.
    """
    tmp_path = tmp_path_factory.mktemp("remote")
    lab = tmp_path / "lab"
    (lab / "data" / "raw" / "K01").mkdir(parents=True)
    (lab / "data" / "raw" / "K01" / "campaign.yaml").write_text("campaign_id: K01\n")
    _run(["git", "init", "-q"], lab)
    _run([DVC, "init", "-q"], lab)
    _run([DVC, "add", "-q", "data/raw"], lab)
    _run([DVC, "remote", "add", "-d", "shelf", str(tmp_path / "shelf")], lab)
    _run(["git", "add", "-A"], lab)
    _run([*GIT, "commit", "-q", "-m", "campaigns under DVC"], lab)
    _run([DVC, "push", "-q"], lab)
    return lab


def test_a_fresh_clone_pulls_the_campaigns_from_a_folder_remote(lab, tmp_path, monkeypatch):
    clone = tmp_path / "clone"
    _run(["git", "clone", "-q", str(lab), str(clone)], tmp_path)
    assert not (clone / "data" / "raw" / "K01").exists()
    monkeypatch.chdir(clone)
    assert tracked_data() == [Path("data/raw.dvc")]
    assert pull(DVC) == "pulled data/raw.dvc from the DVC remote shelf"
    assert (clone / "data" / "raw" / "K01" / "campaign.yaml").read_text() == "campaign_id: K01\n"


def test_without_a_remote_the_campaigns_are_used_as_they_are(lab, tmp_path, monkeypatch):
    clone = tmp_path / "clone"
    _run(["git", "clone", "-q", str(lab), str(clone)], tmp_path)
    _run([DVC, "remote", "remove", "shelf"], clone)
    monkeypatch.chdir(clone)
    assert pull(DVC).startswith("no DVC remote configured")


def test_an_unreachable_remote_is_an_error_that_says_what_to_check(lab, tmp_path, monkeypatch):
    clone = tmp_path / "clone"
    _run(["git", "clone", "-q", str(lab), str(clone)], tmp_path)
    _run([DVC, "remote", "modify", "shelf", "url", str(tmp_path / "gone")], clone)
    monkeypatch.chdir(clone)
    with pytest.raises(UserError, match="dvc pull failed .* check the remote's address"):
        pull(DVC)

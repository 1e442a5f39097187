"""An interrupted trials run resumes only in the setting and code it was made in."""

from __future__ import annotations

import subprocess

import pytest

from benchmarks.trial_resume import code_version, finished, save, start, trial_setting
from pipeline.settings.discrepancy import DiscrepancySettings


def _row(generator: str, hidden: str, seed: int, named: str) -> dict:
    return {"generator": generator, "hidden": hidden, "seed": seed, "named": named, "plan": ""}


def test_a_resumed_run_keeps_the_finished_trials_of_its_setting(tmp_path):
    setting = trial_setting(DiscrepancySettings(), 8, "abc")
    assert start(tmp_path, setting, resume=True).empty  # nothing to resume yet
    rows = [_row("twin", "none", 1, "none"), _row("independent", "motor_heat", 1, "motor_heat")]
    save(tmp_path, start(tmp_path, setting, resume=False), rows)

    kept = start(tmp_path, setting, resume=True)
    assert finished(kept) == {("twin", "none", 1), ("independent", "motor_heat", 1)}
    trials = save(tmp_path, kept, [_row("twin", "none", 2, "none")])
    assert list(trials["seed"]) == [1, 1, 2]
    assert list(trials["named"]) == ["none", "motor_heat", "none"]

    assert start(tmp_path, setting, resume=False).empty  # a fresh run starts again


@pytest.mark.parametrize(
    ("change", "word"),
    [
        ({"code": "def"}, "code"),
        ({"campaigns": 4}, "campaigns"),
        ({"discrepancy": DiscrepancySettings(n_folds=2).model_dump(mode="json")}, "discrepancy"),
    ],
)
def test_a_run_of_another_setting_is_not_resumed(tmp_path, change, word):
    setting = trial_setting(DiscrepancySettings(), 8, "abc")
    save(tmp_path, start(tmp_path, setting, resume=False), [_row("twin", "none", 1, "none")])
    with pytest.raises(ValueError, match=f"another {word}.*without --resume"):
        start(tmp_path, {**setting, **change}, resume=True)


def test_the_code_version_changes_with_the_code_not_the_docs(tmp_path):
    assert code_version(tmp_path) == "unknown"
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(tmp_path)]

    def commit(path: str, text: str) -> str:
        (tmp_path / path).parent.mkdir(exist_ok=True)
        (tmp_path / path).write_text(text)
        subprocess.run([*git, "add", "."], check=True)
        subprocess.run([*git, "commit", "-q", "-m", path], check=True)
        return code_version(tmp_path)

    subprocess.run([*git, "init", "-q"], check=True)
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "machine.py").write_text("HEAT = 1\n")
    (tmp_path / "params.yaml").write_text("n_folds: 4\n")
    first = commit("pipeline/rule.py", "LIMIT = 1\n")
    assert first != "unknown" and not first.endswith("-dirty")
    assert commit("docs/notes.md", "a\n") == first  # the trials' outcome does not change
    (tmp_path / "pipeline" / "rule.py").write_text("LIMIT = 2\n")
    assert code_version(tmp_path) == f"{first}-dirty"
    assert commit("pipeline/rule.py", "LIMIT = 2\n") not in (first, f"{first}-dirty")
    assert commit("params.yaml", "n_folds: 2\n") != commit("params.yaml", "n_folds: 3\n")

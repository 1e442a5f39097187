"""Resume an interrupted trials run: keep the trials it finished in the same setting and code.

The full hidden-effect trials (:mod:`benchmarks.discrepancy_trials`) take hours. Each finished
trial is written to ``trials.csv`` as it ends; this module records the setting the run was made
in (campaigns per trial, the ``discrepancy`` params section, the code's version) in
``setting.json`` beside it, and on ``--resume`` returns the finished trials only when the
setting is the same, so rates never mix trials of different rules or campaigns.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pandas as pd

from pipeline.settings.discrepancy import DiscrepancySettings

REPO_ROOT = Path(__file__).resolve().parents[1]
SETTING_FILE = "setting.json"
TRIALS_FILE = "trials.csv"
TRIAL_KEY = ("generator", "hidden", "seed")
CODE_PATHS = ("pipeline", "benchmarks", "params.yaml")


def code_version(root: Path = REPO_ROOT) -> str:
    """Return the version of the code the trials' outcome depends on.

    Parameters
    ----------
    root : Path
        The repository.

    Returns
    -------
    str
        The git object ids of ``pipeline/``, ``benchmarks/`` and ``params.yaml`` at ``HEAD``
        (so a commit that changes only the docs keeps the version), with ``-dirty`` appended when
        they have uncommitted changes; ``unknown`` outside a git checkout.
    """
    try:
        trees = _git(root, "rev-parse", *(f"HEAD:{path}" for path in CODE_PATHS))
        changes = _git(root, "status", "--porcelain", "--", *CODE_PATHS)
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    version = "-".join(tree[:12] for tree in trees.split())
    return f"{version}-dirty" if changes else version


def _git(root: Path, *args: str) -> str:
    """Return the stripped output of a git command in ``root``."""
    done = subprocess.run(
        ["git", *args], cwd=root, capture_output=True, text=True, check=True, timeout=60
    )
    return done.stdout.strip()


def trial_setting(section: DiscrepancySettings, n_campaigns: int, code: str) -> dict[str, Any]:
    """Return what a trial's outcome depends on besides its case, seed and generator.

    Parameters
    ----------
    section : DiscrepancySettings
        The ``discrepancy`` params section the trials run with (folds included).
    n_campaigns : int
        Campaigns per trial.
    code : str
        :func:`code_version`.
    """
    return {"campaigns": n_campaigns, "code": code, "discrepancy": section.model_dump(mode="json")}


def start(out: Path, setting: dict[str, Any], resume: bool) -> pd.DataFrame:
    """Prepare ``out`` for a trials run; return the finished trials to keep (none unless resuming).

    Parameters
    ----------
    out : Path
        The run's folder (``trials.csv``, ``rates.md``, ``setting.json``).
    setting : dict
        :func:`trial_setting` of this run.
    resume : bool
        Keep the trials already in ``out/trials.csv``.

    Returns
    -------
    pandas.DataFrame
        The kept rows of ``trials.csv`` (empty without ``resume`` or without a previous run).

    Raises
    ------
    ValueError
        On ``resume`` when ``out`` holds trials of another setting, naming what differs.
    """
    out.mkdir(parents=True, exist_ok=True)
    trials_path, setting_path = out / TRIALS_FILE, out / SETTING_FILE
    if resume and trials_path.exists():
        before = {}
        if setting_path.exists():
            before = json.loads(setting_path.read_text(encoding="utf-8"))
        differs = sorted(k for k in setting if before.get(k) != setting[k])
        if differs:
            was = [f"{k} was {before.get(k)!r}" for k in differs if k != "discrepancy"]
            raise ValueError(
                f"{trials_path} holds trials run with another {' and '.join(differs)}"
                f"{' (' + ', '.join(was) + ')' if was else ''}; their rates would mix settings. "
                f"Run without --resume to start again, or choose another --out."
            )
        kept = pd.read_csv(trials_path)
    else:
        kept = pd.DataFrame(columns=list(TRIAL_KEY))
    setting_path.write_text(json.dumps(setting, indent=2, sort_keys=True), encoding="utf-8")
    return kept


def finished(kept: pd.DataFrame) -> set[tuple[str, str, int]]:
    """Return the ``(generator, hidden, seed)`` of the kept trials."""
    return {(str(g), str(h), int(s)) for g, h, s in kept[list(TRIAL_KEY)].itertuples(index=False)}


def save(out: Path, kept: pd.DataFrame, rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Write the kept and the new trials to ``out/trials.csv``; return them as read back.

    Reading back gives the same types whether a trial ran now or in an interrupted run.
    """
    new = pd.DataFrame(rows)
    trials = new if kept.empty else pd.concat([kept, new], ignore_index=True)
    trials.to_csv(out / TRIALS_FILE, index=False)
    return pd.read_csv(out / TRIALS_FILE)

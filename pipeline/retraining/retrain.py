"""``thermal retrain``: pull the campaigns, reproduce the pipeline, report the promotion gate.

The one command a scheduled job runs, and a person can run:

1. **pull**: when the repository has a DVC remote and DVC-tracked data (``*.dvc`` files, e.g.
   ``data/raw.dvc`` after ``dvc add data/raw``), ``dvc pull <those files>`` brings the campaigns
   pushed since
   (``--no-pull`` skips it; without a remote there is nothing to pull and the campaigns in
   ``data/raw`` are used as they are);
2. **reproduce**: ``dvc repro``; its ``track`` stage registers each axis' new champion (the
   challenger) and runs the promotion gate (:mod:`pipeline.tracking.promotion`);
3. **report**: the gate's decision per axis (current champion against the challenger on the
   campaigns the current one was not trained on, decision, why) as Markdown on stdout, in
   ``--report`` and appended to ``$GITHUB_STEP_SUMMARY`` when set, and as JSON in ``--json``.

The exit code is 0 whether the alias moved or was kept; 1 on an error: pull or ``dvc repro``
failed, or the gate could not score an axis.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

from pipeline.errors import UserError
from pipeline.paths import PROMOTION_DECISION, PROMOTION_REPORT

LOGGER = logging.getLogger(__name__)

DEFAULT_REPORT = Path("reports/retrain.md")
DEFAULT_JSON = Path("reports/retrain.json")
SUMMARY_ENV = "GITHUB_STEP_SUMMARY"


def dvc_command() -> str:
    """Return the ``dvc`` beside this Python (the repository's .venv), else the one on PATH."""
    beside = Path(sys.executable).parent / "dvc"
    if beside.is_file():
        return str(beside)
    found = shutil.which("dvc")
    if found is None:
        raise UserError("dvc not found: run 'make install' (creates .venv with dvc)")
    return found


def remotes(dvc: str) -> list[str]:
    """Return the DVC remotes configured for this repository (names)."""
    listed = subprocess.run([dvc, "remote", "list"], capture_output=True, text=True, check=False)
    if listed.returncode != 0:
        raise UserError(f"dvc remote list failed: {listed.stderr.strip()}")
    return [line.split()[0] for line in listed.stdout.splitlines() if line.strip()]


def tracked_data(root: Path = Path(".")) -> list[Path]:
    """Return the ``.dvc`` files of data added with ``dvc add`` (outside ``.dvc/``)."""
    return sorted(p for p in root.rglob("*.dvc") if ".dvc" not in p.parent.parts and p.is_file())


def pull(dvc: str) -> str:
    """``dvc pull`` when there is a remote and DVC-tracked data; return what was done, in words.

    Raises
    ------
    UserError
        If ``dvc pull`` fails (the remote unreachable, credentials missing...).
    """
    configured = remotes(dvc)
    tracked = tracked_data()
    if not configured:
        return "no DVC remote configured: the campaigns in data/raw are used as they are"
    if not tracked:
        return (
            f"DVC remote {configured[0]} configured but no data is DVC-tracked (dvc add "
            "data/raw): nothing to pull"
        )
    names = [p.as_posix() for p in tracked]
    LOGGER.info("dvc pull %s", " ".join(names))
    # Only the added data: the stage outputs of dvc.lock are rebuilt by dvc repro, and a
    # remote that never received them would fail a plain `dvc pull`.
    done = subprocess.run([dvc, "pull", *names], check=False)
    if done.returncode != 0:
        raise UserError(
            f"dvc pull failed (exit {done.returncode}): check the remote's address and "
            "credentials (dvc remote list; AWS_ACCESS_KEY_ID/AWS_SECRET_ACCESS_KEY for S3)"
        )
    return f"pulled {', '.join(names)} from the DVC remote {configured[0]}"


def reproduce(dvc: str) -> None:
    """Run ``dvc repro``; raise :class:`UserError` when it fails."""
    done = subprocess.run([dvc, "repro"], check=False)
    if done.returncode != 0:
        raise UserError(f"dvc repro failed (exit {done.returncode}); its output above says why")


def report(pulled: str, report_path: Path, json_path: Path) -> tuple[str, dict]:
    """Read the gate's outputs of the last ``track``; write the retrain report and JSON."""
    if not PROMOTION_DECISION.is_file():
        raise UserError(
            f"{PROMOTION_DECISION} not found: the track stage did not run the promotion gate"
        )
    decision = json.loads(PROMOTION_DECISION.read_text(encoding="utf-8"))
    decision["pull"] = pulled
    text = PROMOTION_REPORT.read_text(encoding="utf-8")
    text = text.replace("# Promotion gate\n", f"# Promotion gate\n\nData: {pulled}.\n", 1)
    for path, content in ((report_path, text), (json_path, json.dumps(decision, indent=2))):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(content + "\n", encoding="utf-8")
    summary = os.environ.get(SUMMARY_ENV)
    if summary:
        with open(summary, "a", encoding="utf-8") as handle:
            handle.write(text + "\n")
    return text, decision


def main(argv: list[str] | None = None) -> int:
    """Pull, reproduce, report; return 1 when an axis could not be gated."""
    parser = argparse.ArgumentParser(prog="thermal retrain", description=__doc__.splitlines()[0])
    parser.add_argument("--no-pull", action="store_true", help="use data/raw as it is")
    parser.add_argument("--report", type=Path, default=DEFAULT_REPORT, help="Markdown report")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON, help="decision as JSON")
    args = parser.parse_args(argv)
    dvc = dvc_command()
    pulled = "pull skipped (--no-pull)" if args.no_pull else pull(dvc)
    LOGGER.info("%s", pulled)
    reproduce(dvc)
    text, decision = report(pulled, args.report, args.json)
    sys.stdout.write(text + "\n")
    errors = [
        f"{axis.get('machine', '')} {axis['axis']}".strip()
        for axis in decision["axes"]
        if axis["action"] == "error"
    ]
    if errors:
        LOGGER.error("the gate could not score axis %s: see %s", ", ".join(errors), args.report)
        return 1
    return 0

"""Trained on day 1, how good on day 2? The ranking score against the RMS on later campaigns.

``python -m benchmarks.day_two_check --seed 2046 --out reports/day_two_check`` writes the
workshop twin's 46-h record (W01-W06, one continuous run, X/Y/Z probes), marks the last
``--validation`` campaigns ``split: validation`` (the later days), and runs the real ``dvc
repro`` in a copy of the repository once per protocol setting:

- ``time-ordered``: ``params.yaml`` as shipped (``protocol.rank_by: auto``, hv-block buffer,
  rolling origin);
- ``plain-loco``: ``protocol.buffer_campaigns: 0``, ``rank_by: loco`` (leave-one-campaign-out
  with the neighbouring hours in training: how the champion was ranked before).

Per axis and setting it prints the champion, the score it was ranked by, its RMS on the later
campaigns (``pooled_Mn_val_rms_um``), their ratio, no compensation on the later campaigns and
the best later-campaign RMS among the eligible candidates; ``summary.json`` holds the same.
The validation campaigns never choose: they only check. Synthetic data, for the behaviour of the
scores, not a target to tune to.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from tests.helpers.repository import copy_repository

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
SETTINGS = {
    "time-ordered": {},
    "plain-loco": {"buffer_campaigns": 0, "rank_by": "loco"},
}


def prepare(out: Path, seed: int, validation: int, name: str) -> Path:
    """Copy the repository; its data/raw: the workshop record, the last campaigns validation."""
    work = out / name
    if work.exists():
        shutil.rmtree(work)
    copy_repository(ROOT, work)
    shutil.rmtree(work / "data" / "raw")
    subprocess.run(
        [str(BIN / "thermal"), "simulate", "--preset", "workshop", "--out", "data/raw"]
        + ["--seed", str(seed)],
        cwd=work,
        check=True,
        capture_output=True,
    )
    for folder in sorted((work / "data" / "raw").iterdir())[-validation:]:
        path = folder / "campaign.yaml"
        text = re.sub(r"^split: \w+\n", "", path.read_text(), flags=re.MULTILINE)
        path.write_text(text + "split: validation\n")
    params = yaml.safe_load((work / "params.yaml").read_text())
    params["protocol"].update(SETTINGS[name])
    (work / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    return work


def summarise(work: Path) -> list[dict]:
    """Per axis: the champion, its ranking score, its RMS on the later campaigns, the best."""
    scores = pd.read_csv(work / "reports" / "model_scores.csv")
    rows = []
    for axis, group in scores.groupby("axis"):
        eligible = group[group["eligible"].astype(bool) & (group["model"] != "none")]
        champion = group[group["champion"].astype(bool)].iloc[0]
        card = json.loads((work / "data/models/champion" / axis / "champion.json").read_text())
        column = card["chosen_on"]
        none = group[group["model"] == "none"].iloc[0]
        best = eligible.sort_values("pooled_Mn_val_rms_um").iloc[0]
        rows.append(
            {
                "axis": axis,
                "champion": f"{champion['model']}/{champion['selection']}/{champion['mode']}",
                "ranked_by": column,
                "ranking_score_um": round(float(champion[column]), 3),
                "later_rms_um": round(float(champion["pooled_Mn_val_rms_um"]), 3),
                "ratio": round(float(champion[column] / champion["pooled_Mn_val_rms_um"]), 2),
                "none_later_rms_um": round(float(none["pooled_Mn_val_rms_um"]), 3),
                "best_later_rms_um": round(float(best["pooled_Mn_val_rms_um"]), 3),
                "best_later": f"{best['model']}/{best['selection']}/{best['mode']}",
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run every setting; print and save the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2046)
    parser.add_argument("--validation", type=int, default=3, help="last campaigns held back")
    parser.add_argument("--out", type=Path, default=Path("reports/day_two_check"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    env_path = f"{BIN}:/usr/local/bin:/usr/bin:/bin"
    results = {}
    for name in SETTINGS:
        work = prepare(args.out.resolve(), args.seed, args.validation, name)
        subprocess.run(
            [str(BIN / "dvc"), "repro"],
            cwd=work,
            check=True,
            capture_output=True,
            env={"PATH": env_path, "HOME": str(work), "LANG": "C.UTF-8"},
        )
        results[name] = summarise(work)
        table = pd.DataFrame(results[name])
        sys.stdout.write(f"\n{name} (seed {args.seed}):\n{table.to_string(index=False)}\n")
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

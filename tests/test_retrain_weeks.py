"""Three weekly retraining cycles against a real MLflow server and a real S3-compatible remote.

A shop's lab clone keeps its campaigns under DVC with an S3 remote (``moto_server`` on
127.0.0.1), set up and fed with the README's own lines; a second clone, the scheduled job, runs
the README's ``git pull -q && .venv/bin/thermal retrain`` against a real ``mlflow server``. The
campaigns come from the workshop twin (one record per week, another seed each week, a week
later each time, sampled every two minutes, its X and Z probes kept: two axes, one retrained and
rolled back without the other):

- week 1: a single campaign. No held-out score exists, the champion is ``none`` (do not
  compensate), and as the first champion it is promoted: version 1;
- week 2: a 4-campaign record. The challenger is a regression whose held-out forecasts leave a
  fraction of the error of no compensation: promoted (version 2, ``@previous`` = 1);
- week 3: a 3-campaign record, with the shop's candidates cut to ``none`` in ``params.yaml``:
  the challenger (no compensation) is far worse than version 2 on the new campaigns, so the
  alias stays, version 3 is ``@challenger`` and the report says why.

Then ``thermal rollback --axis Z`` returns ``@champion`` to version 1. Test data for the
mechanics of retraining, not a target to tune models to.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from datetime import datetime, timedelta
from pathlib import Path

import pandas as pd
import pytest
import yaml
from mlflow.tracking import MlflowClient

from pipeline.twin.workshop import WORKSHOP_MACHINE as MACHINE
from tests.helpers.mlflow_server import running_mlflow_server
from tests.helpers.repository import copy_repository
from tests.helpers.s3_server import S3_CREDENTIALS, running_s3_server

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
VENV = Path(sys.executable).parent.parent
README = (ROOT / "README.md").read_text(encoding="utf-8")
BUCKET = "thermal-campaigns"
README_REMOTE = ("s3://thermal-campaigns/shop1", "http://minio.example:9000")
AXES = ("X", "Z")
"""The probes kept of the workshop twin's X, Y and Z."""
WEEKS = {1: ("A", 1), 2: ("B", 4), 3: ("C", 3)}
"""Week -> (campaign id letter, campaigns kept of the workshop record)."""
INTERVAL_S = 120.0
"""The shop's logger samples every two minutes, slower than the models' 60-s window (each sample
is its own window): a sixth of the workshop preset's rows, the same campaigns."""
SHOP_PARAMS = {
    "candidates": {"none": "none", "mlr": "all", "ridge": "all_speed"},
    "methods": ("all", "all_speed"),
}


def readme_block(mark: str) -> list[str]:
    """The lines of the README's bash block after ``<!-- walkthrough: <mark> -->``."""
    after = README.split(f"<!-- walkthrough: {mark} -->", 1)[1]
    block = re.search(r"```bash\n(.*?)```", after, flags=re.DOTALL)
    assert block is not None, mark
    return [line for line in block.group(1).splitlines() if line.strip()]


def run(lines: list[str], cwd: Path, env: dict[str, str], endpoint: str = "") -> list[str]:
    """Run each line with bash as written (the README's remote swapped for the test's)."""
    outputs = []
    for line in lines:
        line = line.replace(README_REMOTE[0], f"s3://{BUCKET}/shop1")
        line = line.replace(README_REMOTE[1], endpoint)
        done = subprocess.run(
            ["bash", "-c", line], cwd=cwd, env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, f"{line}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
        assert "Traceback" not in done.stderr, done.stderr[-3000:]
        outputs.append(done.stdout)
    return outputs


def write_week(week: int, raw: Path, scratch: Path, env: dict[str, str]) -> list[str]:
    """Add week ``week``'s record to ``raw``: the workshop twin, renamed, a week later, no Y."""
    letter, keep = WEEKS[week]
    out = scratch / f"week{week}"
    subprocess.run(
        [str(VENV / "bin" / "thermal"), "simulate", "--preset", "workshop", "--out", str(out)]
        + ["--seed", str(week), "--interval-s", str(INTERVAL_S)],
        check=True,
        env=env,
        capture_output=True,
    )
    written = []
    for number, folder in enumerate(sorted(out.iterdir())[:keep], start=1):
        campaign = f"{letter}0{number}"
        text = (folder / "campaign.yaml").read_text()
        start = re.search(r"^start: (\S+)$", text, flags=re.MULTILINE).group(1)
        later = datetime.fromisoformat(start) + timedelta(days=7 * (week - 1))
        text = re.sub(r"^campaign_id: \S+$", f"campaign_id: {campaign}", text, flags=re.M)
        text = re.sub(r"^start: \S+$", f"start: {later.isoformat()}", text, flags=re.M)
        text = re.sub(r"^  Y: \{probe: .*\}\n", "", text, flags=re.M)
        shutil.copytree(folder, raw / campaign)
        (raw / campaign / "campaign.yaml").write_text(text)
        displacement = raw / campaign / "displacement.csv"
        pd.read_csv(displacement, dtype=str)[["elapsed_s", *AXES]].to_csv(displacement, index=False)
        written.append(campaign)
    return written


def shop_params(path: Path, candidates: dict) -> None:
    params = yaml.safe_load(path.read_text())
    params["evaluate"]["candidates"] = candidates
    methods = params["select"]["methods"]
    params["select"]["methods"] = {m: methods[m] for m in SHOP_PARAMS["methods"]}
    path.write_text(yaml.safe_dump(params, sort_keys=False))


def gate(ci: Path) -> dict:
    decision = json.loads((ci / "reports" / "retrain.json").read_text())
    return {axis["axis"]: axis for axis in decision["axes"]}


@pytest.fixture(scope="module")
def weeks(tmp_path_factory):
    """Run the three weeks; yield what each retrain decided, the clones and the store."""
    tmp = tmp_path_factory.mktemp("weeks")
    lab = copy_repository(ROOT, tmp / "lab")
    (lab / ".venv").symlink_to(VENV, target_is_directory=True)
    shutil.rmtree(lab / "data" / "raw")
    (lab / "data" / "raw").mkdir()
    shop_params(lab / "params.yaml", SHOP_PARAMS["candidates"])
    summary = tmp / "step_summary.md"
    base = {
        "PATH": "/usr/local/bin:/usr/bin:/bin",
        "HOME": str(tmp),
        "LANG": "C.UTF-8",
        **S3_CREDENTIALS,
        **{
            f"GIT_{who}_{what}": value
            for who in ("AUTHOR", "COMMITTER")
            for what, value in (("NAME", "shop"), ("EMAIL", "shop@localhost"))
        },
    }
    with running_s3_server(tmp, BUCKET) as endpoint, running_mlflow_server(tmp) as uri:
        env = {**base, "MLFLOW_TRACKING_URI": uri, "GITHUB_STEP_SUMMARY": str(summary)}
        write_week(1, lab / "data" / "raw", tmp, base)
        run(["git add data/raw params.yaml", "git commit -q -m 'week 1, shop params'"], lab, base)
        run(readme_block("data under DVC"), lab, base, endpoint)
        run([f"git clone -q {lab} {tmp / 'ci'}"], tmp, base)
        ci = tmp / "ci"
        (ci / ".venv").symlink_to(VENV, target_is_directory=True)
        decisions, stdout = {}, {}
        for week in (1, 2, 3):
            if week > 1:
                write_week(week, lab / "data" / "raw", tmp, base)
                if week == 3:
                    shop_params(lab / "params.yaml", {"none": "none"})
                    run(["git commit -q -am 'week 3: candidates cut to none'"], lab, base)
                run(readme_block("new campaigns"), lab, base)
            stdout[week] = run(readme_block("retrain"), ci, env)[-1]
            decisions[week] = gate(ci)
        rollback = run([".venv/bin/thermal rollback --axis Z"], ci, env)[-1]
        client = MlflowClient(tracking_uri=uri)
        aliases = {
            axis: {
                alias: str(
                    client.get_model_version_by_alias(
                        f"thermal-error-spindle-{MACHINE}-{axis}", alias
                    ).version
                )
                for alias in ("champion", "previous", "challenger")
            }
            for axis in AXES
        }
        yield {
            "decisions": decisions,
            "stdout": stdout,
            "rollback": rollback,
            "aliases": aliases,
            "ci": ci,
            "summary": summary.read_text(),
            "remote": endpoint,
        }


def test_week_one_pulls_from_the_s3_remote_and_promotes_the_first_champion(weeks):
    week = weeks["decisions"][1]
    assert set(week) == set(AXES)
    for axis in AXES:
        assert week[axis]["action"] == "promote" and week[axis]["challenger_version"] == "1"
        assert week[axis]["challenger_label"] == "none/none/static"  # one campaign: no score
    record = json.loads((weeks["ci"] / "reports" / "retrain.json").read_text())
    assert record["pull"].startswith("pulled data/raw.dvc")
    assert "# Promotion gate" in weeks["stdout"][1]


def test_week_two_promotes_a_challenger_that_proves_better_on_the_new_campaigns(weeks):
    week = weeks["decisions"][2]
    for axis in AXES:
        decision = week[axis]
        assert decision["action"] == "promote", decision["reason"]
        assert (decision["current_version"], decision["challenger_version"]) == ("1", "2")
        compared = {c["campaign_id"] for c in decision["campaigns"]}
        assert compared and compared <= {"B01", "B02", "B03", "B04"}
        means = decision["means_um"]
        assert means["challenger"] <= 0.95 * means["current"] and means["current"] == means["none"]


def test_week_three_keeps_the_champion_that_is_better_than_the_challenger(weeks):
    week = weeks["decisions"][3]
    for axis in AXES:
        decision = week[axis]
        assert decision["action"] == "keep", decision["reason"]
        assert (decision["current_version"], decision["challenger_version"]) == ("2", "3")
        assert decision["challenger_label"] == "none/none/static"
        assert decision["means_um"]["current"] < 0.5 * decision["means_um"]["challenger"]
        assert "not better by the margin" in decision["reason"]
        assert {c["campaign_id"] for c in decision["campaigns"]} <= {"C01", "C02", "C03"}
    report = (weeks["ci"] / "reports" / "retrain.md").read_text()
    assert f"| {MACHINE} Z | **keep** | v2 | v3 (none/none/static) |" in report
    assert report in weeks["summary"]  # the job summary got every week's report


def test_every_challenger_is_registered_and_rollback_returns_to_previous(weeks):
    assert weeks["aliases"]["X"] == {"champion": "2", "previous": "1", "challenger": "3"}
    assert weeks["aliases"]["Z"] == {"champion": "1", "previous": "2", "challenger": "3"}
    assert "@champion v2 -> v1" in weeks["rollback"]

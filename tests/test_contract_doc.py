"""docs/data-contract.md, the reader and the Pandera models describe one contract."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import yaml

from pipeline.io import contract_doc
from pipeline.io.metadata import REQUIRED_KEYS
from pipeline.io.reader import read_campaign
from pipeline.validation.texts import PROBLEM_TEXTS
from schemas import CampaignsModel, LaserModel
from schemas.contract import (
    ALWAYS,
    CAMPAIGN_KEYS,
    CONTRACT_FILES,
    DERIVED_COLUMNS,
    FILES,
    LASER_COLUMNS,
)
from schemas.vocabulary import KINDS, SENSOR_ROLES

ROOT = Path(__file__).resolve().parents[1]
DOCUMENT = ROOT / "docs" / "data-contract.md"


def test_the_document_is_what_the_code_generates():
    text = DOCUMENT.read_text(encoding="utf-8")
    assert contract_doc.render(text) == text, "run: .venv/bin/thermal contract-doc"


def test_the_command_s_default_document_is_the_repository_s():
    """``thermal contract-doc`` without ``--path`` rewrites docs/data-contract.md."""
    assert contract_doc.DOCUMENT == DOCUMENT
    assert contract_doc.main(["--check"]) == 0


def test_check_mode_fails_on_a_stale_document(tmp_path):
    stale = tmp_path / "contract.md"
    text = DOCUMENT.read_text(encoding="utf-8")
    stale.write_text(text.replace("`spindle_motor`", "`spindle_engine`", 1), encoding="utf-8")
    assert contract_doc.main(["--path", str(stale), "--check"]) == 1
    assert contract_doc.main(["--path", str(stale)]) == 0
    assert stale.read_text(encoding="utf-8") == text


def test_every_campaigns_column_comes_from_a_documented_key_or_is_derived():
    documented = {key.column for key in CAMPAIGN_KEYS} | set(DERIVED_COLUMNS)
    assert documented == set(CampaignsModel.to_schema().columns)


def test_the_laser_columns_are_the_laser_model_columns():
    model = [c for c in LaserModel.to_schema().columns if c not in ("campaign_id", "source_row")]
    assert list(LASER_COLUMNS) == model
    laser = next(f for f in FILES if f.name == "laser.csv")
    assert tuple(name for name, _ in laser.columns) == LASER_COLUMNS


def test_every_kind_requires_temperature_and_its_own_file():
    assert set(CONTRACT_FILES) == set(KINDS)
    assert CONTRACT_FILES["spindle_drift"] == ("temperature.csv", "displacement.csv")
    assert CONTRACT_FILES["axis_positioning"] == ("temperature.csv", "laser.csv")


def test_the_document_lists_every_role_and_every_check():
    text = DOCUMENT.read_text(encoding="utf-8")
    for role in SENSOR_ROLES:
        assert f"`{role}`" in text
    for check in PROBLEM_TEXTS:
        assert f"| `{check}` |" in text


def test_the_documented_example_is_a_campaign_the_reader_accepts(tmp_path):
    text = DOCUMENT.read_text(encoding="utf-8")
    example = yaml.safe_load(re.search(r"```yaml\n(.*?)```", text, re.DOTALL).group(1))
    documented = {key.name.split(".")[0] for key in CAMPAIGN_KEYS}
    assert set(example) <= documented
    example.pop("axis")  # the example shows both kinds' keys; this one is spindle_drift
    folder = tmp_path / example["campaign_id"]
    folder.mkdir()
    (folder / "campaign.yaml").write_text(yaml.safe_dump(example), encoding="utf-8")
    sensors = list(example["sensors"])
    rows = [
        f"{60 * i}," + ",".join(f"{20 + 0.1 * i + j:.2f}" for j in range(len(sensors)))
        for i in range(5)
    ]
    (folder / "temperature.csv").write_text(
        "elapsed_s," + ",".join(sensors) + "\n" + "\n".join(rows) + "\n", encoding="utf-8"
    )
    (folder / "displacement.csv").write_text(
        "elapsed_s,Z\n" + "\n".join(f"{60 * i},{i}" for i in range(5)) + "\n", encoding="utf-8"
    )
    campaign = read_campaign(folder, max_alignment_gap_s=60.0)
    assert campaign.problems == []
    for key in CAMPAIGN_KEYS:
        top = key.name.split(".")[0]
        if top in example and key.column is not None:
            assert campaign.metadata[key.column] not in (None, "", "[]", "{}"), key.name


def _reported_checks(path: Path) -> set[str]:
    """The check ids a raw-file reader passes to ``report(file, row, column, check, ...)``."""
    checks = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "report":
            check = node.args[3] if len(node.args) > 3 else None
            assert isinstance(check, ast.Constant), f"{path}:{node.lineno}: check is not literal"
            checks.add(check.value)
    return checks


def test_every_check_the_readers_report_is_documented():
    readers = ("io/reader.py", "io/files.py", "io/metadata.py")
    checks = set().union(*(_reported_checks(ROOT / "pipeline" / name) for name in readers))
    assert len(checks) >= 20
    assert checks <= set(PROBLEM_TEXTS), sorted(checks - set(PROBLEM_TEXTS))


def test_the_keys_the_reader_requires_are_the_documented_required_keys():
    documented = {k.name for k in CAMPAIGN_KEYS if k.required == ALWAYS and "." not in k.name}
    assert set(REQUIRED_KEYS) == documented

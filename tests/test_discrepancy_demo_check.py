"""The demo check: the demo plans simulated as shipped and without their unseen state."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from benchmarks.discrepancy_demo_check import VARIANTS, markdown, summarise, write_demo
from pipeline.twin.effects import DEMO_EFFECTS

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def demo_variants(tmp_path_factory):
    root = tmp_path_factory.mktemp("demo")
    ids = {v: write_demo(root / v, v) for v in VARIANTS}
    return root, ids


def test_the_shipped_variant_is_the_shipped_demo(demo_variants):
    root, ids = demo_variants
    shipped = sorted(p.name for p in (REPO / "data" / "raw").iterdir() if p.is_dir())
    spindle = [c for c in shipped if c.startswith(("K", "V"))]
    assert ids["shipped"] == spindle
    for cid in ("K01", "V06"):
        for name in ("temperature.csv", "displacement.csv"):
            written = pd.read_csv(root / "shipped" / cid / name)
            pd.testing.assert_frame_equal(written, pd.read_csv(REPO / "data" / "raw" / cid / name))


def test_without_state_only_the_unseen_state_differs(demo_variants):
    root, ids = demo_variants
    assert ids["without_state"] == ids["shipped"]
    a = pd.read_csv(root / "shipped" / "K02" / "displacement.csv")
    b = pd.read_csv(root / "without_state" / "K02" / "displacement.csv")
    assert list(a["elapsed_s"]) == list(b["elapsed_s"])
    assert (a["Z"] - b["Z"]).abs().max() > 1.0  # um: the state changes the drift


def test_speed_steps_keep_the_state_and_change_the_program(demo_variants):
    root, ids = demo_variants
    assert ids["speed_steps"] == ids["shipped"]
    shipped = pd.read_csv(root / "shipped" / "K03" / "temperature.csv")
    stepped = pd.read_csv(root / "speed_steps" / "K03" / "temperature.csv")
    assert len(stepped) == len(shipped)
    program = (root / "speed_steps" / "K03" / "campaign.yaml").read_text(encoding="utf-8")
    assert program.count("rpm:") > (root / "shipped" / "K03" / "campaign.yaml").read_text(
        encoding="utf-8"
    ).count("rpm:")


def _doc(named):
    candidates = [
        {
            "effect": "sensor_lag",
            "delta_bic": 3.0,
            "heldout_reduction": -0.01,
            "heldout_T_reduction": 0.0,
            "passes": False,
        }
    ]
    return {
        "named_effects": named,
        "rmse_um_before": 4.0,
        "rmse_um_after": 1.0,
        "rmse_T_K_before": 1.0,
        "rmse_T_K_after": 0.5,
        "validation": {"rmse_um_before": 5.0, "rmse_um_after": 2.0},
        "steps": [
            {
                "effect": e,
                "evidence": {
                    "delta_bic": -50.0,
                    "heldout_reduction": 0.3,
                    "heldout_T_reduction": 0.1,
                },
            }
            for e in named
        ],
        "candidates_by_step": [{"step": 1, "candidates": candidates}],
        "seconds": 10.0,
    }


def test_summary_says_which_demo_effects_were_named():
    r = summarise(_doc(["motor_heat", "centrifugal_growth"]))
    assert r["demo_effects_named"] == ["motor_heat"]
    assert r["named_but_not_in_demo"] == ["centrifugal_growth"]
    assert set(r["demo_effects_not_named"]) == DEMO_EFFECTS - {"motor_heat"}
    assert r["validation_rmse_um"] == [5.0, 2.0]
    unsplit = summarise({**_doc([]), "quarantined": ["K02"]})
    md = markdown({"shipped": r, "without_state": unsplit}, 2016)
    assert "Quarantined by validation in `without_state` and left out: K02" in md
    assert "| shipped | motor_heat, centrifugal_growth |" in md
    assert "| without_state | nothing |" in md and "4.00 -> 1.00" in md
    assert "`sensor_lag`: delta BIC 3, held-out Z +1 %, T +0 %\n" in md


def test_a_candidate_that_passed_but_was_held_back_says_why():
    doc = _doc(["motor_heat"])
    doc["candidates_by_step"][-1]["candidates"].append(
        {
            "effect": "nonlinear_bearing_heat",
            "delta_bic": -4487.0,
            "heldout_reduction": 0.201,
            "heldout_T_reduction": 0.186,
            "passes": True,
        }
    )
    doc["suspects"] = [{"effect": "nonlinear_bearing_heat", "reason": "its evidence lies where"}]
    md = markdown({"speed_steps": summarise(doc)}, 2016)
    assert "Candidates in the last round of `speed_steps`:" in md
    assert (
        "`nonlinear_bearing_heat`: delta BIC -4487, held-out Z -20 %, T -19 %; passes the "
        "thresholds, held back as a suspect: its evidence lies where\n" in md
    )
    assert "`sensor_lag`: delta BIC 3, held-out Z +1 %, T +0 %\n" in md
    doc["named_effects"].append("nonlinear_bearing_heat")
    md = markdown({"speed_steps": summarise(doc)}, 2016)
    assert "held-out Z -20 %, T -19 %; named\n" in md

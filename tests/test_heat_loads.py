"""External heat loads (``heat_loads:`` of campaign.yaml): ingest, checks, twin, written files.

A campaign with loads goes through the real ``ingest`` and ``validate`` stages (in-process) and
the discrepancy workflow's reader gets the loads back; every bad entry is a problem naming the
campaign, campaign.yaml and the entry, and quarantines its campaign. The generator puts a
load's power into the node of its role: checked against a hand calculation from the network,
``solve_ivp`` and the steady state, and an absent or zero load changes nothing, bit for bit.
"""

from __future__ import annotations

import json
import shutil
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from pipeline import paths
from pipeline.discrepancy.data import MeasuredCampaign
from pipeline.discrepancy.model import ROLE_NODES
from pipeline.io.tables import ingest as ingest_folder
from pipeline.stages import ingest, validate
from pipeline.thermal.loads import POWER_KEY, HeatLoad, loads_from_contract
from pipeline.thermal.program import Program, Segment
from pipeline.twin.ambient import AmbientProfile
from pipeline.twin.campaigns import SpindlePlan, simulate_spindle_campaign
from pipeline.twin.params import SpindleParams
from pipeline.twin.spindle import simulate_spindle
from pipeline.twin.writer import write_campaign
from schemas.vocabulary import STRUCTURE_ROLES
from tests.helpers.raw_builders import write_axis_campaign, write_spindle_campaign
from tests.helpers.raw_edits import edit_yaml

REPO = Path(__file__).resolve().parents[1]
BAD = "B01"
LOADS = [
    {"role": "column_rear", "from_min": 0, "to_min": 60, "power_W": 300, "what": "heater mat"},
    {"role": "column_rear", "from_min": 90, "to_min": 100, "power_W": 300},
    {"role": "bed", "from_min": 30, "power_W": -50.5, "what": "draught from the door"},
]
"""Good loads: two on one role one after the other, one open-ended draught on another role."""


def test_the_structure_roles_are_the_nodes_of_the_calibrated_twin():
    assert set(STRUCTURE_ROLES) == set(ROLE_NODES)


# ---------------------------------------------------------------------- ingest and validate


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """A folder laid out like the repository: params.yaml, data/raw with K01 and A01."""
    shutil.copy(REPO / "params.yaml", tmp_path / "params.yaml")
    raw = tmp_path / paths.RAW
    raw.mkdir(parents=True)
    write_spindle_campaign(raw, "K01", ambient_rise=1.0, seed=1)
    write_axis_campaign(raw, "A01", seed=1)
    return tmp_path


def with_loads(root: Path, campaign_id: str, loads: object) -> None:
    """Write a spindle campaign whose campaign.yaml has ``heat_loads: loads``."""
    folder = write_spindle_campaign(root / paths.RAW, campaign_id, ambient_rise=1.0, seed=2)
    edit_yaml(folder / "campaign.yaml", lambda meta: meta.__setitem__("heat_loads", loads))


def run_stages(root: Path, monkeypatch) -> dict:
    """Run ingest then validate in ``root``; return reports/validation.json."""
    monkeypatch.chdir(root)
    assert ingest.main([]) == 0
    assert validate.main([]) == 0
    return json.loads((root / paths.VALIDATION_REPORT).read_text())


def test_loads_reach_the_validated_table_and_the_discrepancy_reader(workdir, monkeypatch):
    with_loads(workdir, "K02", LOADS)
    report = run_stages(workdir, monkeypatch)
    assert report["problems"] == [] and report["summary"]["quarantined"] == []

    campaigns = pd.read_parquet(workdir / paths.VALIDATED_SPINDLE / paths.CAMPAIGNS_FILE)
    samples = pd.read_parquet(workdir / paths.VALIDATED_SPINDLE / paths.SAMPLES_FILE)
    rows = campaigns.set_index("campaign_id", drop=False)
    assert json.loads(rows.loc["K01", "heat_loads_json"]) == []
    measured = MeasuredCampaign.from_tables(rows.loc["K02"], samples)
    assert measured.heat_loads == loads_from_contract(LOADS)
    rear, bed = measured.heat_loads
    assert (rear.role, rear.what, bed.role) == ("column_rear", "heater mat", "bed")
    np.testing.assert_array_equal(rear.power_at([0.0, 3599.0, 3600.0, 5400.0]), [300, 300, 0, 300])
    assert bed.power_at(1e6) == -50.5
    assert MeasuredCampaign.from_tables(rows.loc["K01"], samples).heat_loads == ()


REAR = {"role": "column_rear", "from_min": 0, "to_min": 120, "power_W": 300}
OPEN = {"role": "column_rear", "from_min": 0, "power_W": 300}
BAD_LOADS = [
    # name, heat_loads, check, entry number, words of the message
    ("no_power", [{"role": "bed", "from_min": 0, "to_min": 60}], "bad_heat_load", 1, "no power_W"),
    (
        "nan_power",
        [{"role": "bed", "from_min": 0, "power_W": np.nan}],
        "bad_heat_load",
        1,
        "finite",
    ),
    ("no_role", [REAR, {"from_min": 130, "power_W": 100}], "bad_heat_load", 2, "no role"),
    (
        "no_start",
        [{"role": "bed", "to_min": 60, "power_W": 100}],
        "bad_heat_load",
        1,
        "no from_min",
    ),
    ("not_a_mapping", [REAR, "heater on the column"], "bad_heat_load", 2, "not a mapping"),
    ("ambient_role", [{**REAR, "role": "ambient"}], "heat_load_role", 1, "'ambient'"),
    ("nut_role", [REAR, {**REAR, "role": "nut"}], "heat_load_role", 2, "'nut'"),
    ("ends_first", [{**REAR, "from_min": 120, "to_min": 60}], "heat_load_times", 1, "to_min 60"),
    ("zero_length", [{**REAR, "to_min": 0}], "heat_load_times", 1, "never on"),
    (
        "ends_first_no_power",
        [{"role": "bed", "from_min": 9, "to_min": 1}],
        "bad_heat_load",
        1,
        "no",
    ),
    ("overlap", [REAR, {**REAR, "from_min": 100, "to_min": 200}], "heat_loads_overlap", 2, "1 and"),
    ("after_open_end", [OPEN, {**OPEN, "from_min": 180}], "heat_loads_overlap", 2, "column_rear"),
]


@pytest.mark.parametrize(("name", "loads", "check", "number", "words"), BAD_LOADS)
def test_a_bad_entry_is_reported_with_its_number_and_quarantines(
    name, loads, check, number, words, workdir, monkeypatch
):
    with_loads(workdir, BAD, loads)
    report = run_stages(workdir, monkeypatch)

    found = [p for p in report["problems"] if p["check"] == check]
    assert len(found) == 1, json.dumps(report["problems"], indent=1)
    problem = found[0]
    assert (problem["campaign"], problem["file"], problem["row"], problem["column"]) == (
        BAD,
        "campaign.yaml",
        None,
        "heat_loads",
    )
    assert f"{BAD}/campaign.yaml" in problem["message"] and words in problem["message"]
    assert f"entry {number} " in problem["message"] or f"and {number} " in problem["message"]
    assert f"{BAD}/campaign.yaml" in problem["action"]
    assert "rerun dvc repro" in problem["action"]
    assert {p["campaign"] for p in report["problems"]} == {BAD}
    assert report["summary"]["quarantined"] == [BAD]
    assert set(report["summary"]["valid"]) == {"A01", "K01"}


def test_heat_loads_of_the_wrong_type_are_reported_not_a_crash(workdir, monkeypatch):
    with_loads(workdir, BAD, {"column_rear": 300})
    report = run_stages(workdir, monkeypatch)
    (problem,) = report["problems"]
    assert (problem["check"], problem["column"]) == ("wrong_type", "heat_loads")
    assert "a list of entries" in problem["message"]
    assert report["summary"]["quarantined"] == [BAD]


def test_the_entry_number_counts_from_one_in_the_message(tmp_path):
    with_loads(tmp_path, BAD, [REAR, REAR, {**REAR, "role": "coolant"}])
    problems = ingest_folder(tmp_path / paths.RAW, 60.0)["problems"]
    messages = dict(zip(problems["check"], problems["problem"], strict=True))
    assert messages["heat_load_role"].startswith(f"heat_loads entry 3 in {BAD}/campaign.yaml")
    assert messages["heat_loads_overlap"].startswith(f"heat_loads entries 1 and 2 in {BAD}/")


# ------------------------------------------------------------------------------ generator

PARAMS = SpindleParams()
AIR = AmbientProfile(mean_degc=20.0)
HEATER = HeatLoad("column_rear", Program((Segment(0.0, 120.0, 300.0),), key=POWER_KEY), "mat")
# 7 min sampling: 120 min (the heater's switch-off) is not a sample instant
TIMES = np.concatenate([[0.0, 60.0], np.arange(420.0, 240 * 60 + 1, 420.0)])


def stopped(heat_loads=(), times=TIMES, **kwargs) -> pd.DataFrame:
    """The baseline twin, spindle stopped, constant air at 20 degC, under ``heat_loads``."""
    return simulate_spindle(PARAMS, frozenset(), 0.0, AIR, times, heat_loads=heat_loads, **kwargs)


def test_a_heater_raises_its_node_as_the_network_predicts():
    out = stopped((HEATER,)).set_index("elapsed_s")
    rise = out["node_column_rear"] - 20.0
    net = PARAMS.network
    i = net.index("column_rear")
    capacity = net.capacity_j_per_k[i]
    # hand calculation: the part alone, its neighbours held at the air (conductance to the air
    # and to column_front and bed: 8 + 15 + 10 W/K); exact at the start, a few % low at 2 h
    # because the neighbours warm and take less heat
    links = sum(g for a, b, g in net.links if "column_rear" in (a, b))
    conductance = net.convection_w_per_k[i] + links
    assert conductance == pytest.approx(33.0)
    hand = 300.0 / conductance * (1.0 - np.exp(-rise.index.to_numpy() * conductance / capacity))
    assert rise.loc[60.0] == pytest.approx(hand[1], rel=1e-4)  # ~ P t / C = 0.072 K
    assert rise.loc[60.0] == pytest.approx(300.0 * 60.0 / capacity, rel=1e-2)
    heated = (rise.index > 0) & (rise.index <= 7200.0)
    np.testing.assert_allclose(rise[heated], hand[heated], rtol=0.04)
    assert rise.loc[7140.0] > 5.0  # ~5.7 K after 2 h
    assert rise.idxmax() == 7140.0  # the last sample before the heater is switched off
    others = out[[c for c in out if c.startswith("node_") and c != "node_column_rear"]] - 20.0
    assert others.to_numpy().max() < rise.max() / 4  # the neighbours warm far less


def test_a_heater_matches_solve_ivp_and_switches_off_between_samples():
    exact = stopped((HEATER,))
    radau = stopped((HEATER,), method="Radau")
    nodes = [c for c in exact if c.startswith("node_")]
    np.testing.assert_allclose(exact[nodes], radau[nodes], atol=2e-3)
    on_the_switch = stopped((HEATER,), times=np.union1d(TIMES, [7200.0])).set_index("elapsed_s")
    np.testing.assert_allclose(
        exact.set_index("elapsed_s")[nodes], on_the_switch.loc[TIMES, nodes], rtol=0, atol=1e-9
    )


def test_a_steady_load_reaches_the_steady_state_of_the_network():
    always = HeatLoad("column_rear", Program.constant(300.0, key=POWER_KEY))
    out = stopped((always,), times=np.array([0.0, 3.0e7]))
    q = np.zeros(len(PARAMS.network.nodes))
    q[PARAMS.network.index("column_rear")] = 300.0
    expected = PARAMS.network.steady_state(q, 20.0)
    nodes = [f"node_{n}" for n in PARAMS.network.nodes]
    np.testing.assert_allclose(out.loc[1, nodes].to_numpy(float), expected, rtol=0, atol=1e-6)
    assert PARAMS.network.convection @ (expected - 20.0) == pytest.approx(300.0)


@pytest.mark.parametrize("effects", [frozenset(), frozenset({"ambient_variation", "sensor_lag"})])
def test_no_load_or_a_zero_load_leaves_the_result_unchanged_bit_for_bit(effects):
    daily = AmbientProfile(mean_degc=20.0, daily_amplitude_k=3.0, start_hour=8.5)
    program = [{"from_min": 0, "to_min": 120, "rpm": 6000}, {"from_min": 120, "rpm": 0}]
    zero = HeatLoad("column_rear", Program((Segment(30.0, 45.0, 0.0),), key=POWER_KEY))
    runs = [
        simulate_spindle(PARAMS, effects, program, daily, TIMES, **kwargs)
        for kwargs in ({}, {"heat_loads": ()}, {"heat_loads": (zero,)})
    ]
    for other in runs[1:]:
        pd.testing.assert_frame_equal(runs[0], other, check_exact=True)


def test_a_load_goes_into_the_node_its_role_s_sensors_read():
    screw = HeatLoad("ball_screw", Program.constant(20.0, key=POWER_KEY))
    out = stopped((screw,)).iloc[-1]
    nodes = {c: out[c] - 20.0 for c in out.index if c.startswith("node_")}
    assert max(nodes, key=nodes.get) == "node_z_screw"  # T8, role ball_screw, reads z_screw


def test_a_load_accepts_the_contract_entries():
    entries = [{"role": "column_rear", "from_min": 0, "to_min": 120, "power_W": 300}]
    pd.testing.assert_frame_equal(stopped(entries), stopped((HEATER,)), check_exact=True)


def test_a_load_on_a_role_without_a_node_is_a_clear_error():
    nut = HeatLoad("nut", Program.constant(10.0, key=POWER_KEY))
    with pytest.raises(ValueError, match=r"role 'nut': no sensor reads a node.*column_rear"):
        stopped((nut,))


# --------------------------------------------------------------------------- written files


def test_the_written_campaign_yaml_round_trips_the_loads(tmp_path):
    loads = (
        HEATER,
        HeatLoad("bed", Program((Segment(30.0, None, -50.5),), key=POWER_KEY), 'door "open"'),
    )
    start = datetime(2024, 3, 5, 8, 0)
    plans = [
        SpindlePlan("H01", start, rpm=0.0, run_min=120.0, cooldown_min=60.0, heat_loads=loads),
        SpindlePlan("H02", start, rpm=4000.0, run_min=120.0, cooldown_min=60.0),
    ]
    for plan in plans:
        campaign = simulate_spindle_campaign(plan, seed=3, effects=frozenset())
        assert campaign.heat_loads == plan.heat_loads
        write_campaign(campaign, tmp_path)
    meta = yaml.safe_load((tmp_path / "H01" / "campaign.yaml").read_text())
    assert loads_from_contract(meta["heat_loads"]) == loads
    assert "heat_loads" not in yaml.safe_load((tmp_path / "H02" / "campaign.yaml").read_text())

    tables = ingest_folder(tmp_path, 60.0)
    assert tables["problems"].empty
    row = tables["campaigns"].set_index("campaign_id", drop=False).loc["H01"]
    assert MeasuredCampaign.from_tables(row, tables["samples"]).heat_loads == loads

"""Machines as partitions: names, one machine's rows, the machine a command acts on, the cache."""

from __future__ import annotations

import pandas as pd
import pytest

from pipeline.errors import MissingInputError
from pipeline.fit_cache import StageCache, cache_key
from pipeline.machines import (
    UNNAMED,
    machine_key,
    machine_rows,
    one_machine,
    registered_name,
    resolved_names,
)
from pipeline.separation.features import separated_by_machine


def _campaigns(*machines):
    return pd.DataFrame(
        {"campaign_id": [f"C{i}" for i in range(len(machines))], "machine": list(machines)}
    )


def test_a_campaign_without_machine_is_of_the_one_machine_the_others_name():
    names = resolved_names(_campaigns(" vmc-450 ", None, "", "vmc-450"))
    assert list(names) == ["vmc-450"] * 4


def test_a_folder_naming_no_machine_is_one_unnamed_machine():
    assert list(resolved_names(_campaigns(None, ""))) == [UNNAMED, UNNAMED]


def test_with_two_machines_a_campaign_without_one_has_no_machine():
    names = resolved_names(_campaigns("vmc-450", "FL_THERMAL", None))
    assert list(names) == ["vmc-450", "FL_THERMAL", ""]


@pytest.mark.parametrize(
    ("name", "key"),
    [("vmc-450-twin", "vmc-450-twin"), ("DMU 50 #2", "DMU-50-2"), ("FL_THERMAL", "FL_THERMAL")],
)
def test_a_machine_is_written_safely_in_folder_and_model_names(name, key):
    assert machine_key(name) == key
    assert registered_name("thermal-error-spindle", name, "Z") == f"thermal-error-spindle-{key}-Z"


def test_one_machine_rows_leave_out_the_sensors_only_other_machines_fill():
    table = pd.DataFrame(
        {
            "machine": ["a", "a", "b"],
            "campaign_id": ["A1", "A1", "B1"],
            "campaign_start": [None, None, None],  # a fixed column stays, empty or not
            "T1": [20.0, 21.0, None],
            "S7": [None, None, 30.0],
        }
    )
    rows = machine_rows(table, "a", fixed=["machine", "campaign_id", "campaign_start"])
    assert list(rows.columns) == ["machine", "campaign_id", "campaign_start", "T1"]
    assert list(rows["T1"]) == [20.0, 21.0]


def test_a_separated_table_is_split_by_machine_with_each_machines_inputs():
    table = pd.DataFrame(
        {
            "machine": ["a", "b"],
            "axis": ["Z", "Z"],
            "thermal_error_um": [1.0, 2.0],
            "T1": [20.0, None],
            "rise_T1": [0.0, None],
            "T9": [None, 25.0],
            "rise_T9": [None, 0.5],
        }
    )
    parts = dict(separated_by_machine(table))
    assert list(parts) == ["a", "b"]
    assert list(parts["a"].columns) == ["machine", "axis", "thermal_error_um", "T1", "rise_T1"]
    assert list(parts["b"].columns) == ["machine", "axis", "thermal_error_um", "T9", "rise_T9"]


def test_the_machine_a_command_acts_on():
    assert one_machine(None, ["vmc-450"], "the bundles") == "vmc-450"
    assert one_machine("DMU 50", ["DMU-50", "vmc-450"], "the bundles") == "DMU-50"
    with pytest.raises(MissingInputError, match=r"2 machines \(DMU-50, vmc-450\).*--machine"):
        one_machine(None, ["DMU-50", "vmc-450"], "the bundles")
    with pytest.raises(MissingInputError, match="--machine lathe: no such machine"):
        one_machine("lathe", ["vmc-450"], "the bundles")


def test_the_cache_reuses_a_machines_result_only_while_its_inputs_are_unchanged(tmp_path):
    rows = pd.DataFrame({"T1": [20.0, 21.0], "thermal_error_um": [0.0, 3.0]})
    calls = []

    def fit(value):
        calls.append(value)
        return {"fitted": value}

    cache = StageCache("evaluate", tmp_path)
    assert cache.result("a", [("rows", rows)], lambda: fit(1)) == {"fitted": 1}
    again = StageCache("evaluate", tmp_path)
    assert again.result("a", [("rows", rows)], lambda: fit(2)) == {"fitted": 1}
    assert calls == [1] and again.reused == ["a"]
    changed = rows.assign(T1=[20.0, 21.5])
    assert again.result("a", [("rows", changed)], lambda: fit(3)) == {"fitted": 3}
    assert cache_key("evaluate", "a", [("rows", rows)]) != cache_key(
        "evaluate", "b", [("rows", rows)]
    )
    again.prune()  # the entry of the first rows was not used by this run
    assert len(list((tmp_path / "evaluate").glob("*.joblib"))) == 2
    last = StageCache("evaluate", tmp_path)
    last.result("a", [("rows", changed)], lambda: fit(4))
    last.prune()
    assert len(list((tmp_path / "evaluate").glob("*.joblib"))) == 1
    assert calls == [1, 3]

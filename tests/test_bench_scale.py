"""The scale benchmark's fleet writer and growth exponents (``make bench-scale`` runs the rest)."""

from __future__ import annotations

from collections import Counter

import pytest
import yaml

from benchmarks.bench_scale import add_campaign, exponents, report_lines, write_fleet


def _size(machines: int, campaigns: int, seconds: float) -> dict:
    return {
        "machines": machines,
        "campaigns_per_machine": campaigns,
        "stages": {"evaluate": {"seconds": seconds, "peak_mib": 100.0}},
    }


def test_the_exponents_are_the_slopes_of_time_on_log_log_axes():
    sizes = [_size(m, c, 2.0 * m * c**1.5) for m in (1, 2, 4) for c in (6, 12, 24)]
    sizes.append({**_size(8, 6, 1.0), "failed": {"stage": "validate", "output": "refused"}})
    found = exponents(sizes)
    assert set(found["campaigns"]) == {"1", "2", "4"}  # the failed size counts nowhere
    for by_stage in found["campaigns"].values():
        assert by_stage["evaluate"] == pytest.approx(1.5)
    for by_stage in found["machines"].values():
        assert by_stage["evaluate"] == pytest.approx(1.0)


@pytest.mark.parametrize("campaigns", [6, 12])
def test_every_size_covers_the_four_seasons_one_machine_name_per_machine(tmp_path, campaigns):
    ids = write_fleet(tmp_path, machines=2, campaigns=campaigns)
    assert len(ids) == len(set(ids)) == 2 * campaigns
    meta = [yaml.safe_load((tmp_path / i / "campaign.yaml").read_text()) for i in ids]
    assert {m["machine"] for m in meta} == {"workshop-1", "workshop-2"}
    for machine in ("workshop-1", "workshop-2"):
        seasons = Counter(m["season"] for m in meta if m["machine"] == machine)
        assert len(seasons) == 4
        assert max(seasons.values()) - min(seasons.values()) <= 1  # shared out evenly
    with pytest.raises(ValueError, match="4 \\(one a season\\) to 24, not 25"):
        write_fleet(tmp_path, machines=1, campaigns=25)


def test_the_campaign_added_is_the_last_machines_a_week_later_and_cold(tmp_path):
    write_fleet(tmp_path, machines=2, campaigns=6)
    added = add_campaign(tmp_path, 2)
    meta = yaml.safe_load((tmp_path / added / "campaign.yaml").read_text())
    first = yaml.safe_load((tmp_path / "M2R1W01" / "campaign.yaml").read_text())
    assert (meta["campaign_id"], meta["machine"], meta["start_state"]) == (
        added,
        "workshop-2",
        "cold",
    )
    assert (meta["start"] - first["start"]).days == 7


def test_the_report_shows_the_rerun_beside_the_first_run():
    size = {**_size(2, 6, 10.0), "one_more": {"evaluate": {"seconds": 6.0, "peak_mib": 90.0}}}
    run = {"sizes": [size], "exponents": exponents([size])}
    lines = report_lines({"local": run})
    assert "  then one campaign added to workshop-2 (the others' results reused):" in lines
    assert any("6.0 s (first run 10.0 s)" in line for line in lines)

import numpy as np
import pandas as pd
import pytest

from pipeline.io.tables import ingest
from tests.helpers.raw_builders import write_spindle_campaign
from tests.helpers.raw_edits import set_cell


def test_ingest_reads_samples_on_temperature_time_base(tmp_path):
    write_spindle_campaign(tmp_path, "K01", n=10)
    tables = ingest(tmp_path, max_alignment_gap_s=200.0)
    samples = tables["samples"]
    assert list(samples["source_row"]) == list(range(1, 11))
    assert samples["rpm"].iloc[0] == 4000.0
    assert samples["rpm"].iloc[-1] == 0.0  # the program stops at half time
    assert {"T1", "T2", "T3", "T4", "disp_Z", "disp_Z_source_row"} <= set(samples.columns)
    assert tables["problems"].empty
    campaign = tables["campaigns"].iloc[0]
    assert campaign["season"] == "winter" and bool(campaign["season_derived"])


def test_displacement_is_interpolated_to_temperature_instants(tmp_path):
    folder = write_spindle_campaign(tmp_path, "K01", n=10, displacement_offset_s=60.0)
    displacement = pd.read_csv(folder / "displacement.csv")
    samples = ingest(tmp_path, max_alignment_gap_s=200.0)["samples"]
    expected = np.interp(
        samples["elapsed_s"], displacement["elapsed_s"], displacement["Z"], left=np.nan
    )
    np.testing.assert_allclose(samples["disp_Z"], expected, equal_nan=True)
    assert np.isnan(samples["disp_Z"].iloc[0])  # before the first displacement sample
    assert samples["disp_Z_source_row"].iloc[1] == 2  # nearest to 180 s: row 2, at 240 s


def test_an_empty_displacement_cell_is_not_interpolated_across(tmp_path):
    """Validate bridges or drops the gap (validate.max_bridged_gap_s); ingest only marks it."""
    folder = write_spindle_campaign(tmp_path, "K01", n=10, displacement_offset_s=60.0)
    set_cell(folder / "displacement.csv", 4, "Z", "")  # the reading at 600 s
    samples = ingest(tmp_path, max_alignment_gap_s=200.0)["samples"].set_index("source_row")
    # the instants at 540 s and 720 s lie between row 4 and a neighbour: no value, row 4 named
    assert samples.loc[[4, 5], "disp_Z"].isna().all()
    assert list(samples.loc[[4, 5], "disp_Z_source_row"]) == [4, 4]
    assert samples.loc[[2, 3, 6, 7, 8, 9, 10], "disp_Z"].notna().all()
    # before the first displacement sample (60 s) there is no reading to name
    assert np.isnan(samples.loc[1, "disp_Z"]) and pd.isna(samples.loc[1, "disp_Z_source_row"])


def test_alignment_gap_leaves_displacement_missing(tmp_path):
    write_spindle_campaign(tmp_path, "K01", n=10, displacement_offset_s=60.0)
    samples = ingest(tmp_path, max_alignment_gap_s=30.0)["samples"]
    assert samples["disp_Z"].isna().all()


def test_measured_speed_log_wins_over_program(tmp_path):
    folder = write_spindle_campaign(tmp_path, "K01", n=10)
    (folder / "spindle.csv").write_text("elapsed_s,rpm\n0,1000\n500,3000\n")
    samples = ingest(tmp_path, max_alignment_gap_s=200.0)["samples"]
    assert list(samples["rpm"].iloc[:4]) == [1000.0, 1000.0, 1000.0, 3000.0]


def test_bad_content_becomes_problems_with_file_row_column(tmp_path):
    folder = write_spindle_campaign(tmp_path, "K01", n=10)
    lines = (folder / "temperature.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[2] = "err"
    lines[3] = ",".join(cells)
    (folder / "temperature.csv").write_text("\n".join(lines) + "\n")
    (folder / "campaign.yaml").write_text(
        (folder / "campaign.yaml").read_text().replace("campaign_id: K01", "campaign_id: K1")
    )
    write_spindle_campaign(tmp_path, "K02", n=10)
    (tmp_path / "K02" / "displacement.csv").unlink()
    problems = ingest(tmp_path, max_alignment_gap_s=200.0)["problems"]
    by_check = {p.check: p for p in problems.itertuples()}
    assert by_check["not_a_number"].campaign_id == "K01"
    assert by_check["not_a_number"].file == "temperature.csv"
    assert by_check["not_a_number"].row == 3 and by_check["not_a_number"].column == "T2"
    assert by_check["campaign_id_mismatch"].column == "campaign_id"
    assert by_check["missing_file"].campaign_id == "K02"
    assert "displacement.csv" in by_check["missing_file"].problem


def test_unreadable_yaml_names_the_line(tmp_path):
    folder = tmp_path / "K05"
    folder.mkdir()
    (folder / "campaign.yaml").write_text("campaign_id: K05\nkind: [spindle_drift\n")
    tables = ingest(tmp_path, max_alignment_gap_s=200.0)
    problem = tables["problems"].iloc[0]
    assert problem["check"] == "unreadable_yaml" and problem["file"] == "campaign.yaml"
    assert pd.notna(problem["row"])
    assert tables["campaigns"].empty


def test_missing_raw_folder_says_what_to_do(tmp_path):
    with pytest.raises(FileNotFoundError, match="thermal simulate --preset demo"):
        ingest(tmp_path / "nope", max_alignment_gap_s=200.0)


def test_raw_files_are_not_modified(tmp_path):
    folder = write_spindle_campaign(tmp_path, "K01", n=10)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    ingest(tmp_path, max_alignment_gap_s=200.0)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_start_state_and_follows_are_read_and_optional(tmp_path):
    write_spindle_campaign(tmp_path, "K01", n=10)
    folder = write_spindle_campaign(tmp_path, "K02", n=10)
    meta = (folder / "campaign.yaml").read_text()
    (folder / "campaign.yaml").write_text(meta + "start_state: warm\nfollows: K01\n")
    campaigns = ingest(tmp_path, max_alignment_gap_s=200.0)["campaigns"].set_index("campaign_id")
    assert campaigns.loc["K02", "start_state"] == "warm"
    assert campaigns.loc["K02", "follows"] == "K01"
    assert campaigns.loc["K01", ["start_state", "follows"]].isna().all()


def test_a_second_probe_under_another_name_is_read(tmp_path):
    folder = write_spindle_campaign(tmp_path, "K01", n=10)
    displacement = pd.read_csv(folder / "displacement.csv")
    displacement["Z2"] = displacement["Z"] * 0.5
    displacement.to_csv(folder / "displacement.csv", index=False)
    tables = ingest(tmp_path, max_alignment_gap_s=200.0)
    np.testing.assert_allclose(tables["samples"]["disp_Z2"], 0.5 * tables["samples"]["disp_Z"])
    assert tables["problems"].empty

"""Every campaign folder of a raw folder read into the four ingested tables.

``campaigns`` (one row per campaign), ``samples`` (temperatures, displacements and speed on one
time base), ``laser`` (interferometer runs) and ``problems`` (what stopped a file or value from
being read, for the validation report); columns as in :mod:`schemas.ingested`. The ``ingest``
stage writes them; ``thermal discrepancy --raw`` reads a folder outside the pipeline with them.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipeline.errors import MissingInputError
from pipeline.io.reader import Problem, RawCampaign, problems_frame, read_campaign
from schemas import CampaignsModel


def campaign_folders(raw_dir: Path) -> list[Path]:
    """Campaign folders under ``raw_dir``, sorted by name (hidden entries ignored)."""
    if not raw_dir.is_dir():
        raise MissingInputError(
            f"raw campaign folder {raw_dir} does not exist; put one folder per campaign there "
            "(see docs/data-contract.md) or generate the demo set with "
            "'thermal simulate --preset demo --out data/raw'"
        )
    return sorted(p for p in raw_dir.iterdir() if p.is_dir() and not p.name.startswith("."))


def ingest(raw_dir: Path, max_alignment_gap_s: float) -> dict[str, pd.DataFrame]:
    """Read every campaign folder into the four ingested tables.

    Parameters
    ----------
    raw_dir : Path
        Folder holding one sub-folder per campaign.
    max_alignment_gap_s : float
        Seconds; see :func:`pipeline.io.reader.read_campaign`.

    Returns
    -------
    dict of str to DataFrame
        ``campaigns``, ``samples``, ``laser`` and ``problems``.
    """
    campaigns = [read_campaign(folder, max_alignment_gap_s) for folder in campaign_folders(raw_dir)]
    return tabulate(campaigns)


def tabulate(campaigns: list[RawCampaign]) -> dict[str, pd.DataFrame]:
    """Concatenate per-campaign reads into the ingested tables (all columns even when empty)."""
    problems: list[Problem] = [p for c in campaigns for p in c.problems]
    metadata = pd.DataFrame(
        [c.metadata for c in campaigns if c.metadata is not None],
        columns=list(CampaignsModel.to_schema().columns),
    )
    samples = [c.samples for c in campaigns if c.samples is not None and len(c.samples)]
    laser = [c.laser for c in campaigns if c.laser is not None]
    return {
        "campaigns": metadata,
        "samples": _concat_samples(samples),
        "laser": pd.concat(laser, ignore_index=True) if laser else _empty_laser(),
        "problems": problems_frame(problems),
    }


def _concat_samples(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """Union of the per-campaign columns: fixed columns first, then sensors, then displacement."""
    if not frames:
        return pd.DataFrame(
            {
                "campaign_id": pd.Series(dtype="str"),
                "source_row": pd.Series(dtype="int64"),
                "elapsed_s": pd.Series(dtype="float64"),
                "rpm": pd.Series(dtype="float64"),
            }
        )
    combined = pd.concat(frames, ignore_index=True, sort=False)
    fixed = ["campaign_id", "source_row", "elapsed_s", "rpm"]
    displacement = sorted(c for c in combined.columns if c.startswith("disp_"))
    sensors = [c for c in combined.columns if c not in fixed and c not in displacement]
    combined = combined[fixed + sensors + displacement]
    for column in displacement:
        if column.endswith("_source_row"):
            combined[column] = combined[column].astype("Int64")
    return combined


def _empty_laser() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "campaign_id": pd.Series(dtype="str"),
            "source_row": pd.Series(dtype="int64"),
            "elapsed_min": pd.Series(dtype="float64"),
            "run": pd.Series(dtype="int64"),
            "direction": pd.Series(dtype="str"),
            "target_mm": pd.Series(dtype="float64"),
            "deviation_um": pd.Series(dtype="float64"),
        }
    )

r"""Write a spindle thermal-drift campaign folder in the raw contract (docs/data-contract.md).

``campaign.yaml`` is written with :func:`yaml.safe_dump` (so that any name or text is quoted
where YAML needs it), the CSV files comma separated, UTF-8, ``\n`` line endings, numbers with
10 significant digits and empty cells for missing readings.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from schemas.contract import FILE_NAMES

logger = logging.getLogger(__name__)

FLOAT_FORMAT = "%.10g"


@dataclass(frozen=True)
class SpindleDriftCampaign:
    """One campaign ready to be written.

    Attributes
    ----------
    campaign_id : str
        Folder name.
    metadata : dict
        campaign.yaml keys after ``campaign_id`` and ``kind`` (``machine``, ``start``,
        ``sensors``, ``displacement``...), written in this order; None values are left out.
    temperature : DataFrame
        ``elapsed_s`` (s since ``start``) then one column per sensor, degC.
    displacement : DataFrame
        ``elapsed_s`` then one column per axis, um.
    spindle : DataFrame
        ``elapsed_s``, ``rpm``.
    """

    campaign_id: str
    metadata: dict[str, Any]
    temperature: pd.DataFrame
    displacement: pd.DataFrame
    spindle: pd.DataFrame


def campaign_yaml(campaign: SpindleDriftCampaign) -> str:
    """Return the campaign.yaml text (``kind: spindle_drift``)."""
    content = {"campaign_id": campaign.campaign_id, "kind": "spindle_drift"}
    content |= {k: v for k, v in campaign.metadata.items() if v is not None}
    return yaml.safe_dump(
        content, sort_keys=False, default_flow_style=None, allow_unicode=True, width=100
    )


def write_campaign(campaign: SpindleDriftCampaign, out_dir: Path, overwrite: bool) -> Path:
    """Write ``out_dir/<campaign_id>/``; return the folder.

    Parameters
    ----------
    campaign : SpindleDriftCampaign
    out_dir : Path
        The raw directory (e.g. ``data/raw``); created if missing.
    overwrite : bool
        Replace an existing folder's contract files (other files are left alone); False: raise.

    Raises
    ------
    FileExistsError
        The folder exists and ``overwrite`` is False.
    """
    folder = out_dir / campaign.campaign_id
    if folder.exists() and not overwrite:
        raise FileExistsError(f"{folder} already exists")
    folder.mkdir(parents=True, exist_ok=True)
    for name in FILE_NAMES:
        (folder / name).unlink(missing_ok=True)
    with (folder / "campaign.yaml").open("w", encoding="utf-8", newline="\n") as handle:
        handle.write(campaign_yaml(campaign))
    for name, table in (
        ("temperature.csv", campaign.temperature),
        ("displacement.csv", campaign.displacement),
        ("spindle.csv", campaign.spindle),
    ):
        table.to_csv(
            folder / name,
            index=False,
            float_format=FLOAT_FORMAT,
            na_rep="",
            lineterminator="\n",
            encoding="utf-8",
        )
    logger.info("wrote %s", folder)
    return folder

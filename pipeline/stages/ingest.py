"""DVC stage ``ingest``: every campaign folder under ``data/raw/`` -> tidy parquet tables.

Writes ``data/ingested/{campaigns,samples,laser,problems}.parquet`` (columns in
``schemas.ingested``). Bad content does not stop the stage: it is recorded in the problems table
and the validation stage quarantines the campaign. Raw files are only read.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from pipeline import paths
from pipeline.io.tables import ingest
from pipeline.settings.base import load_settings
from pipeline.settings.ingest import IngestSettings
from pipeline.warnings_capture import summarise_warnings

LOGGER = logging.getLogger(__name__)


@summarise_warnings()
def main(argv: list[str] | None = None) -> int:
    """Run the stage: read ``data/raw``, write ``data/ingested/*.parquet``."""
    parser = argparse.ArgumentParser(prog="thermal ingest", description=__doc__.splitlines()[0])
    parser.add_argument("--raw", type=Path, default=paths.RAW, help="raw campaign folder")
    parser.add_argument("--out", type=Path, default=paths.INGESTED, help="output folder")
    args = parser.parse_args(argv)
    settings = load_settings(IngestSettings, "ingest")
    tables = ingest(args.raw, settings.max_alignment_gap_s)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, table in tables.items():
        table.to_parquet(args.out / f"{name}.parquet", engine="pyarrow", index=False)
    LOGGER.info(
        "ingested %d campaign folders (%d samples, %d laser rows, %d problems) into %s",
        len(tables["campaigns"]),
        len(tables["samples"]),
        len(tables["laser"]),
        len(tables["problems"]),
        args.out,
    )
    return 0

"""``thermal import <source>``: convert a logger's table or instrument exports into campaigns.

``thermal import logger TABLE --mapping MAPPING.yaml --out data/raw`` cuts a data logger's
wide table into contract campaign folders (:mod:`pipeline.importers.logger_import`,
``docs/import-logger.md``); ``thermal import rtl FILE.rtl ... --out data/raw/<id>`` writes an
axis campaign's ``laser.csv`` from Renishaw laser exports (:mod:`pipeline.importers.rtl_import`,
``docs/import-rtl.md``). ``thermal import <source> --help`` lists each one's options.
"""

from __future__ import annotations

import sys

from pipeline.cli import dispatch

SOURCES = {
    "logger": ("pipeline.importers.logger_import", "a data logger's wide table (CSV or XLSX)"),
    "rtl": ("pipeline.importers.rtl_import", "Renishaw .rtl laser interferometer exports"),
}


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv[0]`` to its importer; return the process exit code."""
    return dispatch(
        "thermal import", SOURCES, list(sys.argv[1:] if argv is None else argv), "source"
    )

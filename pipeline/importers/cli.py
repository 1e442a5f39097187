"""``thermal import <source>``: convert a logger's table or instrument exports into campaigns.

``thermal import logger TABLE --mapping MAPPING.yaml --out data/raw`` cuts a data logger's
wide table into contract campaign folders (:mod:`pipeline.importers.logger_import`,
``docs/import-logger.md``); ``thermal import rtl FILE.rtl ... --out data/raw/<id>`` writes an
axis campaign's ``laser.csv`` from Renishaw laser exports (:mod:`pipeline.importers.rtl_import`,
``docs/import-rtl.md``). ``thermal import <source> --help`` lists each one's options.
"""

from __future__ import annotations

import importlib
import sys

SOURCES = {
    "logger": ("pipeline.importers.logger_import", "a data logger's wide table (CSV or XLSX)"),
    "rtl": ("pipeline.importers.rtl_import", "Renishaw .rtl laser interferometer exports"),
}


def _usage() -> str:
    lines = ["usage: thermal import <source> [options]", "", "sources:"]
    lines += [f"  {name:<8} {text}" for name, (_, text) in SOURCES.items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv[0]`` to its importer; return the process exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in {"-h", "--help"}:
        sys.stdout.write(_usage() + "\n")
        return 0 if args else 2
    if args[0] not in SOURCES:
        sys.stderr.write(f"thermal import: unknown source '{args[0]}'\n\n{_usage()}\n")
        return 2
    module = importlib.import_module(SOURCES[args[0]][0])
    return int(module.main(args[1:]) or 0)

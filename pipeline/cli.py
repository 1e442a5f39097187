"""The ``thermal`` command: one sub-command per DVC stage and tool.

``thermal <command> [options]`` (or ``python -m pipeline <command>``) imports the command's
module and calls its ``main(argv)``; ``thermal <command> --help`` lists that command's options.
A :class:`pipeline.errors.UserError` (bad input data, params.yaml, a stage not run yet) is printed
as ``thermal <command>: error: <message>`` with exit code 1, without a traceback; any other
exception is an internal error and keeps its traceback.
"""

from __future__ import annotations

import importlib
import logging
import sys

from pipeline.errors import UserError

COMMANDS = {
    "simulate": ("pipeline.twin.cli", "write synthetic campaigns from the physical twin"),
    "import": ("pipeline.importers.cli", "a logger's table or laser exports -> campaign folders"),
    "ingest": ("pipeline.ingest", "raw campaign folders -> tidy parquet tables"),
    "validate": ("pipeline.validate", "Pandera checks; quarantine bad campaigns"),
    "separate": ("pipeline.separate", "geometric / thermal error separation"),
    "model-axis": ("pipeline.model_axis", "linear-axis composite model (the patent)"),
    "select": ("pipeline.select", "sensitive temperature points by every selection method"),
    "evaluate": ("pipeline.evaluate", "fit models, score every campaign against every other"),
    "discrepancy": ("pipeline.discrepancy_stage", "twin vs measurements: which effect is missing"),
    "discrepancy-trials": (
        "pipeline.discrepancy.trials",
        "rate of correct naming on campaigns with hidden effects",
    ),
    "discrepancy-demo-check": (
        "pipeline.discrepancy.demo_check",
        "the workflow on the demo plans with and without their unseen state",
    ),
    "track": ("pipeline.track", "log the scores to MLflow"),
    "summary": ("pipeline.summary", "print where the results are and how to open MLflow"),
    "contract-doc": ("pipeline.contract_doc", "write the tables of docs/data-contract.md"),
    "bench": ("pipeline.bench", "time each stage of the default dvc repro"),
}


def _usage() -> str:
    lines = ["usage: thermal <command> [options]", "", "commands:"]
    lines += [f"  {name:<19} {text}" for name, (_, text) in COMMANDS.items()]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv[0]`` to its command module; return the process exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in {"-h", "--help"}:
        sys.stdout.write(_usage() + "\n")
        return 0 if args else 2
    name, rest = args[0], args[1:]
    if name not in COMMANDS:
        sys.stderr.write(f"thermal: unknown command '{name}'\n\n{_usage()}\n")
        return 2
    logging.basicConfig(
        level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )
    module = importlib.import_module(COMMANDS[name][0])
    try:
        return int(module.main(rest) or 0)
    except UserError as error:
        sys.stderr.write(f"thermal {name}: error: {error}\n")
        return 1

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
    "ingest": ("pipeline.stages.ingest", "raw campaign folders -> tidy parquet tables"),
    "validate": ("pipeline.stages.validate", "Pandera checks; quarantine bad campaigns"),
    "separate-spindle": ("pipeline.stages.separate_spindle", "spindle thermal error and its runs"),
    "separate-axis": ("pipeline.stages.separate_axis", "axis geometric / thermal separation"),
    "model-axis": ("pipeline.stages.model_axis", "linear-axis composite model (the patent)"),
    "select": ("pipeline.stages.select", "sensitive temperature points by every selection method"),
    "evaluate": (
        "pipeline.stages.evaluate",
        "fit models, score every campaign against every other",
    ),
    "discrepancy": ("pipeline.stages.discrepancy", "twin vs measurements: which effect is missing"),
    "compensation": (
        "pipeline.stages.compensation",
        "each axis' runtime bundle, controller exports, replay proof, sensor budget",
    ),
    "track": ("pipeline.stages.track", "log the scores to MLflow"),
    "compensate": (
        "pipeline.compensation.cli",
        "run the compensation: live inputs from a file or OPC UA -> per-axis offsets",
    ),
    "retrain": (
        "pipeline.retraining.retrain",
        "pull new campaigns, dvc repro, report the promotion gate",
    ),
    "rollback": ("pipeline.retraining.rollback", "move an axis' @champion back to @previous"),
    "summary": ("pipeline.reporting.summary", "print where the results are and how to open MLflow"),
    "contract-doc": ("pipeline.io.contract_doc", "write the tables of docs/data-contract.md"),
}


def dispatch(prog: str, commands: dict[str, tuple[str, str]], args: list[str], noun: str) -> int:
    """Run ``args[0]``'s module ``main(args[1:])``; print the usage for none, -h or an unknown one.

    Parameters
    ----------
    prog : str
        The command line so far, e.g. ``thermal`` or ``thermal import``.
    commands : dict
        Name -> (module, one-line description).
    args : list of str
        The arguments after ``prog``.
    noun : str
        What a name is called in messages (``command``, ``source``).

    Returns
    -------
    int
        The module's exit code; 0 for help, 2 for a missing or unknown name.
    """
    lines = [f"usage: {prog} <{noun}> [options]", "", f"{noun}s:"]
    width = max(len(name) for name in commands)
    lines += [f"  {name:<{width}}  {text}" for name, (_, text) in commands.items()]
    usage = "\n".join(lines)
    if not args or args[0] in {"-h", "--help"}:
        sys.stdout.write(usage + "\n")
        return 0 if args else 2
    if args[0] not in commands:
        sys.stderr.write(f"{prog}: unknown {noun} '{args[0]}'\n\n{usage}\n")
        return 2
    module = importlib.import_module(commands[args[0]][0])
    return int(module.main(args[1:]) or 0)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv[0]`` to its command module; return the process exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args and args[0] in COMMANDS:
        logging.basicConfig(
            level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
        )
    try:
        return dispatch("thermal", COMMANDS, args, "command")
    except UserError as error:
        sys.stderr.write(f"thermal {args[0]}: error: {error}\n")
        return 1

"""Generate the tables of ``docs/data-contract.md`` from the code that enforces the contract.

``thermal contract-doc`` rewrites the blocks between ``<!-- generated: <name> -->`` and
``<!-- end generated: <name> -->`` in the document: the keys of ``campaign.yaml``
(:data:`schemas.contract.CAMPAIGN_KEYS`), the sensor roles (:mod:`schemas.vocabulary`), the
files and their columns (:data:`schemas.contract.FILES`), every check of the ingest and
validate stages with its message and action (:data:`pipeline.validation.texts.PROBLEM_TEXTS`)
and the warnings of missing readings (:data:`pipeline.validation.texts.WARNING_TEXTS`).
``thermal contract-doc --check`` fails when the
document differs from what the code would write; the test suite runs that check. The prose
around the blocks is written by hand.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path

from pipeline.errors import InputDataError, MissingInputError
from pipeline.validation.texts import PROBLEM_TEXTS, WARNING_TEXTS
from schemas.contract import ALWAYS, CAMPAIGN_KEYS, FILES, OPTIONAL, VERSION
from schemas.vocabulary import AMBIENT_ROLE, SENSOR_ROLES

DOCUMENT = Path(__file__).resolve().parents[2] / "docs" / "data-contract.md"
"""The document, in the repository this package is installed from (an editable install)."""
BLOCK_RE = re.compile(
    r"(<!-- generated: (?P<name>[a-z-]+) -->\n)(?P<body>.*?)(<!-- end generated: (?P=name) -->)",
    re.DOTALL,
)


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("\n", " ") for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _requirement(required: str) -> str:
    """Return who needs a key or file: every campaign, none, or one kind of campaign."""
    return {ALWAYS: "every campaign", OPTIONAL: "optional"}.get(required, f"`kind: {required}`")


def keys_block() -> str:
    """Return the table of ``campaign.yaml`` keys."""
    rows = [(f"`{k.name}`", _requirement(k.required), k.value, k.meaning) for k in CAMPAIGN_KEYS]
    return _table(("key", "required", "value", "meaning"), rows)


def roles_block() -> str:
    """Return the list of sensor roles."""
    roles = ", ".join(f"`{role}`" for role in SENSOR_ROLES)
    return f"{roles}. At most one sensor of a campaign is `{AMBIENT_ROLE}`.\n"


def files_block() -> str:
    """Return one table per file of a campaign folder."""
    parts = []
    for file in FILES:
        if not file.columns:
            continue
        parts.append(f"**`{file.name}`** ({_requirement(file.required)})\n\n")
        parts.append(_table(("column", "content"), [(f"`{c}`", m) for c, m in file.columns]))
        parts.append("\n")
    return "".join(parts).rstrip("\n") + "\n"


def _readable(template: str) -> str:
    """Return a message template with its ``{field}`` placeholders shown as ``<field>``."""
    text = re.sub(r"(?<!\{)\{(\w+)\}(?!\})", r"<\1>", template)
    return text.replace("{{", "{").replace("}}", "}").replace("|", "\\|")


def checks_block() -> str:
    """Return the table of every check: id, what is wrong, what to do."""
    rows = [
        (f"`{check}`", _readable(text.message), _readable(text.action))
        for check, text in PROBLEM_TEXTS.items()
    ]
    return _table(("check", "what is wrong", "what to do"), rows)


def warnings_block() -> str:
    """Return the table of every warning of a missing reading: case, what happened, what to do."""
    rows = [
        (f"`{case}`", _readable(text.message), _readable(text.action))
        for case, text in WARNING_TEXTS.items()
    ]
    return _table(("warning", "what happened", "what to do"), rows)


BLOCKS: dict[str, Callable[[], str]] = {
    "version": lambda: f"Version {VERSION}.\n",
    "keys": keys_block,
    "roles": roles_block,
    "files": files_block,
    "checks": checks_block,
    "warnings": warnings_block,
}


def render(document: str, name: str = "the document") -> str:
    """Return ``document`` with every generated block rewritten.

    Raises
    ------
    InputDataError
        When a block of :data:`BLOCKS` has no markers in the document (``name`` says which).
    """
    found = {match["name"] for match in BLOCK_RE.finditer(document)}
    missing = sorted(set(BLOCKS) - found)
    if missing:
        raise InputDataError(
            f"{name}: no generated block {missing}; add '<!-- generated: NAME -->' and "
            "'<!-- end generated: NAME -->' lines where each belongs"
        )
    return BLOCK_RE.sub(lambda m: m.group(1) + BLOCKS[m["name"]]() + m.group(4), document)


def main(argv: list[str] | None = None) -> int:
    """Rewrite (or with ``--check`` compare) the generated blocks; return the exit code."""
    parser = argparse.ArgumentParser(
        prog="thermal contract-doc", description="generate the tables of docs/data-contract.md"
    )
    parser.add_argument("--path", type=Path, default=DOCUMENT, help="the document (%(default)s)")
    parser.add_argument(
        "--check", action="store_true", help="fail if the document differs from the code"
    )
    args = parser.parse_args(argv)
    if not args.path.is_file():
        raise MissingInputError(
            f"{args.path} not found: run thermal contract-doc in a clone of the repository, or "
            "give the document with --path"
        )
    current = args.path.read_text(encoding="utf-8")
    wanted = render(current, str(args.path))
    if args.check:
        if wanted != current:
            sys.stderr.write(
                f"{args.path} is out of date with schemas/ and pipeline/validation/texts.py; "
                "run 'thermal contract-doc' and commit the result\n"
            )
            return 1
        return 0
    args.path.write_text(wanted, encoding="utf-8")
    return 0

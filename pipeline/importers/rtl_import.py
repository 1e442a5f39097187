"""``thermal import rtl``: Renishaw ``.rtl`` laser exports -> an axis campaign's ``laser.csv``.

One ``.rtl`` file holds the runs measured at one warm-up time. The files are read with
:func:`pipeline.importers.renishaw.read_rtl`; each gets an ``elapsed_min`` (the warm-up time,
from ``--warmup-min`` in file order or from the files' ``Date`` relative to the earliest file),
and their runs are written to ``<out>/laser.csv`` in time order, numbered 1.., one row per
target: ``elapsed_min,run,direction,target_mm,deviation_um``. The cold pass (elapsed_min 0) must
be among the files, every file must hold runs in both directions and all files the same targets,
as the validate stage requires. If ``<out>`` has no ``campaign.yaml`` a skeleton is written when
``--machine --axis --stroke-mm`` and a start time are given; ``temperature.csv`` is never
written (the user supplies it). Input files are only read. Exit code 2 and one paragraph on
stderr for any user or data error.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path

import pandas as pd
import yaml

from pipeline.importers.arguments import non_negative, positive
from pipeline.importers.axis_campaign_yaml import SKELETON_OPTIONS, keys_to_add, skeleton_text
from pipeline.importers.renishaw import RtlFile, RtlFormatError, read_rtl
from schemas.contract import LASER_COLUMNS
from schemas.vocabulary import AXIS_KIND, CAMPAIGN_ID_RE, is_displacement_name

PROG = "thermal import rtl"


class ImportRtlError(ValueError):
    """A user error of ``thermal import rtl`` not tied to one line of a file."""


def main(argv: list[str] | None = None) -> int:
    """Run ``thermal import rtl``; return the exit code (0 done, 2 user or data error)."""
    try:
        args = _parser().parse_args(argv)
    except SystemExit as done:  # argparse: --help (0) or a usage error (2, already printed)
        return int(done.code or 0)
    try:
        message = import_rtl(
            [Path(f) for f in args.files],
            Path(args.out),
            args.warmup_min,
            force=args.force,
            skeleton={key: getattr(args, key) for key in SKELETON_OPTIONS},
        )
    except (RtlFormatError, ImportRtlError) as error:
        sys.stderr.write(f"{PROG}: {error}\n")
        return 2
    sys.stdout.write(message + "\n")
    return 0


def import_rtl(
    files: Sequence[Path],
    out: Path,
    warmup_min: Sequence[float] | None,
    *,
    force: bool,
    skeleton: dict[str, object],
) -> str:
    """Convert ``.rtl`` files to ``<out>/laser.csv`` (and maybe a ``campaign.yaml`` skeleton).

    Parameters
    ----------
    files : sequence of Path
        One ``.rtl`` file per warm-up time.
    out : Path
        The campaign folder ``<raw dir>/<campaign_id>/`` (created if missing).
    warmup_min : sequence of float or None, min
        Warm-up time of each file, in file order; None to take the times from the files'
        ``Date`` lines, relative to the earliest file.
    force : bool
        Overwrite an existing ``laser.csv``.
    skeleton : dict
        ``machine``, ``axis``, ``stroke_mm``, ``start`` (datetime) for a new ``campaign.yaml``;
        None where not given.

    Returns
    -------
    str
        One paragraph saying what was written and what the user must still supply.

    Raises
    ------
    RtlFormatError
        A file is not in the layout read (names file, line and section).
    ImportRtlError
        Any other user error (arguments, folder, inconsistent files).
    """
    campaign_id = out.name
    _check_target_folder(out, force)
    rtls = _read_all(files)
    elapsed = _elapsed_minutes(rtls, warmup_min)
    _check_consistent(rtls)
    laser = laser_rows(rtls, elapsed)
    _write_atomic(out / "laser.csv", laser.to_csv(index=False, lineterminator="\n"))
    header_start = min(r.measured_at() for r in rtls) if warmup_min is None else None
    note = _campaign_yaml(out, campaign_id, skeleton, header_start, len(rtls))
    times = ", ".join(f"{m:g}" for m in sorted(elapsed))
    return (
        f"wrote {out / 'laser.csv'}: {len(laser)} rows, {laser['run'].nunique()} runs from "
        f"{len(rtls)} files at elapsed_min {times}. {note}. temperature.csv is not written by "
        f"this importer: add {out / 'temperature.csv'} yourself (elapsed_s since start, one "
        "column per sensor in degC, as in docs/data-contract.md) before running dvc repro."
    )


def laser_rows(rtls: Sequence[RtlFile], elapsed_min: Sequence[float]) -> pd.DataFrame:
    """Return the ``laser.csv`` table of the files' runs, runs numbered 1.. in time order.

    Parameters
    ----------
    rtls : sequence of RtlFile
        Parsed files.
    elapsed_min : sequence of float, min
        Time of each file since ``start``, same order as ``rtls``.

    Returns
    -------
    DataFrame
        Columns ``elapsed_min`` (min), ``run``, ``direction``, ``target_mm`` (mm),
        ``deviation_um`` (um); one row per target of each run, in measurement order.
    """
    rows = []
    run_number = 0
    for minutes, rtl in sorted(zip(elapsed_min, rtls, strict=True), key=lambda pair: pair[0]):
        for run in rtl.runs:
            run_number += 1
            rows += [
                (float(minutes), run_number, run.direction, target, deviation)
                for target, deviation in zip(run.target_mm, run.deviation_um, strict=True)
            ]
    return pd.DataFrame(rows, columns=list(LASER_COLUMNS))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Convert Renishaw .rtl laser exports (one file per warm-up time) into the "
        "laser.csv of an axis_positioning campaign folder (see docs/import-rtl.md).",
    )
    parser.add_argument("files", nargs="+", metavar="FILE.rtl", help="one file per warm-up time")
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="campaign folder, e.g. data/raw/A07"
    )
    times = parser.add_mutually_exclusive_group(required=True)
    times.add_argument(
        "--warmup-min",
        nargs="+",
        type=non_negative,
        metavar="M",
        help="warm-up time (min since start) of each file, in file order; one must be 0",
    )
    times.add_argument(
        "--times-from-header",
        action="store_true",
        help="take each file's time from its Date line (YYYY-MM-DD HH:MM[:SS]), relative to "
        "the earliest file",
    )
    parser.add_argument("--force", action="store_true", help="overwrite an existing laser.csv")
    skeleton = parser.add_argument_group("campaign.yaml skeleton (only if the folder has none)")
    skeleton.add_argument("--machine", help="machine name (free text)")
    skeleton.add_argument("--axis", type=_axis, help="axis measured, e.g. Y")
    skeleton.add_argument("--stroke-mm", type=positive, metavar="MM", help="axis travel (mm)")
    skeleton.add_argument(
        "--start",
        type=_iso_datetime,
        help="ISO 8601 local time of the cold run (default with --times-from-header: the Date "
        "of the cold file)",
    )
    return parser


def _axis(text: str) -> str:
    if not is_displacement_name(text):
        raise argparse.ArgumentTypeError(f"'{text}' is not an axis name like X, Y, Z")
    return text


def _iso_datetime(text: str) -> datetime:
    try:
        value = datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"'{text}' is not an ISO 8601 date-time like 2015-01-12T08:30:00"
        ) from None
    if value.tzinfo is not None:
        raise argparse.ArgumentTypeError(f"'{text}' has a time zone; give the local time")
    return value


def _check_target_folder(out: Path, force: bool) -> None:
    """Refuse a folder that is not a campaign id, an existing laser.csv, a non-axis campaign."""
    if not CAMPAIGN_ID_RE.match(out.name):
        raise ImportRtlError(
            f"--out {out}: the folder name '{out.name}' is the campaign id and may hold only "
            "letters, digits, '-' and '_'; choose e.g. --out data/raw/A07"
        )
    if out.exists() and not out.is_dir():
        raise ImportRtlError(f"--out {out} exists and is not a folder; choose a campaign folder")
    if (out / "laser.csv").exists() and not force:
        raise ImportRtlError(
            f"{out / 'laser.csv'} already exists and was left unchanged; add --force to "
            "overwrite it, or choose another --out folder"
        )
    meta_path = out / "campaign.yaml"
    if not meta_path.is_file():
        return
    try:
        meta = yaml.safe_load(meta_path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError):
        return  # the validate stage reports an unreadable campaign.yaml with its line
    kind = meta.get("kind") if isinstance(meta, dict) else None
    if kind is not None and kind != AXIS_KIND:
        raise ImportRtlError(
            f"{meta_path} declares kind: {kind}, but laser.csv belongs to a kind: {AXIS_KIND} "
            "campaign; choose another --out folder or correct campaign.yaml"
        )


def _read_all(files: Sequence[Path]) -> list[RtlFile]:
    resolved = [f.resolve() for f in files]
    for index, path in enumerate(resolved):
        if path in resolved[:index]:
            raise ImportRtlError(f"{files[index]} is given twice; give each .rtl file once")
        if not path.is_file():
            raise ImportRtlError(f"{files[index]} is not a file; check the path")
    return [read_rtl(path) for path in files]


def _elapsed_minutes(rtls: list[RtlFile], warmup_min: Sequence[float] | None) -> list[float]:
    """Return each file's elapsed_min; the earliest must be 0 and all must differ."""
    if warmup_min is None:
        stamps = [r.measured_at() for r in rtls]
        first = min(stamps)
        elapsed = [(stamp - first).total_seconds() / 60.0 for stamp in stamps]
    else:
        if len(warmup_min) != len(rtls):
            raise ImportRtlError(
                f"{len(rtls)} .rtl files but {len(warmup_min)} --warmup-min values; give one "
                "warm-up time (min) per file, in the order of the files"
            )
        elapsed = [float(m) for m in warmup_min]
        if min(elapsed) != 0:
            raise ImportRtlError(
                f"no file has warm-up time 0 (--warmup-min {' '.join(f'{m:g}' for m in elapsed)});"
                " the cold pass at elapsed_min 0 carries the geometric error and is required: "
                "add the cold-machine file with warm-up time 0"
            )
    for index, minutes in enumerate(elapsed):
        if minutes in elapsed[:index]:
            raise ImportRtlError(
                f"{rtls[index].path} and {rtls[elapsed.index(minutes)].path} both have "
                f"elapsed_min {minutes:g}; give one file per warm-up time"
            )
    return elapsed


def _check_consistent(rtls: list[RtlFile]) -> None:
    """Require runs in both directions in every file and the same targets in all files."""
    reference = rtls[0]
    for rtl in rtls:
        directions = {run.direction for run in rtl.runs}
        if directions != {"+", "-"}:
            raise ImportRtlError(
                f"{rtl.path} has only '{directions.pop()}' runs; laser.csv needs both directions "
                "at each warm-up time (bidirectional passes): export a bidirectional measurement"
            )
        if rtl.targets_mm != reference.targets_mm:
            raise ImportRtlError(
                f"{rtl.path} has the targets {list(rtl.targets_mm)} mm but {reference.path} has "
                f"{list(reference.targets_mm)} mm; all runs of a campaign must measure the same "
                "targets, so import files of one target set together"
            )


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file, so no half file is left behind."""
    partial = path.with_name(path.name + ".partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(text, encoding="utf-8")
        os.replace(partial, path)
    except OSError as error:
        raise ImportRtlError(
            f"cannot write {path} ({error.strerror}); check the --out folder and its permissions"
        ) from error


def _campaign_yaml(
    out: Path,
    campaign_id: str,
    skeleton: dict[str, object],
    header_start: datetime | None,
    n_files: int,
) -> str:
    """Write a campaign.yaml skeleton if none exists; return the sentence saying what happened.

    ``header_start`` (the Date of the cold file, with --times-from-header) is the start when
    ``--start`` is not given.
    """
    path = out / "campaign.yaml"
    if path.exists():
        given = [SKELETON_OPTIONS[key] for key, value in skeleton.items() if value is not None]
        ignored = f" ({', '.join(given)} ignored)" if given else ""
        return f"{path} exists and was left unchanged{ignored}"
    values = {**skeleton, "start": skeleton["start"] or header_start}
    missing = [key for key, value in values.items() if value is None]
    if missing:
        return keys_to_add(campaign_id, missing)
    _write_atomic(path, skeleton_text(campaign_id, source=f"{n_files} .rtl files", **values))
    origin = " (start: the Date of the cold file)" if skeleton["start"] is None else ""
    return f"wrote the skeleton {path}{origin}; list the columns of temperature.csv in its sensors"

"""``thermal import logger``: a data logger's wide table -> raw campaign folders.

``thermal import logger TABLE --mapping MAPPING.yaml --out data/raw`` reads the table as the
mapping file says (:mod:`pipeline.importers.mapping`, :mod:`pipeline.importers.logger_table`),
cuts the record into campaigns by the rule of the mapping's ``cut:`` section or the flags
(:mod:`pipeline.importers.cutting`; flags win) and writes one spindle_drift folder per campaign
(:mod:`pipeline.importers.contract_writer`): ``<prefix><number>`` with ``campaign.yaml``,
``temperature.csv``, ``displacement.csv`` and ``spindle.csv``, ``elapsed_s`` counted from the
campaign's own first sample. Every campaign after the first says ``follows:`` the one before and
``start_state: warm`` (it continues the record without a break), unless the spindle had been
stopped for ``cold_after_stop_h`` before it: then it says ``start_state: cold`` and starts a new
run. The first campaign's ``start_state`` is the mapping's ``campaign: start_state:`` (not
written when absent). See docs/import-logger.md.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.importers.arguments import non_negative, positive
from pipeline.importers.contract_writer import SpindleDriftCampaign, write_campaign
from pipeline.importers.cutting import RULES, CutRule, segments
from pipeline.importers.logger_table import LoggerRecord, TableError, read_logger_table
from pipeline.importers.mapping import LoggerMapping, MappingError, load_mapping
from schemas.vocabulary import CAMPAIGN_ID_RE

logger = logging.getLogger(__name__)

PROG = "thermal import logger"


class OptionError(ValueError):
    """A command-line option (or its combination with the mapping) that cannot be used."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Convert a data logger's wide table (CSV or XLSX) into raw campaign folders "
        "(docs/data-contract.md), cut by a stated rule; see docs/import-logger.md.",
    )
    parser.add_argument("table", type=Path, help="the logger table (.csv, .txt, .xlsx)")
    parser.add_argument("--mapping", type=Path, required=True, help="mapping file (YAML)")
    parser.add_argument("--out", type=Path, required=True, help="raw directory, e.g. data/raw")
    parser.add_argument("--cut", choices=RULES, help="cut rule (default: mapping cut.rule)")
    parser.add_argument(
        "--min-stop-min",
        type=non_negative,
        help="shortest stop that counts, min (speed_cycles, stops)",
    )
    parser.add_argument("--window-h", type=positive, help="window length of the fixed rule, h")
    parser.add_argument(
        "--cold-after-stop-h",
        type=positive,
        help="a campaign after a stop this long (h) starts cold, a new run",
    )
    parser.add_argument("--id-prefix", help="campaign id prefix (default: mapping id_prefix)")
    parser.add_argument(
        "--force", action="store_true", help="overwrite existing campaign folders of the same ids"
    )
    return parser


def cut_rule(mapping: LoggerMapping, args: argparse.Namespace) -> CutRule:
    """Return the mapping's ``cut:`` rule with the command-line flags applied (flags win).

    Raises
    ------
    OptionError
        The ``fixed`` rule without a window.
    """
    flags = {
        "rule": args.cut,
        "min_stop_min": args.min_stop_min,
        "window_h": args.window_h,
        "cold_after_stop_h": args.cold_after_stop_h,
    }
    rule = replace(mapping.cut, **{k: v for k, v in flags.items() if v is not None})
    if rule.rule == "fixed" and rule.window_h is None:
        raise OptionError(
            f"the fixed cut rule needs a window length: write cut: window_h: N (hours) "
            f"in {mapping.path} or pass --window-h N"
        )
    if rule.rule == "stops" and rule.cold_after_stop_h is not None:
        raise OptionError(
            "cold_after_stop_h cannot be used with the stops rule: its campaigns begin with the "
            "stop, so none starts after one; use the speed_cycles rule (campaigns begin when the "
            f"spindle starts again) or remove cold_after_stop_h from {mapping.path} and the flags"
        )
    return rule


def id_prefix(mapping: LoggerMapping, flag: str | None) -> str:
    """Return ``--id-prefix``, else the mapping's ``campaign: id_prefix:``."""
    prefix = flag if flag is not None else mapping.campaign.id_prefix
    if prefix is None:
        raise OptionError(
            f"no campaign id prefix: write campaign: id_prefix: (e.g. L) in "
            f"{mapping.path} or pass --id-prefix L"
        )
    if not CAMPAIGN_ID_RE.match(prefix):
        raise OptionError(
            f"--id-prefix '{prefix}' has characters a campaign id cannot have; use "
            "letters, digits, '-' and '_' only"
        )
    return prefix


def build_campaigns(
    record: LoggerRecord, mapping: LoggerMapping, rule: CutRule, prefix: str, source_note: str
) -> list[SpindleDriftCampaign]:
    """Cut the record and describe every campaign in the contract.

    Parameters
    ----------
    record : LoggerRecord
    mapping : LoggerMapping
    rule : CutRule
    prefix : str
        Campaign ids are ``prefix`` and a number of at least two digits.
    source_note : str
        Where the data come from, written in each campaign.yaml's ``notes:``.

    Returns
    -------
    list of SpindleDriftCampaign
        In time order.
    """
    parts = segments(record.elapsed_s, record.rpm, rule)
    width = max(2, len(str(len(parts))))
    campaigns: list[SpindleDriftCampaign] = []
    for number, part in enumerate(parts, start=1):
        rows = slice(part.first, part.stop)
        elapsed_s = record.elapsed_s[rows] - record.elapsed_s[part.first]
        start = record.start + pd.Timedelta(seconds=float(record.elapsed_s[part.first]))
        if not campaigns:
            start_state, follows = mapping.campaign.start_state, None
        elif (
            rule.cold_after_stop_h is not None
            and part.stopped_before_s >= rule.cold_after_stop_h * 3600.0
        ):
            start_state, follows = "cold", None
        else:
            start_state, follows = "warm", campaigns[-1].campaign_id
        data_rows = record.data_rows[rows]
        metadata = {
            "machine": mapping.campaign.machine,
            "start": start.isoformat(),
            "season": mapping.campaign.season,
            "synthetic": mapping.campaign.synthetic,
            "split": mapping.campaign.split,
            "start_state": start_state,
            "follows": follows,
            "notes": f"{source_note}, data rows {data_rows[0]}-{data_rows[-1]}; "
            f"cut: {rule.describe()}",
            "sensors": {
                s.sensor: _present({"role": s.role, "location": s.location, "type": s.type})
                for s in mapping.sensors
            },
            "displacement": {
                p.axis: _present({"probe": p.probe, "location": p.location}) for p in mapping.probes
            },
        }
        campaigns.append(
            SpindleDriftCampaign(
                campaign_id=f"{prefix}{number:0{width}d}",
                metadata=metadata,
                temperature=_with_time(elapsed_s, record.temperatures.iloc[rows]),
                displacement=_with_time(elapsed_s, record.displacement.iloc[rows]),
                spindle=pd.DataFrame({"elapsed_s": elapsed_s, "rpm": record.rpm[rows]}),
            )
        )
    return campaigns


def _with_time(elapsed_s: np.ndarray, values: pd.DataFrame) -> pd.DataFrame:
    """Return ``values`` with ``elapsed_s`` (s) as first column and a fresh index."""
    return pd.concat(
        [pd.DataFrame({"elapsed_s": elapsed_s}), values.reset_index(drop=True)], axis=1
    )


def _present(entry: dict) -> dict:
    return {k: v for k, v in entry.items() if v is not None}


def _warn_empty_channels(campaign: SpindleDriftCampaign) -> None:
    """Log channels without any reading in a campaign (the validate stage quarantines it)."""
    empty = [
        c
        for t in (campaign.temperature, campaign.displacement)
        for c in t.columns[1:]
        if t[c].isna().all()
    ]
    if empty:
        logger.warning(
            "%s: %s have no reading in this campaign; the validate stage will "
            "quarantine it unless they are removed",
            campaign.campaign_id,
            empty,
        )


def import_logger(
    table: Path, mapping: LoggerMapping, rule: CutRule, prefix: str, out: Path, force: bool
) -> list[SpindleDriftCampaign]:
    """Read the table, cut it and write the campaign folders.

    Parameters
    ----------
    table : Path
        The logger table; only read.
    mapping : LoggerMapping
    rule : CutRule
    prefix : str
        Campaign id prefix.
    out : Path
        The raw directory.
    force : bool
        Overwrite existing campaign folders of the same ids.

    Returns
    -------
    list of SpindleDriftCampaign
        The campaigns written.

    Raises
    ------
    TableError
        The table cannot be read with the mapping.
    OptionError
        A campaign folder exists and ``force`` is False (nothing is written then).
    """
    record = read_logger_table(table, mapping)
    digest = hashlib.sha256(table.read_bytes()).hexdigest()
    note = f"imported by {PROG} from {table.name} (sha256 {digest[:16]})"
    campaigns = build_campaigns(record, mapping, rule, prefix, note)
    existing = [c.campaign_id for c in campaigns if (out / c.campaign_id).exists()]
    if existing and not force:
        raise OptionError(
            f"campaign folder(s) {existing} already exist in {out}; nothing was "
            "written. Choose another --id-prefix, or pass --force to overwrite "
            "them"
        )
    for campaign in campaigns:
        _warn_empty_channels(campaign)
        write_campaign(campaign, out, overwrite=force)
    written = {c.campaign_id for c in campaigns}
    stale = sorted(
        p.name
        for p in out.iterdir()
        if p.is_dir()
        and p.name not in written
        and p.name.startswith(prefix)
        and p.name[len(prefix) :].isdigit()
    )
    if stale:
        logger.warning(
            "%s also holds %s with the prefix '%s' (an earlier import?); delete them "
            "if they are not separate campaigns",
            out,
            stale,
            prefix,
        )
    return campaigns


def summary(table: Path, out: Path, rule: CutRule, campaigns: list[SpindleDriftCampaign]) -> str:
    """Return the lines printed after an import: the rule and each campaign's time span."""
    lines = [f"{PROG}: {table} -> {out}: {len(campaigns)} campaign(s), cut by {rule.describe()}"]
    for c in campaigns:
        start = pd.Timestamp(c.metadata["start"])
        length_s = float(c.temperature["elapsed_s"].iloc[-1])
        end = start + pd.Timedelta(seconds=length_s)
        link = f"follows {c.metadata['follows']}" if c.metadata["follows"] else "first of a run"
        state = c.metadata["start_state"] or "start state not given"
        lines.append(
            f"  {c.campaign_id}: {start:%Y-%m-%d %H:%M:%S} to {end:%Y-%m-%d %H:%M:%S} "
            f"({length_s / 3600.0:.2f} h, {len(c.temperature)} samples), {link}, "
            f"{state}"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run ``thermal import logger``; return 0, or 2 on a user error (message on stderr)."""
    args = _parser().parse_args(argv)
    try:
        mapping = load_mapping(args.mapping)
        rule = cut_rule(mapping, args)
        prefix = id_prefix(mapping, args.id_prefix)
        campaigns = import_logger(args.table, mapping, rule, prefix, args.out, args.force)
    except (MappingError, TableError, OptionError) as error:
        sys.stderr.write(f"{PROG}: {error}\n")
        return 2
    except OSError as error:  # e.g. --out is a file, or a folder cannot be written
        sys.stderr.write(f"{PROG}: {error}; check --out and the permissions there\n")
        return 2
    sys.stdout.write(summary(args.table, args.out, rule, campaigns))
    return 0

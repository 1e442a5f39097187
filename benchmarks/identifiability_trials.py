"""Calibrate the identifiability thresholds on the hidden-effect trials.

For each seed and case (nothing hidden, and each effect hidden alone), the trial campaigns of
:mod:`benchmarks.discrepancy_trials` (``write_hidden_campaigns``: 8 campaigns with speed steps
and a cool-down) go through the discrepancy workflow like measurements; every candidate effect's
identifiability class and figures (:mod:`pipeline.discrepancy.identifiability`) are recorded
with whether it was hidden and whether the search named it. The thresholds of ``params.yaml``
``discrepancy.identifiability`` are right when every effect the search names when it is hidden
lies above them (signal, and collinearity below its limit) and the hidden effects it does not
name lie below: ``thresholds.md`` gives, per effect, the range of each figure on the trials
where it was hidden and named, hidden and not named, and not hidden (nothing hidden); and counts
the trials where the thresholds put a hidden effect on the wrong side.

``python -m benchmarks.identifiability_trials --seeds 1 2 3 --out reports/identifiability_trials``
(about 25 min on 2 cores) writes ``figures.csv`` (one row per trial and candidate) and
``thresholds.md``. With ``--quick`` only the baseline is calibrated (no search; ``named`` is left
empty): the figures in a few minutes, to read against the search's outcomes of ``make trials``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from benchmarks.discrepancy_trials import run_workflow, write_hidden_campaigns
from pipeline.config import DEFAULT_PARAMS
from pipeline.discrepancy.calibrate import calibrate
from pipeline.discrepancy.identifiability import IdentifiabilitySettings, assess_effects
from pipeline.discrepancy.model import build_model
from pipeline.discrepancy.search import (
    CANDIDATE_EFFECTS,
    SearchSettings,
    campaign_roles,
    split_for_search,
    untestable_effects,
)
from pipeline.discrepancy.visibility import baseline_point
from pipeline.discrepancy.workflow import read_raw
from pipeline.settings.base import load_settings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.validate import ValidateSettings

logger = logging.getLogger(__name__)

SINGLE_CASES: tuple[frozenset, ...] = (frozenset(), *(frozenset({e}) for e in CANDIDATE_EFFECTS))
"""Nothing hidden, then each effect hidden alone."""

FIGURES = ("signal_sigma", "signal_Z_um", "signal_T_K", "collinearity_index")
"""Figures of an identifiability entry recorded per trial."""


def baseline_document(
    raw: Path, section: DiscrepancySettings, params_file: Path = DEFAULT_PARAMS
) -> dict:
    """Return the ``identifiability`` of a raw folder at its calibrated baseline, no search.

    The baseline twin is calibrated on the campaigns the search would use, as its first fit;
    the document has ``named_effects`` None (not searched) and ``identifiability``.
    """
    gap = load_settings(IngestSettings, "ingest", params_file).max_alignment_gap_s
    limits = load_settings(ValidateSettings, "validate", params_file).limits()
    campaigns, _, _ = read_raw(raw, gap, limits)
    settings = SearchSettings.from_settings(section)
    searched, _ = split_for_search(campaigns, settings)
    roles = campaign_roles(campaigns)
    fit = calibrate(build_model(roles), searched)
    ident = IdentifiabilitySettings.from_settings(section.identifiability)
    values = {k: v for k, (v, _) in fit.params.items()}
    point = baseline_point(searched, values, roles, prior_log_sd=ident.prior_log_sd)
    untestable = untestable_effects(settings.candidates, roles)
    classes = assess_effects(point, settings.candidates, [], untestable, ident)
    return {
        "named_effects": None,
        "identifiability": {e: c.to_dict(ident) for e, c in classes.items()},
    }


def trial_rows(doc: dict, hidden: frozenset, seed: int) -> list[dict]:
    """Return one row per candidate effect of a trial's ``discrepancy.json``.

    Columns: ``seed``, ``hidden`` (the case), ``effect``, ``is_hidden``, ``named``, ``class``,
    ``identifiable`` (the figures meet both thresholds, whatever the class) and :data:`FIGURES`
    (None for an untestable effect).
    """
    case = "+".join(sorted(hidden)) or "none"
    rows = []
    for effect, entry in doc["identifiability"].items():
        rows.append(
            {
                "seed": seed,
                "hidden": case,
                "effect": effect,
                "is_hidden": effect in hidden,
                "named": None if doc["named_effects"] is None else effect in doc["named_effects"],
                "class": entry["class"],
                "identifiable": not entry.get("shortfalls", ["untestable"]),
                **{name: entry.get(name) for name in FIGURES},
            }
        )
    return rows


def _group(row: pd.Series) -> str:
    """Return the group of a row: hidden and named, hidden and not named, or not hidden."""
    if not row["is_hidden"]:
        return "not hidden (nothing hidden)"
    if pd.isna(row["named"]):
        return "hidden"
    return "hidden, named" if row["named"] else "hidden, not named"


def _span(values: pd.Series, digits: int) -> str:
    """Return ``min - max`` of the values, or ``n/a``."""
    values = values.dropna()
    if values.empty:
        return "n/a"
    return f"{values.min():.{digits}f} - {values.max():.{digits}f}"


def misplaced(figures: pd.DataFrame) -> pd.DataFrame:
    """Return the hidden effects the thresholds put on the wrong side of the search's outcome.

    Named when hidden although its figures miss a threshold: a false alarm of invisibility;
    hidden, not named and identifiable by its figures (``not_needed``): an effect called absent
    that the campaigns should have shown. Trials without a search (``named`` empty) are left
    out.
    """
    hidden = figures[figures["is_hidden"] & figures["named"].notna()]
    named = hidden["named"].astype(bool)
    identifiable = hidden["identifiable"].astype(bool)
    return hidden[(named & ~identifiable) | (~named & identifiable)]


def thresholds_markdown(figures: pd.DataFrame, thresholds: dict, seeds: Sequence[int]) -> str:
    """Return the per-effect ranges of the figures by group, and the misplaced trials."""
    figures = figures.assign(group=figures.apply(_group, axis=1))
    clean = figures[(figures["hidden"] == "none") | figures["is_hidden"]]
    lines = [
        "# Identifiability figures on the hidden-effect trials",
        "",
        f"Seeds {', '.join(map(str, seeds))}; thresholds: signal >= "
        f"{thresholds['min_signal_sigma']:g} sigma and collinearity index <= "
        f"{thresholds['max_collinearity_index']:g}. Figures: min - max over the trials of the "
        "group (signal RMS beyond what the baseline absorbs, at the plausible size).",
        "",
        "| effect | group | trials | signal (sigma) | Z (um) | T (K) | collinearity index "
        "| classes |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (effect, group), g in clean.groupby(["effect", "group"], sort=False):
        classes = ", ".join(f"{k} {v}" for k, v in g["class"].value_counts().items())
        lines.append(
            f"| {effect} | {group} | {len(g)} | {_span(g['signal_sigma'], 2)} | "
            f"{_span(g['signal_Z_um'], 3)} | {_span(g['signal_T_K'], 4)} | "
            f"{_span(g['collinearity_index'], 1)} | {classes} |"
        )
    wrong = misplaced(figures)
    lines += ["", f"Hidden effects on the wrong side of the thresholds: {len(wrong)}."]
    lines += [
        f"- seed {r['seed']}, {r['effect']} hidden: named {r['named']}, identifiable "
        f"{r['identifiable']}, "
        f"signal {r['signal_sigma']} sigma, collinearity index {r['collinearity_index']}"
        for _, r in wrong.iterrows()
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.identifiability_trials``: run the cases; write the figures."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.identifiability_trials", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--out", type=Path, default=Path("reports/identifiability_trials"))
    parser.add_argument("--campaigns", type=int, default=8, help="campaigns per trial")
    parser.add_argument("--params", type=Path, default=DEFAULT_PARAMS)
    parser.add_argument("--quick", action="store_true", help="calibrate the baseline only")
    args = parser.parse_args(argv)
    section = load_settings(DiscrepancySettings, "discrepancy", args.params)
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    for seed in args.seeds:
        for case in SINGLE_CASES:
            with tempfile.TemporaryDirectory() as tmp:
                raw = Path(tmp) / "raw"
                write_hidden_campaigns(raw, case, seed, args.campaigns)
                if args.quick:
                    doc = baseline_document(raw, section, args.params)
                else:
                    doc = run_workflow(raw, Path(tmp) / "out", section, args.params)
            rows += trial_rows(doc, case, seed)
            pd.DataFrame(rows).to_csv(args.out / "figures.csv", index=False)
            logger.info("seed %d, hidden %s: named %s", seed, sorted(case), doc["named_effects"])
    thresholds = next(iter(doc["identifiability"].values()))["thresholds"]
    text = thresholds_markdown(pd.DataFrame(rows), thresholds, args.seeds)
    (args.out / "thresholds.md").write_text(text, encoding="utf-8")
    logger.info("figures written to %s", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The engineer's report, ``discrepancy.md``, written from the ``discrepancy.json`` document.

One function per section of the report, each returning its Markdown lines: where the baseline
twin disagrees with the measurements, which effects the search named with what evidence, the
check on the validation campaigns, what remains, the evidence of every candidate, whether the
campaigns can show each effect at all (its identifiability class) and the effects the data cannot
test (:func:`markdown`); and the short report of campaigns the twin cannot be
compared with (:func:`untestable_markdown`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.discrepancy.followup import signed_percent
from pipeline.discrepancy.model import REFERENCE_RPM

TITLE = "# Where the twin and the measurements disagree"
"""First line of both reports."""

EFFECT_WORDS = {
    "ambient_variation": "the workshop air temperature varies and the structure follows it",
    "centrifugal_growth": "the spindle nose shifts instantly with speed squared (centrifugal)",
    "nonlinear_bearing_heat": "bearing friction heat grows faster than linearly with speed",
    "sensor_lag": "the sensors read their locations through a first-order lag",
    "thermal_bending": "the column bends when its front and rear differ in temperature",
    "motor_heat": "the spindle motor heats the headstock",
}
"""One line per effect, for the report."""

WHY_Z_STAYS = {
    "sensor_lag": "a lag changes what the sensors read, not the structure, so it cannot move "
    "the displacement; the refit it brings only re-balances the twin's Z laws",
    "motor_heat": "the motor's heat reaches the displacement through the headstock, whose "
    "sensor the baseline already follows, so the twin's Z prediction hardly changes",
}
"""Why an effect named on the temperatures leaves the displacement gap as it was."""
WHY_Z_STAYS_OTHERWISE = (
    "the effect explains the readings, while what is left of the displacement residual is not its "
    "signature"
)


def _source(doc: Mapping[str, Any]) -> str:
    """Return what the campaigns are: synthetic or measured."""
    return "synthetic campaigns (not measurements)" if doc["synthetic"] else "measured campaigns"


def untestable_markdown(doc: Mapping[str, Any]) -> str:
    """Write the engineer's report when the twin cannot be compared with the campaigns."""
    source = _source(doc)
    quarantined = (
        f" Quarantined and left out: {', '.join(doc['quarantined'])}." if doc["quarantined"] else ""
    )
    lines = [
        TITLE,
        "",
        f"**Untestable on these campaigns.** {doc['reason'][:1].upper()}{doc['reason'][1:]}.",
        "",
        f"Data: {len(doc['campaigns'])} spindle campaign(s) with a Z displacement, {source}; "
        f"sensor roles present: {', '.join(doc['roles_present']) or 'none'}.{quarantined}",
        "",
        "The physical twin is a thermal network whose nodes are the places of the sensors "
        "(`campaign.yaml` `sensors: <name>: {role: ...}`). Roles it can use: "
        + ", ".join(f"`{r}`" for r in doc["needed_roles"])
        + "; `ambient` drives it. Nothing was calibrated or named, and the `twin` candidate of "
        "the model comparison is skipped for this reason. The rest of the pipeline (the "
        "regression models, their scores and the champion) does not need the roles.",
        "",
    ]
    return "\n".join(lines)


def _fmt(x: float | None, digits: int = 2) -> str:
    """Return ``x`` with ``digits`` decimals, or ``n/a`` when missing or not finite."""
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def _pct(x: float | None) -> str:
    """Return the fraction ``x`` as a whole percentage, or ``n/a`` when missing or not finite."""
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:.0f} %"


def _motor_rise(params: Mapping[str, Any]) -> float | None:
    """Steady rise of the motor node per 1000 rpm at the reference speed, K (None if n/a)."""
    names = ("q_motor_W_per_krpm", "h_motor_W_per_K", "G_motor_headstock_W_per_K")
    values = [(params.get(n) or {}).get("value") for n in names]
    if any(v is None for v in values):
        return None
    q, h, g = values
    return q / (h + g)


def _per_campaign_table(label: str, per_campaign: Mapping[str, Any]) -> list[str]:
    """Markdown rows: Z (um) and temperature (K) RMS before and after, one row per campaign."""
    lines = [
        f"| {label} | Z before (um) | Z after (um) | T before (K) | T after (K) |",
        "|---|---:|---:|---:|---:|",
    ]
    for cid, row in per_campaign.items():
        b, a = row["before"], row["after"]
        lines.append(
            f"| {cid} | {_fmt(b.get('z_um'))} | {_fmt(a.get('z_um'))} | "
            f"{_fmt(b.get('t_k'))} | {_fmt(a.get('t_k'))} |"
        )
    return lines


def _section(title: str, body: list[str]) -> list[str]:
    """Return a Markdown section: a blank line, the ``## title`` heading, a blank line, body."""
    return ["", f"## {title}", "", *body]


def _twin_plus(named: Sequence[str], otherwise: str) -> str:
    """Return "the twin + <named effects>", or ``otherwise`` when nothing is named."""
    return f"the twin + {', '.join(named)}" if named else otherwise


def _intro_lines(doc: Mapping[str, Any]) -> list[str]:
    """Return the title and what the data and the held-out residual are."""
    source = _source(doc)
    quarantined = (
        f"; quarantined and left out: {', '.join(doc['quarantined'])}" if doc["quarantined"] else ""
    )
    validation = (
        f"; the {len(doc['validation']['campaigns'])} validation campaigns are held back "
        "from the search and used only for the check below."
        if doc.get("validation")
        else "."
    )
    return [
        TITLE,
        "",
        f"Data: {len(doc['campaigns'])} spindle campaigns, {source}{quarantined}.",
        f"Held-out = displacement residual on campaigns not used for calibration "
        f"({len(doc['folds'])}-fold cross-validation across the "
        f"{sum(len(f) for f in doc['folds'])} searched campaigns){validation}",
    ]


def _temperature_only_line(step: Mapping[str, Any], min_z_reduction: float) -> list[str]:
    """Return the line saying that an effect named on the temperatures left the Z gap open."""
    ev = step["evidence"]
    on_test = ev.get("passes_on_test", False)
    reduction = ev["heldout_reduction_on_test"] if on_test else ev["heldout_reduction"]
    if reduction is None or reduction >= min_z_reduction or ev.get("passes_on_signature"):
        return []
    why = WHY_Z_STAYS.get(step["effect"], WHY_Z_STAYS_OTHERWISE)
    return [
        f"  - named on the temperatures alone: the held-out Z residual changed by "
        f"{signed_percent(-reduction)}, short of the -{_pct(min_z_reduction)} that names an effect "
        f"on the displacement, so **the displacement gap did not shrink** with it: {why}"
    ]


MOVED_PARAMETERS = 3
"""Twin parameters a report names as moved most by an effect whose Z gap rose."""


def _moved_parameters(before: Mapping[str, Any], after: Mapping[str, Any]) -> str:
    """Return the twin parameters that moved most between two calibrations, in words.

    Parameters
    ----------
    before, after : mapping
        Parameter name -> ``{"value", "unit"}``, before and after the effect was added; the
        parameters of ``after`` only (the effect's own) are left out.

    The move is the factor between the two values (the calibration works on log-parameters);
    values are given to three significant figures.
    """
    shared = [k for k in after if k in before and before[k]["value"] > 0 and after[k]["value"] > 0]
    factor = {k: abs(np.log(after[k]["value"] / before[k]["value"])) for k in shared}
    moved = sorted(factor, key=factor.get, reverse=True)[:MOVED_PARAMETERS]
    return ", ".join(
        f"{k} {before[k]['value']:.3g} -> {after[k]['value']:.3g} {after[k]['unit']}" for k in moved
    )


def _signature_lines(
    step: Mapping[str, Any], previous: Mapping[str, Any], min_z_reduction: float
) -> list[str]:
    """Return the lines of an effect named on its own signature, and of a Z gap that rose.

    ``previous``: the parameters of the model the effect was added to (name -> value, unit).
    When the held-out Z residual rose with the effect, say so, where it rose and which of the
    twin's other parameters its calibration moved most: the effect's own structure is measured,
    and the rise is the rest of the twin meeting the data without the misfit the missing
    effect used to hide.
    """
    ev = step["evidence"]
    reduction = ev["heldout_reduction"]
    lines = [f"  - named on its own signature: {ev['signature']}."]
    if reduction >= 0.0:
        lines[0] += (
            f" Its held-out Z fall, {_pct(reduction)}, is short of the {_pct(min_z_reduction)} "
            "that names an effect on the whole residual: the rest of the gap is a misfit it does "
            "not remove"
        )
        return lines
    before, after = step["per_campaign_before"], step["per_campaign_after"]
    rose = [c for c in after if c in before and after[c]["z_um"] > before[c]["z_um"]]
    where = ", ".join(f"{c} {_fmt(before[c]['z_um'])} -> {_fmt(after[c]['z_um'])} um" for c in rose)
    lines.append(
        f"  - **the displacement gap did not shrink**: with it the held-out Z residual rose by "
        f"{_pct(-reduction)}, on {len(rose)} of {len(after)} campaigns ({where}). "
        "Calibrated with it, the twin's other laws moved most in "
        f"{_moved_parameters(previous, step['parameters'])}: without the effect they likely "
        "stood in for it, and with it they meet a misfit of the twin's own structure (a part or "
        "law the machine does not share) that the stand-in hid. The effect is named for its "
        "signature; as a predictor of these campaigns the twin with it is worse than without"
    )
    return lines


def _step_lines(
    step: Mapping[str, Any], previous: Mapping[str, Any], min_z_reduction: float
) -> list[str]:
    """Return the bullet of one named effect: its evidence and its calibrated parameters.

    ``previous`` is the calibrated parameters of the model the effect was added to (name ->
    value and unit); ``min_z_reduction`` the relative fall of the held-out Z residual that
    names an effect on the displacement (``params.yaml`` ``discrepancy.min_heldout_reduction``).
    """
    ev = step["evidence"]
    change = "reduces" if ev["heldout_reduction"] >= 0.0 else "raises"
    lines = [
        f"- adding `{step['effect']}` ({EFFECT_WORDS.get(step['effect'], '')}) {change} the "
        f"held-out Z residual from {_fmt(step['rmse_um_before'])} um to "
        f"{_fmt(step['rmse_um_after'])} um RMS ({_pct(abs(ev['heldout_reduction']))}), "
        f"temperatures from {_fmt(step['rmse_T_K_before'])} K to "
        f"{_fmt(step['rmse_T_K_after'])} K; BIC changes by {_fmt(ev['delta_bic'], 1)}."
    ]
    if ev.get("passes_on_test"):
        lines.append(
            "  - named on the campaigns of the test proposed for it: on them its held-out Z "
            f"residual changed by {signed_percent(-ev['heldout_reduction_on_test'])} and the "
            f"temperatures by {signed_percent(-ev['heldout_T_reduction_on_test'])}; the earlier "
            "campaigns could not show it, and pooled over all it does not raise the residual"
        )
    if ev.get("passes_on_signature"):
        lines += _signature_lines(step, previous, min_z_reduction)
    lines += _temperature_only_line(step, min_z_reduction)
    own = step["effect_parameters"]
    shown = ", ".join(f"{k} = {_fmt(v['value'], 4)} {v['unit']}" for k, v in own.items())
    shown = shown or "none (it uses the measured signals)"
    lines.append(f"  - its own calibrated parameters: {shown} (all parameters in discrepancy.json)")
    rise = _motor_rise(step["parameters"]) if step["effect"] == "motor_heat" else None
    if rise is not None:
        lines.append(
            "  - read the motor loss together with the node's cooling: the temperatures "
            "fix the motor node's steady rise over its surroundings, q / (h + G) = "
            f"{_fmt(rise, 3)} K per 1000 rpm at {REFERENCE_RPM:.0f} rpm, and its time "
            "constant, not q, h and its heat capacity one by one (they scale together while "
            "its link to the headstock is weak)"
        )
    return lines


PROXY_OVERLAP = 0.9
"""Overlap (|cos| of the visible parts) from which a named effect may stand in for another."""


def _proxy_line(effect: str, entries: Mapping[str, Any]) -> list[str]:
    """Return the line saying which other candidate a named effect's evidence is closest to."""
    overlaps = {
        other: value
        for other, value in ((entries.get(effect) or {}).get("overlaps") or {}).items()
        if value is not None
    }
    if not overlaps:
        return []
    other = max(overlaps, key=overlaps.get)
    value = overlaps[other]
    verdict = (
        f"it may stand in for `{other}`: the data cannot tell the two apart, and a test that "
        "loads them differently is needed before the name can be trusted"
        if value >= PROXY_OVERLAP
        else "its signature is its own"
    )
    return [
        f"  - a proxy for another candidate? what the baseline cannot absorb of it overlaps "
        f"that of `{other}` by {value:.2f} (|cos|, the most of any other candidate; 1 = "
        f"indistinguishable, from {PROXY_OVERLAP}: a possible proxy): {verdict}"
    ]


def _suspect_lines(suspects: Sequence[Mapping[str, str]]) -> list[str]:
    """Return the effects that passed the search's rule but were held back, with why."""
    if not suspects:
        return []
    return [
        "",
        "**Suspects**, held back though they pass the search's rule (not in the twin):",
        "",
        *(f"- `{s['effect']}`: {s['reason']}." for s in suspects),
    ]


def _no_longer_named_lines(dropped: Sequence[Mapping[str, str]]) -> list[str]:
    """Return the effects the earlier run named that this run does not, with why."""
    if not dropped:
        return []
    return [
        "",
        "**No longer named** (named by the earlier run, before the new campaigns; not in the "
        "twin now):",
        "",
        *(f"- `{d['effect']}`: {d['reason']}." for d in dropped),
    ]


def _missing_lines(doc: Mapping[str, Any]) -> list[str]:
    """Return the named effects with their evidence, the overall and per-campaign RMS."""
    named = doc["named_effects"]
    if named:
        lines = [
            f"The search names **{len(named)}** effect(s), in order: "
            + ", ".join(f"`{e}`" for e in named)
            + ".",
            "",
        ]
        previous = doc["baseline_parameters"]
        for step in doc["steps"]:
            lines += _step_lines(step, previous, doc["thresholds"]["min_heldout_reduction"])
            previous = step["parameters"]
            lines += _proxy_line(step["effect"], doc.get("identifiability") or {})
    else:
        lines = [
            "No candidate effect passes the thresholds: the baseline twin explains the data "
            "within what the cross-validation can tell apart. Nothing is named."
        ]
    return [
        *lines,
        *_suspect_lines(doc.get("suspects") or []),
        *_no_longer_named_lines(doc.get("no_longer_named") or []),
        "",
        f"Overall held-out Z residual: **{_fmt(doc['rmse_um_before'])} um** with the baseline, "
        f"**{_fmt(doc['rmse_um_after'])} um** with {_twin_plus(named, 'no effect added')}; "
        f"temperatures {_fmt(doc['rmse_T_K_before'])} K -> {_fmt(doc['rmse_T_K_after'])} K.",
        "",
        *_per_campaign_table("campaign", doc["per_campaign"]),
    ]


def _validation_lines(doc: Mapping[str, Any]) -> list[str]:
    """Return the check on the validation campaigns, with one row per campaign."""
    val = doc["validation"]
    return [
        f"Calibrated on all {sum(len(f) for f in doc['folds'])} searched campaigns, the "
        f"baseline twin predicts the validation campaigns ({', '.join(val['campaigns'])}), "
        "which no step of the search has seen, with a Z residual of "
        f"**{_fmt(val['rmse_um_before'])} um** RMS and temperatures "
        f"{_fmt(val['rmse_T_K_before'])} K; "
        f"{_twin_plus(doc['named_effects'], 'with nothing added it is the same')}: "
        f"**{_fmt(val['rmse_um_after'])} um**, {_fmt(val['rmse_T_K_after'])} K.",
        "",
        *_per_campaign_table("validation campaign", val["per_campaign"]),
    ]


def _candidate_table(entry: Mapping[str, Any]) -> list[str]:
    """Return the evidence of every candidate of one search step, as a Markdown table."""
    lines = [
        "",
        f"Step {entry['step']}:",
        "",
        "| effect | held-out Z RMS (um) | Z reduction | held-out T RMS (K) | T reduction "
        "| delta BIC | delta AICc | passes |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for c in entry["candidates"]:
        lines.append(
            f"| `{c['effect']}` | {_fmt(c['rmse_heldout_um'])} | "
            f"{_pct(c['heldout_reduction'])} | {_fmt(c['rmse_heldout_T_K'], 3)} | "
            f"{_pct(c['heldout_T_reduction'])} | "
            f"{_fmt(c['delta_bic'], 1)} | {_fmt(c['delta_aicc'], 1)} | "
            f"{_passes_cell(c)} |"
        )
    return lines


def _passes_cell(candidate: Mapping[str, Any]) -> str:
    """Return the *passes* cell: yes, yes on its test's campaigns or on its own signature, or no."""
    if candidate.get("passes_on_test"):
        return "yes, on its test's campaigns"
    if candidate.get("passes_on_signature"):
        return "yes, on its own signature"
    return "yes" if candidate["passes"] else "no"


def _evidence_lines(doc: Mapping[str, Any]) -> list[str]:
    """Return the naming rule and the evidence of every candidate at every step."""
    thresholds = doc["thresholds"]
    lines = [
        f"An effect is named when it reduces the held-out Z RMS by at least "
        f"{100 * thresholds['min_heldout_reduction']:.0f} % or the held-out temperature "
        f"RMS by at least {100 * thresholds['min_heldout_temperature_reduction']:.0f} %, "
        f"and changes BIC by at most {thresholds['max_delta_bic']:g}; the candidate with "
        "the lowest BIC among those is added and the search repeats. After a proposed test, "
        "the effect it was proposed for may reach the threshold on the test's campaigns "
        "alone, when the RMS pooled over all campaigns does not rise. An effect whose own "
        "signature is measured and removed (centrifugal growth: steps of the displacement at "
        "the speed changes that stay while the speed stays) is named on it; when its "
        "held-out Z RMS rises, its step above says so."
    ]
    for entry in doc["candidates_by_step"]:
        lines += _candidate_table(entry)
    return lines


def _size(values: Mapping[str, Any]) -> str:
    """Return the plausible size of an effect in words: its parameters, or switched on."""
    shown = [
        f"{name} = {v['value']:g}" + (f" {v['unit']}" if v["unit"] != "1" else "")
        for name, v in values.items()
    ]
    return f"at {', '.join(shown)}" if shown else "switched on"


def _beyond(entry: Mapping[str, Any]) -> str:
    """Return the visible signal of an effect in words, with its threshold and its parts."""
    limit = entry["thresholds"]["min_signal_sigma"]
    return (
        f"{_size(entry['plausible_values'])}, its effect on Z and temperatures beyond what the "
        f"baseline absorbs is {_fmt(entry['signal_sigma'], 1)} sigma (threshold {limit:g}): "
        f"{_fmt(entry['signal_Z_um'], 3)} um on Z and {_fmt(entry['signal_T_K'], 3)} K on the "
        f"temperatures, of {_fmt(entry['response_Z_um'], 3)} um and "
        f"{_fmt(entry['response_T_K'], 3)} K before the baseline absorbs a part"
    )


def _collinear(entry: Mapping[str, Any]) -> str:
    """Return the collinearity index of an effect in words, with its threshold."""
    return (
        f"collinearity index with the baseline {_fmt(entry['collinearity_index'], 1)} "
        f"(threshold {entry['thresholds']['max_collinearity_index']:g})"
    )


def _identifiability_line(effect: str, entry: Mapping[str, Any]) -> str:
    """Return the bullet of one candidate effect: its class, in words, and the numbers."""
    status = entry["class"]
    if status == "untestable":
        return (
            f"- `{effect}`: untestable: no sensor with role {' / '.join(entry['missing_roles'])}."
        )
    if status == "not_identifiable":
        reasons = []
        if "signal" in entry["shortfalls"]:
            reasons.append(_beyond(entry))
        if "collinearity" in entry["shortfalls"]:
            reasons.append(f"the baseline's parameters mimic it: {_collinear(entry)}")
        if "held_out" in entry["shortfalls"]:
            reasons.append(f"{entry['unconfirmed']} ({_beyond(entry)})")
        line = (
            f"- `{effect}`: **not identifiable with these campaigns**: {'; and '.join(reasons)}. "
            "Not naming it does not mean it is absent."
        )
        if entry.get("proposed_test"):
            line += f"\n\n  *Proposed test.* {entry['proposed_test']['text']}\n"
        return line
    verdict = {
        "named": "named",
        "not_needed": "tested and not needed: these campaigns would show it and the search "
        "did not name it",
    }[status]
    line = f"- `{effect}`: {verdict}; {_beyond(entry)}; {_collinear(entry)}."
    if entry["shortfalls"]:
        line += (
            " Near the baseline's calibration the baseline absorbs it; the search saw it once "
            "the twin was recalibrated with it."
        )
    return line


def _identifiability_lines(entries: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Return what the campaigns can show of each candidate, one bullet per effect."""
    tested = [e for e in entries.values() if "shortfalls" in e]
    rule = (
        f" below {tested[0]['thresholds']['min_signal_sigma']:g} sigma or above collinearity "
        f"index {tested[0]['thresholds']['max_collinearity_index']:g}"
        if tested
        else ""
    )
    return [
        "What the searched campaigns would show of each effect at a plausible size, beyond what "
        "the calibrated baseline absorbs by moving its own parameters (RMS over the measured "
        "samples, in noise sigmas, um and K), and how collinear its sensitivities are with the "
        f"baseline's (Brun et al. 2001). An effect{rule} is not identifiable with these "
        "campaigns: the search cannot name it even if it is there; so is an effect with no "
        "parameter of its own (the measured air) that the calibration on all campaigns prefers "
        "and the held-out campaigns do not confirm.",
        "",
        *(_identifiability_line(effect, entry) for effect, entry in entries.items()),
    ]


def _untestable_lines(untestable: Mapping[str, Sequence[str]]) -> list[str]:
    """Return one bullet per effect that lacks a sensor role (effect -> roles it needs)."""
    return [
        f"- `{effect}`: no sensor with role {' / '.join(roles)}; map one in campaign.yaml "
        "to test it."
        for effect, roles in untestable.items()
    ]


def markdown(doc: Mapping[str, Any], figures: Sequence[str]) -> str:
    """Write the engineer's report (``discrepancy.md``) from the JSON document."""
    findings = doc["localisation"]
    lines = _intro_lines(doc)
    lines += _section(
        "What the baseline twin misses", [f"- {f}" for f in findings["before"]["findings"]]
    )
    lines += _section("What is missing", _missing_lines(doc))
    if doc.get("validation"):
        lines += _section("Check on the validation campaigns", _validation_lines(doc))
    if "after" in findings and doc["named_effects"]:
        lines += _section(
            "What remains after adding the named effects",
            [f"- {f}" for f in findings["after"]["findings"]],
        )
    lines += _section("Evidence of every candidate", _evidence_lines(doc))
    if doc.get("identifiability"):
        lines += _section(
            "Can these campaigns show each effect?", _identifiability_lines(doc["identifiability"])
        )
    if doc["untestable"]:
        lines += _section(
            "Effects that cannot be tested on these data", _untestable_lines(doc["untestable"])
        )
    if figures:
        lines += _section("Figures", [f"![{Path(f).stem}]({Path(f).name})" for f in figures])
    return "\n".join(lines) + "\n"

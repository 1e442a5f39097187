"""The promotion gate: a new champion replaces the registered one only when it proves better.

After a retraining, each axis has a *challenger* (the champion ``evaluate`` just chose, fitted
on every training campaign) and, unless this is the first run, a *current* champion: the
registered model the machine runs. Both are scored on the campaigns the current one was **not
trained on** (its version's ``trained_on``), on the same samples, against no compensation:

- the current champion as it is registered: its prediction of each new campaign, run from the
  cold start of the campaign's record as a machine runs it;
- the challenger by its **held-out** prediction of the same campaign: the fit of the ranking
  scheme that did not see that campaign (the rolling origin's forecast of it, or the fit on all
  training campaigns for a validation campaign; :func:`pipeline.protocol.evaluation.heldout_table`).
  Scoring the challenger's final fit there instead would score it on campaigns it was trained
  on, and a gate that compares a fit with a forecast always promotes.

The challenger is promoted when its mean RMS over the new campaigns is at least ``margin``
below the current one's **and** below no compensation's (a ``none`` challenger -- do not
compensate -- needs only the first: it is promoted when the current champion does worse than
no compensation by the margin). Otherwise the alias stays and the reason says why. On the
first run (no current champion) the challenger is promoted: ``evaluate`` has already held it to
beating no compensation on the ranking score, or chosen ``none``. This is a champion-challenger
comparison on a common holdout, the practice of model monitoring (e.g. Sculley et al. 2015,
"Hidden technical debt in machine learning systems", NeurIPS), with the held-out rule of the
cross-campaign protocol.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from pipeline.fit_statistics import root_mean_square

PROMOTE, KEEP, ERROR = "promote", "keep", "error"


@dataclass(frozen=True)
class CampaignComparison:
    """Both champions and no compensation on one campaign, on the samples all three cover.

    Attributes
    ----------
    campaign_id : str
    n_samples : int
    current_rms_um, challenger_rms_um, none_rms_um : float, um
        RMS of measured - predicted (none: of the measured error itself).
    """

    campaign_id: str
    n_samples: int
    current_rms_um: float
    challenger_rms_um: float
    none_rms_um: float


@dataclass(frozen=True)
class GateDecision:
    """One axis' promotion decision.

    Attributes
    ----------
    axis : str
    action : str
        ``promote``, ``keep`` or ``error``.
    reason : str
        Why, in one or two sentences.
    current_version, challenger_version : str or None
        Registered versions (None: no current champion, or none registered).
    current_label, challenger_label : str
        ``model/selection/mode`` of each.
    margin : float
        The required fraction less RMS.
    campaigns : list of CampaignComparison
        The new campaigns scored.
    unscored : dict of str to str
        New campaigns that could not be compared -> why.
    machine : str
        The machine the axis is of (``""``: not given).
    """

    axis: str
    action: str
    reason: str
    current_version: str | None
    challenger_version: str | None
    current_label: str = ""
    challenger_label: str = ""
    margin: float = 0.0
    campaigns: list[CampaignComparison] = field(default_factory=list)
    unscored: dict[str, str] = field(default_factory=dict)
    machine: str = ""

    @property
    def name(self) -> str:
        """``machine axis`` (the axis alone when the machine is not given)."""
        return f"{self.machine} {self.axis}".strip()

    @property
    def promoted(self) -> bool:
        """Whether the challenger became the champion."""
        return self.action == PROMOTE

    def means(self) -> dict[str, float]:
        """Mean RMS over the compared campaigns (um): ``current``, ``challenger``, ``none``."""
        return mean_rms(self.campaigns)

    @classmethod
    def from_dict(cls, record: dict) -> GateDecision:
        """Rebuild a decision from :meth:`to_dict`'s record."""
        fields = {k: v for k, v in record.items() if k in cls.__dataclass_fields__}
        fields["campaigns"] = [
            CampaignComparison(**{k: math.nan if v is None else v for k, v in c.items()})
            for c in record.get("campaigns") or []
        ]
        return cls(**fields)

    def to_dict(self) -> dict:
        """JSON-ready record (NaN as None)."""
        record = asdict(self)
        record["means_um"] = {k: _finite(v) for k, v in self.means().items()}
        record["campaigns"] = [
            {k: _finite(v) if isinstance(v, float) else v for k, v in asdict(c).items()}
            for c in self.campaigns
        ]
        return record


def mean_rms(comparisons: list[CampaignComparison]) -> dict[str, float]:
    """Mean RMS over campaigns (um): ``current``, ``challenger``, ``none``; NaN without any."""
    return {
        key: float(np.mean([getattr(c, f"{key}_rms_um") for c in comparisons]))
        if comparisons
        else math.nan
        for key in ("current", "challenger", "none")
    }


def _finite(value: float) -> float | None:
    return None if not math.isfinite(value) else round(float(value), 4)


def compare_campaigns(
    current: pd.DataFrame, challenger: pd.DataFrame, campaigns: list[str]
) -> tuple[list[CampaignComparison], dict[str, str]]:
    """Score both champions and no compensation on each new campaign, on common samples.

    Parameters
    ----------
    current : DataFrame
        ``campaign_id``, ``elapsed_s`` (s), ``measured_um``, ``predicted_um``: the registered
        champion's prediction.
    challenger : DataFrame
        The same columns: the challenger's held-out prediction.
    campaigns : list of str
        The campaigns the current champion was not trained on.

    Returns
    -------
    comparisons : list of CampaignComparison
    unscored : dict of str to str
        Campaigns left out and why (no held-out prediction, no common finite sample).
    """
    keys = ["campaign_id", "elapsed_s"]
    merged = current[[*keys, "measured_um", "predicted_um"]].merge(
        challenger[[*keys, "predicted_um"]], on=keys, how="left", suffixes=("_current", "")
    )
    comparisons, unscored = [], {}
    for campaign in campaigns:
        rows = merged[merged["campaign_id"] == campaign]
        if rows.empty:
            unscored[campaign] = "no sample of it reached the comparison"
            continue
        if rows["predicted_um"].isna().all():
            unscored[campaign] = "the challenger has no held-out prediction of it"
            continue
        measured = rows["measured_um"].to_numpy(dtype=float)
        now = rows["predicted_um_current"].to_numpy(dtype=float)
        new = rows["predicted_um"].to_numpy(dtype=float)
        common = np.isfinite(measured) & np.isfinite(now) & np.isfinite(new)
        if not common.any():
            unscored[campaign] = "no sample where both champions predict"
            continue
        comparisons.append(
            CampaignComparison(
                campaign,
                int(common.sum()),
                root_mean_square(measured[common] - now[common]),
                root_mean_square(measured[common] - new[common]),
                root_mean_square(measured[common]),
            )
        )
    return comparisons, unscored


def decide_promotion(
    axis: str,
    comparisons: list[CampaignComparison],
    margin: float,
    versions: tuple[str | None, str | None],
    labels: tuple[str, str] = ("", ""),
    unscored: dict[str, str] | None = None,
) -> GateDecision:
    """Apply the gate's rule (see the module docstring) to the compared campaigns.

    Parameters
    ----------
    axis : str
    comparisons : list of CampaignComparison
    margin : float
        Fraction less RMS the challenger must leave than the current champion (0 to 1).
    versions : tuple
        (current, challenger) registered versions; current None on the first run.
    labels : tuple of str
        (current, challenger) ``model/selection/mode``; a challenger ``none/...`` is held only
        to the margin.
    unscored : dict, optional
        New campaigns that could not be compared.

    Raises
    ------
    ValueError
        If ``margin`` is outside [0, 1).
    """
    if not 0.0 <= margin < 1.0:
        raise ValueError(
            f"params.yaml track.promotion.min_improvement is {margin}; use a fraction in [0, 1)"
        )
    current, challenger = versions
    base = dict(
        axis=axis,
        current_version=current,
        challenger_version=challenger,
        current_label=labels[0],
        challenger_label=labels[1],
        margin=margin,
        campaigns=list(comparisons),
        unscored=dict(unscored or {}),
    )
    if challenger is None:
        return GateDecision(action=ERROR, reason="no challenger was registered", **base)
    if current is None:
        reason = (
            "first registered champion: evaluate held it to beating no compensation on the "
            "campaigns each fit did not see (or chose none)"
        )
        return GateDecision(action=PROMOTE, reason=reason, **base)
    if current == challenger:
        return GateDecision(
            action=KEEP, reason=f"version {current} is already the champion", **base
        )
    if not comparisons:
        reason = (
            f"no campaign that champion version {current} was not trained on could be scored "
            "for both: nothing shows the challenger is better"
        )
        return GateDecision(action=KEEP, reason=reason, **base)
    means = mean_rms(comparisons)
    now, new, none = means["current"], means["challenger"], means["none"]
    gain = 1.0 - new / now if now > 0 else 0.0
    figures = (
        f"on {len(comparisons)} campaign(s) version {current} never saw, the challenger leaves "
        f"{new:.2f} um RMS against {now:.2f} um for the champion and {none:.2f} um without "
        f"compensation ({100 * gain:+.0f} % against the champion; the margin is "
        f"{100 * margin:.0f} %)"
    )
    beats_none = labels[1].startswith("none/") or new < none
    if gain >= margin and beats_none:
        return GateDecision(action=PROMOTE, reason=f"promoted: {figures}", **base)
    why = "not better by the margin" if gain < margin else "no better than no compensation"
    return GateDecision(action=KEEP, reason=f"kept, {why}: {figures}", **base)


def render_report(decisions: list[GateDecision], title: str = "Promotion gate") -> str:
    """Markdown report: per axis, current vs challenger on the new campaigns, decision, why."""
    lines = [f"# {title}", ""]
    if not decisions:
        return "\n".join([*lines, "No axis has a champion to register.", ""])
    lines += [
        "| machine, axis | decision | champion now | challenger | new campaigns "
        "| champion RMS (um) | challenger RMS (um) | no compensation (um) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for d in decisions:
        means = d.means()
        now = d.challenger_version if d.promoted else d.current_version
        lines.append(
            f"| {d.name} | **{d.action}** | v{now or '-'} | v{d.challenger_version or '-'} "
            f"({d.challenger_label or '-'}) | {len(d.campaigns)} | {_cell(means['current'])} | "
            f"{_cell(means['challenger'])} | {_cell(means['none'])} |"
        )
    lines.append("")
    for d in decisions:
        lines += [f"## {d.name}: {d.action}", "", d.reason[0].upper() + d.reason[1:] + ".", ""]
        if d.current_version:
            lines.append(
                f"Champion before: v{d.current_version} ({d.current_label or '-'}); challenger: "
                f"v{d.challenger_version or '-'} ({d.challenger_label or '-'}), scored by its "
                "held-out predictions."
            )
            lines.append("")
        if d.campaigns:
            lines += [
                "| campaign | samples | champion RMS (um) | challenger RMS (um) | "
                "no compensation (um) |",
                "|---|---|---|---|---|",
            ]
            lines += [
                f"| {c.campaign_id} | {c.n_samples} | {_cell(c.current_rms_um)} | "
                f"{_cell(c.challenger_rms_um)} | {_cell(c.none_rms_um)} |"
                for c in d.campaigns
            ]
            lines.append("")
        lines += [f"- {campaign} not compared: {why}" for campaign, why in d.unscored.items()]
        if d.unscored:
            lines.append("")
    return "\n".join(lines)


def _cell(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.2f}"

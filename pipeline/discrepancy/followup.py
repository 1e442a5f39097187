"""After a proposed test: which effects its campaigns may name, and which stay suspects.

A rerun of the workflow after a proposed test has the earlier campaigns and the test's new ones.
Without a memory of the earlier run, a test meant to show one effect could name another one
on a misfit the test's load leaves in the baseline (seen on an independent machine model: a
headstock heater meant for ``sensor_lag`` left a misfit the search gave to ``motor_heat``).
The earlier run's outcome (:class:`FollowUp`, from its ``discrepancy.json`` or the history
file the stage keeps) gates the search (:func:`suspect_reason`):

* an effect named in the earlier run is not asked this, but it must pass the search on all
  the campaigns like any other; one that no longer does is reported as no longer named
  (:func:`no_longer_named`), with its figures on them;
* an effect newly named must owe its evidence to the **new campaigns**: on them alone, its
  held-out Z residual (or, for an effect that qualifies on the readings, the temperatures)
  must fall by the search's own threshold; otherwise it is a *suspect*: what made it pass
  is in the campaigns the earlier run had already seen without naming it;
* an effect newly named by a test proposed for **another** effect is a *suspect* until a
  second test confirms it: a later run in which it passes again on its own new campaigns;
* the effect the test was proposed for may also pass the search's threshold on the new
  campaigns alone, the earlier ones being unable to show it
  (:func:`pipeline.discrepancy.search.qualifies_on_test`).

Suspects are reported (``discrepancy.json`` ``suspects``) with the reason and left out of the
twin, and the search goes on with the other candidates. With no earlier run, or no new
campaign, nothing changes (the suspects of the earlier run stay suspects).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.fit_statistics import root_mean_square

NOT_IDENTIFIABLE = "not_identifiable"
"""The identifiability class whose effects get a proposed test (as in
:mod:`pipeline.discrepancy.identifiability`, which imports the search this module serves)."""


@dataclass(frozen=True)
class FollowUp:
    """What the earlier run of the workflow decided.

    Attributes
    ----------
    campaigns : frozenset of str
        The campaigns it saw.
    named : frozenset of str
        The effects it named.
    targets : frozenset of str
        The effects it proposed a test (or a calibration step) for: those classed not
        identifiable.
    suspects : dict of str to str
        The effects it held as suspects, with the reason.
    """

    campaigns: frozenset[str]
    named: frozenset[str]
    targets: frozenset[str]
    suspects: dict[str, str]

    def new_campaigns(self, campaign_ids: Sequence[str]) -> list[str]:
        """Return the campaigns of ``campaign_ids`` this earlier run had not seen, in order."""
        return [c for c in campaign_ids if c not in self.campaigns]

    @classmethod
    def from_document(cls, doc: Mapping[str, Any] | None) -> FollowUp | None:
        """Read the earlier run's ``discrepancy.json`` (or history entry); None without one.

        An entry without ``named_effects`` gives None: the history the stage keeps of an
        untestable run (:func:`pipeline.stages.discrepancy.history_of`), so that the next run
        that can search starts afresh.
        """
        if not doc or "named_effects" not in doc:
            return None
        ident = doc.get("identifiability") or {}
        targets = {e for e, entry in ident.items() if entry.get("class") == NOT_IDENTIFIABLE}
        targets |= set(doc.get("targets") or ())
        return cls(
            campaigns=frozenset(doc.get("campaigns") or ()),
            named=frozenset(doc["named_effects"]),
            targets=frozenset(targets),
            suspects={s["effect"]: s["reason"] for s in doc.get("suspects") or ()},
        )


def history_entry(doc: Mapping[str, Any]) -> dict[str, Any]:
    """Return what the next run needs of a run's ``discrepancy.json``.

    ``campaigns``, ``named_effects``, ``targets`` (the effects classed not identifiable, which
    got a proposed test) and ``suspects``: :meth:`FollowUp.from_document` reads it back.
    """
    ident = doc.get("identifiability") or {}
    return {
        "campaigns": list(doc.get("campaigns") or ()),
        "named_effects": list(doc.get("named_effects") or ()),
        "targets": sorted(e for e, v in ident.items() if v.get("class") == NOT_IDENTIFIABLE),
        "suspects": list(doc.get("suspects") or ()),
    }


def reduction_on(
    campaign_ids: Sequence[str],
    before: Mapping[str, Any],
    after: Mapping[str, Any],
) -> float:
    """Return ``1 - RMS after / RMS before`` of held-out residuals pooled over ``campaign_ids``.

    ``before`` and ``after`` map a campaign to its residual (an array, or a DataFrame of
    temperature residuals); NaN when none of the campaigns is in both.
    """
    ids = [c for c in campaign_ids if c in before and c in after]
    if not ids:
        return float("nan")
    first, second = (
        root_mean_square(np.concatenate([np.asarray(r[c], dtype=float).ravel() for c in ids]))
        for r in (before, after)
    )
    return 1.0 - second / first if first > 0 else float("nan")


def meets_thresholds(
    z_reduction: float,
    t_reduction: float,
    thresholds: tuple[float, float],
    by_readings_only: bool = False,
) -> bool:
    """Return whether held-out reductions (0..1) pass the search's rule: Z or temperatures.

    ``thresholds`` are ``min_heldout_reduction`` and ``min_heldout_t_reduction``; an effect of
    the readings only (``by_readings_only``) passes on the temperatures alone.
    """
    z_ok = not by_readings_only and np.isfinite(z_reduction) and z_reduction >= thresholds[0]
    return bool(z_ok or (np.isfinite(t_reduction) and t_reduction >= thresholds[1]))


def suspect_reason(
    effect: str,
    follow: FollowUp | None,
    campaign_ids: Sequence[str],
    z_reduction_new: float,
    t_reduction_new: float,
    thresholds: tuple[float, float],
    by_readings_only: bool = False,
) -> str | None:
    """Return why ``effect`` stays a suspect in this run, or None when it may be named.

    Parameters
    ----------
    effect : str
    follow : FollowUp or None
        The earlier run (None: no earlier run, nothing is gated).
    campaign_ids : sequence of str
        The campaigns of this run.
    z_reduction_new, t_reduction_new : float
        Fall of the held-out Z and temperature residuals on the new campaigns alone when the
        effect is added (:func:`reduction_on`), 0..1.
    thresholds : (float, float)
        The search's ``min_heldout_reduction`` and ``min_heldout_t_reduction``.
    by_readings_only : bool
        The effect changes the readings only (its Z route does not count).
    """
    if follow is None or effect in follow.named:
        return None
    new = sorted(follow.new_campaigns(campaign_ids))
    if not new:
        return follow.suspects.get(effect)
    if not meets_thresholds(z_reduction_new, t_reduction_new, thresholds, by_readings_only):
        return (
            f"its evidence is not in the new campaigns {', '.join(new)}: on them alone it "
            f"changes the held-out Z residual by {signed_percent(-z_reduction_new)} and the "
            f"temperatures by {signed_percent(-t_reduction_new)}; it passed on campaigns the "
            "earlier run had already seen without naming it"
        )
    if effect in follow.targets or effect in follow.suspects:
        return None
    meant = ", ".join(sorted(follow.targets)) or "no effect"
    return (
        f"newly named by the new campaigns {', '.join(new)}, while the earlier run proposed "
        f"tests for {meant}: a second test must confirm it (the next run names it if it passes "
        "again on its own new campaigns)"
    )


def signed_percent(x: float | None) -> str:
    """Return a fraction as a signed whole percentage (``-4 %``), or n/a."""
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:+.0f} %"


def no_longer_named(
    follow: FollowUp | None,
    named: Sequence[str],
    suspects: Mapping[str, str],
    last_evidence: Mapping[str, tuple[float, float]],
) -> list[dict[str, str]]:
    """Return the effects the earlier run named that this run does not name, with why.

    Parameters
    ----------
    follow : FollowUp or None
        The earlier run (None: nothing to compare with).
    named : sequence of str
        The effects this run names.
    suspects : mapping of str to str
        This run's suspects and their reasons.
    last_evidence : mapping of str to (float, float)
        Effect -> its held-out Z and temperature reductions (0..1) when it was last tried in
        this run's search.

    Returns
    -------
    list of dict
        ``{"effect", "reason"}`` per effect, in name order.
    """
    if follow is None:
        return []
    out = []
    for effect in sorted(follow.named - set(named)):
        if effect in suspects:
            why = f"it passes the search's rule but is held back: {suspects[effect]}"
        elif effect in last_evidence:
            z, t = last_evidence[effect]
            why = (
                "with the new campaigns it no longer passes the search's rule (held-out Z "
                f"{signed_percent(-z)}, temperatures {signed_percent(-t)} when last tried): "
                "what the earlier campaigns showed of it does not hold on all of them"
            )
        else:
            why = "this run did not try it (its sensors are missing or it left the candidates)"
        out.append({"effect": effect, "reason": why})
    return out

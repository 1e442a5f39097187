"""The discrepancy workflow on campaigns already read: search, localise, report.

:func:`run` calibrates the baseline twin (:mod:`pipeline.discrepancy.model`), names the missing
effects by forward selection with cross-validation across campaigns
(:mod:`pipeline.discrepancy.search`), classes every candidate effect by whether the campaigns
can show it (:mod:`pipeline.discrepancy.identifiability`), proposes for each effect they cannot
show the cheapest test that would (:mod:`pipeline.discrepancy.plan_proposal`), localises the
residuals before and after by phase, speed level and ambient trend
(:mod:`pipeline.discrepancy.localise`) and writes the report
(:mod:`pipeline.discrepancy.report`); :func:`run_untestable` writes the report of campaigns the
twin cannot be compared with (:func:`untestable_reason`). The campaigns come from the validated
spindle tables (:func:`spindle_campaigns`): those of the ``validate`` stage, or those of any raw
folder read and validated in memory by the same ingest and validation code (:func:`read_raw`).
"""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from pipeline.discrepancy.data import MeasuredCampaign, campaigns_from_tables
from pipeline.discrepancy.followup import FollowUp, no_longer_named
from pipeline.discrepancy.identifiability import (
    IdentifiabilitySettings,
    identifiability,
    searched_point,
    visibility_gate,
)
from pipeline.discrepancy.localise import localise
from pipeline.discrepancy.model import ROLE_NODES
from pipeline.discrepancy.plan_naming import held_out_floor
from pipeline.discrepancy.plan_proposal import propose_tests
from pipeline.discrepancy.report import (
    build_document,
    untestable_document,
    write_outputs,
    write_untestable,
)
from pipeline.discrepancy.search import (
    SearchResult,
    SearchSettings,
    campaign_roles,
    first_reason,
    search_twin,
)
from pipeline.discrepancy.speed_steps import speed_step_gate, step_signature
from pipeline.io.tables import ingest
from pipeline.machines import resolved_names
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.validation.checks import validate_tables
from pipeline.validation.gaps import apply_gaps
from pipeline.validation.report import quarantine_summary
from pipeline.validation.tables import select_valid
from schemas import ValidationLimits

logger = logging.getLogger(__name__)


def read_raw(
    raw_dir: Path, max_alignment_gap_s: float, limits: ValidationLimits
) -> tuple[list[MeasuredCampaign], list[str], bool]:
    """Ingest and validate a raw folder of one machine; return its valid spindle campaigns.

    A folder of several machines is read machine by machine with :func:`read_raw_tables`.

    Parameters
    ----------
    raw_dir : Path
        One sub-folder per campaign (docs/data-contract.md).
    max_alignment_gap_s : float
        As ``params.yaml`` ``ingest.max_alignment_gap_s``.
    limits : ValidationLimits
        The limits of the ``validate`` section
        (:meth:`pipeline.settings.validate.ValidateSettings.limits`).

    Returns
    -------
    campaigns : list of MeasuredCampaign
        Valid spindle-drift campaigns with a Z displacement.
    quarantined : list of str
        Campaigns left out, each logged with its problems.
    synthetic : bool
        True if any kept campaign is flagged ``synthetic`` in its campaign.yaml.

    Raises
    ------
    ValueError
        When the valid campaigns are of more than one machine.
    """
    campaigns, samples, quarantined = read_raw_tables(raw_dir, max_alignment_gap_s, limits)
    machines = sorted(set(campaigns["machine"]))
    if len(machines) > 1:
        raise ValueError(
            f"{raw_dir} holds the campaigns of {len(machines)} machines ({', '.join(machines)}): "
            "compare one machine's campaigns at a time (thermal discrepancy --raw does so)"
        )
    measured, synthetic = spindle_campaigns(campaigns, samples)
    return measured, list(quarantined), synthetic


def read_raw_tables(
    raw_dir: Path, max_alignment_gap_s: float, limits: ValidationLimits
) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, str]]:
    """Ingest and validate a raw folder; return its valid spindle campaigns' tables.

    Parameters are those of :func:`read_raw`.

    Returns
    -------
    campaigns, samples : DataFrame
        As ``data/validated/spindle/{campaigns,samples}.parquet`` (``machine`` resolved).
    quarantined : dict of str to str
        Campaigns left out, each logged with its problems -> its machine (``""``: unknown).
    """
    tables = ingest(Path(raw_dir), max_alignment_gap_s)
    result = validate_tables(
        tables["campaigns"], tables["samples"], tables["laser"], tables["problems"], limits
    )
    for campaign_id in result.quarantined:
        logger.warning(
            "campaign %s quarantined: %s; run `thermal ingest --raw %s` and `thermal validate` "
            "for the full report",
            campaign_id,
            quarantine_summary(result, campaign_id),
            raw_dir,
        )
    samples = apply_gaps(tables["samples"], result.gaps)
    campaigns = tables["campaigns"].assign(machine=resolved_names(tables["campaigns"]))
    spindle = select_valid(campaigns, samples, tables["laser"], result.valid)["spindle"]
    owner = dict(zip(campaigns["campaign_id"].astype(str), campaigns["machine"], strict=True))
    quarantined = {c: owner.get(c, "") for c in result.quarantined}
    return spindle["campaigns"], spindle["samples"], quarantined


def spindle_campaigns(
    campaigns: pd.DataFrame, samples: pd.DataFrame
) -> tuple[list[MeasuredCampaign], bool]:
    """Return the valid spindle-drift campaigns with a Z displacement of the validated tables.

    Parameters
    ----------
    campaigns, samples : DataFrame
        ``data/validated/spindle/{campaigns,samples}.parquet`` (or the same tables in memory).

    Returns
    -------
    campaigns : list of MeasuredCampaign
    synthetic : bool
        True if any campaign is flagged ``synthetic`` in its campaign.yaml.
    """
    measured = campaigns_from_tables(campaigns, samples)
    synthetic = bool(
        "synthetic" in campaigns and pd.Series(campaigns["synthetic"]).fillna(False).any()
    )
    return measured, synthetic


STRUCTURE_ROLES = tuple(ROLE_NODES)
"""Sensor roles that are nodes of the twin's thermal network (at least one is needed)."""


MIN_CAMPAIGNS = 2


def untestable_reason(campaigns: list[MeasuredCampaign]) -> str | None:
    """Why the twin cannot be compared with these campaigns, or None when it can.

    Parameters
    ----------
    campaigns : list of MeasuredCampaign
        The valid spindle-drift campaigns with a Z displacement.

    Returns
    -------
    str or None
        In words, with what to add: too few campaigns (the search holds campaigns out), or no
        sensor whose role is a node of the twin's network.
    """
    if len(campaigns) < MIN_CAMPAIGNS:
        return (
            f"{len(campaigns)} valid spindle-drift campaign(s) with a Z displacement; the "
            f"comparison needs at least {MIN_CAMPAIGNS} (campaigns are held out to test each "
            "effect): add campaigns with a Z probe or fix the quarantined ones"
        )
    roles = campaign_roles(campaigns)
    if not roles & set(STRUCTURE_ROLES):
        return (
            f"no sensor has a structure role (roles present: {', '.join(sorted(roles))}): the "
            "twin's thermal network is built from the places of the sensors; give the sensors "
            "on the machine their role in campaign.yaml (at least one of "
            f"{', '.join(STRUCTURE_ROLES)})"
        )
    return None


def run(
    campaigns: list[MeasuredCampaign],
    section: DiscrepancySettings,
    out_dir: Path,
    *,
    quarantined: list[str] | None = None,
    synthetic: bool = False,
    follow: FollowUp | None = None,
    machine: str | None = None,
) -> tuple[SearchResult, dict, list[Path]]:
    """Search, localise and write the outputs for already-read campaigns (of one machine).

    ``follow`` is the earlier run's outcome (:mod:`pipeline.discrepancy.followup`): an effect
    it did not name must owe its evidence to the campaigns it had not seen. ``machine``, when
    given, is written in the document.

    Returns
    -------
    result : SearchResult
    doc : dict
        The ``discrepancy.json`` content.
    files : list of Path
        The files written to ``out_dir``.
    """
    settings = SearchSettings.from_settings(section)
    loc_settings = section.localise
    ident_settings = IdentifiabilitySettings.from_settings(section.identifiability)
    gate = first_reason(
        visibility_gate(campaigns, ident_settings),
        speed_step_gate(campaigns, settings.min_heldout_reduction),
    )
    signature = step_signature(campaigns, settings.min_heldout_reduction)
    result = search_twin(campaigns, settings, follow, gate, signature)
    point = searched_point(campaigns, result, ident_settings)
    classes = identifiability(
        campaigns, result, settings.candidates, ident_settings, point, settings.max_delta_bic
    )
    floor = held_out_floor(result, point.campaigns, settings)
    proposed = propose_tests(point, classes, ident_settings, floor)
    entries = {e: c.to_dict(ident_settings) for e, c in classes.items()}
    for effect, test in proposed.items():
        entries[effect]["proposed_test"] = test.to_dict()
    before, after = (
        localise(campaigns, fit.z_residual_um, fit.t_residual_k, loc_settings, label=label)
        for fit, label in (
            (result.baseline.full, "the baseline twin"),
            (result.final.full, "the augmented twin"),
        )
    )
    doc = build_document(
        result,
        before,
        after,
        settings,
        synthetic=synthetic,
        campaign_ids=[c.campaign_id for c in campaigns],
        quarantined=quarantined or [],
        identifiability=entries,
    )
    last_tried = {
        c.effect: (c.heldout_reduction, c.heldout_t_reduction) for r in result.rounds for c in r
    }
    doc["no_longer_named"] = no_longer_named(
        follow, result.named_effects, result.suspects, last_tried
    )
    if machine is not None:
        doc["machine"] = machine
    files = write_outputs(out_dir, doc, campaigns, result, before)
    logger.info(
        "discrepancy: named %s; held-out Z RMS %.2f -> %.2f um (%.0f s)",
        ", ".join(result.named_effects) or "nothing",
        result.rmse_um_before,
        result.rmse_um_after,
        result.seconds,
    )
    return result, doc, files


def run_untestable(
    campaigns: list[MeasuredCampaign],
    reason: str,
    out_dir: Path,
    *,
    quarantined: list[str] | None = None,
    synthetic: bool = False,
    machine: str | None = None,
) -> tuple[dict, list[Path]]:
    """Write the report of campaigns the twin cannot be compared with (status untestable).

    ``machine``, when given, is written in the document.

    Returns
    -------
    doc : dict
        The ``discrepancy.json`` content.
    files : list of Path
        The files written to ``out_dir``.
    """
    doc = untestable_document(
        reason,
        needed_roles=list(STRUCTURE_ROLES),
        roles_present=sorted(campaign_roles(campaigns)),
        campaign_ids=[c.campaign_id for c in campaigns],
        quarantined=quarantined or [],
        synthetic=synthetic,
    )
    if machine is not None:
        doc["machine"] = machine
    files = write_untestable(out_dir, doc)
    logger.warning("discrepancy: untestable: %s", reason)
    return doc, files

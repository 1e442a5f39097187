"""Which machine each campaign is of; the campaigns whose machine is unknown are quarantined.

The pipeline models every machine on its own (:mod:`pipeline.machines`): its sensors by name
(``T1`` of one machine is not ``T1`` of another), its runs, its champion. ``machine`` is optional
in the raw contract: a campaign without it is of the one machine the others name. In a folder
whose campaigns name two machines or more, a campaign without ``machine:`` could be of any of
them and is quarantined (``machine_unknown``); so is a campaign that ``follows:`` a campaign of
another machine (``follows_other_machine``: one record cannot run on two machines), and the
campaigns of a machine whose name, made safe for folder and model names, is another machine's
(``machine_name_clash``).
"""

from __future__ import annotations

import pandas as pd

from pipeline.machines import machine_key, resolved_names
from pipeline.validation.findings import Finding
from pipeline.validation.problems import CAMPAIGN_FILE


def machine_findings(campaigns: pd.DataFrame) -> list[Finding]:
    """Return the problems of the campaigns whose machine is unknown or contradictory.

    Parameters
    ----------
    campaigns : DataFrame
        Ingested campaigns (``campaign_id``, ``machine``: free text, ``""`` or missing when not
        given, ``follows``).

    Returns
    -------
    list of Finding
        ``machine_unknown``, ``follows_other_machine`` and ``machine_name_clash``, one per
        campaign, file ``campaign.yaml``, column ``machine`` (``follows``).
    """
    names = resolved_names(campaigns)
    ids = campaigns["campaign_id"].astype(str)
    machines = sorted(set(names) - {""})
    listed = ", ".join(repr(m) for m in machines)
    found = [
        Finding(cid, CAMPAIGN_FILE, "machine_unknown", "machine", fields={"machines": listed})
        for cid in ids[names == ""]
    ]
    owner = dict(zip(ids, names, strict=True))
    follows = campaigns["follows"] if "follows" in campaigns else pd.Series(None, index=ids.index)
    for cid, predecessor in zip(ids, follows, strict=True):
        other = owner.get(str(predecessor)) if isinstance(predecessor, str) else None
        if other and owner[cid] and other != owner[cid]:
            fields = {"machine": owner[cid], "other_machine": other}
            found.append(
                Finding(
                    cid,
                    CAMPAIGN_FILE,
                    "follows_other_machine",
                    "follows",
                    value=predecessor,
                    fields=fields,
                )
            )
    first_name: dict[str, str] = {}
    for name in machines:
        key = machine_key(name)
        if key in first_name:
            fields = {"machine": name, "other_machine": first_name[key], "key": key}
            found += [
                Finding(
                    cid, CAMPAIGN_FILE, "machine_name_clash", "machine", value=name, fields=fields
                )
                for cid in ids[names == name]
            ]
        first_name.setdefault(key, name)
    return found

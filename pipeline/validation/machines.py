"""One machine per folder: campaigns of several machines are not pooled.

The pipeline models one machine: its sensors by name (``T1`` of one machine is not ``T1`` of
another), its runs, its champion. Campaigns whose ``campaign.yaml`` names more than one
``machine`` stop ``validate`` before anything is written, until the pipeline models each machine
on its own. ``machine`` is optional in the raw contract: a campaign without it is taken to be of
the one machine the others name, never a machine of its own.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from pipeline.errors import InputDataError

SHOWN_IDS = 5
"""Campaign ids named per machine in the message (the count says how many there are)."""


class MixedMachinesError(InputDataError):
    """The campaigns of one folder name more than one ``machine``."""


def _ids_text(ids: list[str]) -> str:
    """Return ``3 campaigns (K01, K02, K03)``, the ids cut after :data:`SHOWN_IDS`."""
    shown = ", ".join(ids[:SHOWN_IDS]) + (", ..." if len(ids) > SHOWN_IDS else "")
    return f"{len(ids)} campaign{'s' if len(ids) != 1 else ''} ({shown})"


def _folder(campaigns: pd.DataFrame) -> str:
    """Return the folder the campaigns were read from (``data/raw``), or a phrase for several."""
    parents = {str(Path(str(d)).parent) for d in campaigns["source_dir"].dropna()}
    return parents.pop() if len(parents) == 1 else "one folder"


def require_one_machine(campaigns: pd.DataFrame) -> None:
    """Raise :class:`MixedMachinesError` when the campaigns name more than one machine.

    Parameters
    ----------
    campaigns : DataFrame
        Ingested campaigns (``campaign_id``, ``machine``: free text, ``""`` or missing when not
        given, ``source_dir``). Names are compared without surrounding white space.

    Raises
    ------
    MixedMachinesError
        Naming each machine with its number of campaigns and the first ids, the campaigns
        without ``machine:``, and what to do.
    """
    names = campaigns["machine"].fillna("").astype(str).str.strip()
    ids = campaigns["campaign_id"].astype(str)
    machines = sorted(set(names) - {""})
    if len(machines) < 2:
        return
    parts = [f"machine {m!r}: {_ids_text(sorted(ids[names == m]))}" for m in machines]
    unnamed = sorted(ids[names == ""])
    if unnamed:
        parts.append(f"without machine: {_ids_text(unnamed)}")
    folder = _folder(campaigns)
    raise MixedMachinesError(
        f"validate: the campaigns in {folder} are of {len(machines)} machines, and the pipeline "
        "models one machine at a time (sensor T1 of one machine is not T1 of another): "
        + "; ".join(parts)
        + ". Put each machine's campaign folders in a folder (or repository) of their own and "
        "run the pipeline once per machine, e.g. move the campaigns of all machines but one out "
        f"of {folder}"
        + (" and give the campaigns without machine: their machine" if unnamed else "")
        + ", then rerun dvc repro; nothing was validated"
    )

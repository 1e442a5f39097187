"""Machines are partitions: which machine each campaign is of, and each machine's rows alone.

Sensor ``T1`` of one machine is not ``T1`` of another, so nothing is ever fitted, selected or
scored across machines: every stage runs its work once per machine on that machine's rows and
writes the results side by side (a ``machine`` column in tables, a ``machines`` mapping in JSON
documents, a ``<machine>/`` folder level). ``machine`` is optional in the raw contract: a
campaign without it is of the one machine the others name, of :data:`UNNAMED` when none names
one, and is quarantined by ``validate`` when the folder names several (it could be any of them).
"""

from __future__ import annotations

import re
from collections.abc import Collection, Iterator

import pandas as pd

from pipeline.errors import MissingInputError

MACHINE_COLUMN = "machine"
UNNAMED = "unnamed"
"""The machine of a folder whose campaigns name none."""

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def written_names(campaigns: pd.DataFrame) -> pd.Series:
    """Return each campaign's ``machine`` as written, white space around it aside."""
    if MACHINE_COLUMN not in campaigns:
        return pd.Series("", index=campaigns.index, dtype=object)
    return campaigns[MACHINE_COLUMN].fillna("").astype(str).str.strip()


def resolved_names(campaigns: pd.DataFrame) -> pd.Series:
    """Return each campaign's machine: as written, else the folder's one machine, or UNNAMED.

    Parameters
    ----------
    campaigns : DataFrame
        Ingested campaigns (``machine``: free text, empty or missing when not given).

    Returns
    -------
    Series of str
        Aligned with ``campaigns``; ``""`` for a campaign without ``machine`` in a folder whose
        campaigns name two machines or more (its machine is unknown).
    """
    names = written_names(campaigns)
    named = sorted(set(names) - {""})
    if len(named) > 1:
        return names
    return names.where(names != "", named[0] if named else UNNAMED)


def machine_key(name: str) -> str:
    """Return the machine's name as written in folder, file and registered model names.

    Letters, digits, ``.``, ``_`` and ``-`` are kept; every other run of characters becomes one
    ``-`` (``"DMU 50 #2"`` -> ``"DMU-50-2"``).
    """
    return _UNSAFE.sub("-", name.strip()).strip("-") or UNNAMED


def machines_of(frame: pd.DataFrame) -> list[str]:
    """Return the machines of a table with a ``machine`` column, sorted."""
    return sorted(pd.unique(frame[MACHINE_COLUMN].astype(str)))


def machine_rows(frame: pd.DataFrame, machine: str, fixed: Collection[str]) -> pd.DataFrame:
    """Return one machine's rows, without the columns only the other machines fill.

    A wide table of several machines (one column per sensor) holds the union of their sensor
    columns; a column that is empty on this machine's rows but holds values of another machine
    is left out, so that the slice has the columns the machine's campaigns alone would give.

    Parameters
    ----------
    frame : DataFrame
        Rows of every machine, a ``machine`` column.
    machine : str
    fixed : collection of str
        Columns always kept (the table's own columns, whatever they hold).

    Returns
    -------
    DataFrame
        The machine's rows in their order, index 0..n-1.
    """
    rows = frame.loc[frame[MACHINE_COLUMN].astype(str) == machine]
    others = [
        c
        for c in rows.columns
        if c not in fixed and rows[c].isna().all() and frame[c].notna().any()
    ]
    return rows.drop(columns=others).reset_index(drop=True)


def by_machine(frame: pd.DataFrame, fixed: Collection[str]) -> Iterator[tuple[str, pd.DataFrame]]:
    """Yield each machine of ``frame`` and its rows alone (:func:`machine_rows`), by name."""
    for machine in machines_of(frame):
        yield machine, machine_rows(frame, machine, fixed)


def with_machine(frame: pd.DataFrame, machine: str) -> pd.DataFrame:
    """``frame`` with a leading ``machine`` column holding ``machine``."""
    out = frame.copy()
    out.insert(0, MACHINE_COLUMN, pd.Series([machine] * len(out), index=out.index, dtype="str"))
    return out


def tag_rows(frame: pd.DataFrame, campaigns: pd.DataFrame) -> pd.DataFrame:
    """``frame`` (a ``campaign_id`` column) with the ``machine`` of each row's campaign.

    ``campaigns`` holds ``campaign_id`` and the resolved ``machine`` (``validate``'s output).
    """
    ids, names = campaigns["campaign_id"].astype(str), campaigns[MACHINE_COLUMN].astype(str)
    owner = dict(zip(ids, names, strict=True))
    return frame.assign(**{MACHINE_COLUMN: frame["campaign_id"].astype(str).map(owner)})


def registered_name(prefix: str, machine: str, axis: str) -> str:
    """Return the registered model name of a machine's axis, ``<prefix>-<machine>-<axis>``.

    ``prefix`` is ``params.yaml`` ``track.registered_model``; the machine as
    :func:`machine_key` writes it (``thermal-error-spindle-vmc-450-twin-Z``).
    """
    return f"{prefix}-{machine_key(machine)}-{axis}"


def axis_label(machine: str, axis: str) -> str:
    """Return the file-name label of a machine's axis, ``<machine>_<axis>`` (machine as a key)."""
    return f"{machine_key(machine)}_{axis}"


def one_machine(asked: str | None, machines: list[str], where: str) -> str:
    """Return the machine a command acts on: ``--machine``, else the one machine there is.

    Parameters
    ----------
    asked : str or None
        ``--machine`` as given (compared as :func:`machine_key` writes it).
    machines : list of str
        The machines found (names, or folder names).
    where : str
        Where they were found, for the messages.

    Raises
    ------
    MissingInputError
        When ``--machine`` is not among ``machines``, or is left out and there are several.
    """
    keys = {machine_key(m): m for m in machines}
    if asked is not None:
        if machine_key(asked) not in keys:
            raise MissingInputError(
                f"--machine {asked}: no such machine in {where} (machines: "
                f"{', '.join(machines) or 'none'}); run `dvc repro` or correct the name"
            )
        return keys[machine_key(asked)]
    if len(machines) > 1:
        raise MissingInputError(
            f"{where} hold {len(machines)} machines ({', '.join(machines)}): say which one "
            "with --machine NAME"
        )
    if not machines:
        raise MissingInputError(f"no machine in {where}; run `dvc repro` first")
    return machines[0]

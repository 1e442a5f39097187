"""Slice the ingested tables: one campaign's rows, and the valid campaigns' outputs."""

from __future__ import annotations

from collections.abc import Iterable

import pandas as pd

from schemas.vocabulary import AXIS_KIND, SAMPLE_BASE_COLUMNS, SPINDLE_KIND


def campaign_rows(table: pd.DataFrame, campaign_id: str) -> pd.DataFrame:
    """Return one campaign's rows of a samples or laser table in file order.

    Parameters
    ----------
    table : DataFrame
        Ingested table of all campaigns (``campaign_id``, ``source_row``).
    campaign_id : str

    Returns
    -------
    DataFrame
        The campaign's rows sorted by ``source_row``, index 0..n-1.
    """
    rows = table.loc[table["campaign_id"] == campaign_id].sort_values("source_row")
    return rows.reset_index(drop=True)


def drop_empty_columns(samples: pd.DataFrame) -> pd.DataFrame:
    """Return ``samples`` without temperature/displacement columns that hold no value."""
    keep = [c for c in samples.columns if c in SAMPLE_BASE_COLUMNS or samples[c].notna().any()]
    return samples[keep]


def campaign_samples(samples: pd.DataFrame, campaign_id: str) -> pd.DataFrame:
    """Return one campaign's samples in file order, with only the columns holding its data.

    Parameters
    ----------
    samples : DataFrame
        Ingested samples of all campaigns (union of their columns).
    campaign_id : str

    Returns
    -------
    DataFrame
        Rows of the campaign sorted by ``source_row``, index 0..n-1; the base columns plus every
        temperature / displacement column with at least one value for this campaign.
    """
    return drop_empty_columns(campaign_rows(samples, campaign_id))


def select_valid(
    campaigns: pd.DataFrame,
    samples: pd.DataFrame,
    laser: pd.DataFrame,
    valid: Iterable[str],
) -> dict[str, dict[str, pd.DataFrame]]:
    """Split the valid campaigns' rows into the spindle and axis outputs.

    Parameters
    ----------
    campaigns, samples, laser : DataFrame
        Ingested tables.
    valid : iterable of str
        Campaign ids to keep.

    Returns
    -------
    dict
        ``{"spindle": {"campaigns", "samples"}, "axis": {"campaigns", "samples", "laser"}}``:
        the rows of the valid campaigns of that kind, in their ingested order; samples columns
        without any value for the kept campaigns are dropped (the base columns stay).
    """
    valid = set(valid)
    out: dict[str, dict[str, pd.DataFrame]] = {}
    for name, kind in (("spindle", SPINDLE_KIND), ("axis", AXIS_KIND)):
        kept = campaigns.loc[campaigns["campaign_id"].isin(valid) & (campaigns["kind"] == kind)]
        ids = set(kept["campaign_id"])
        tables = {
            "campaigns": kept.reset_index(drop=True),
            "samples": drop_empty_columns(
                samples.loc[samples["campaign_id"].isin(ids)].reset_index(drop=True)
            ),
        }
        if kind == AXIS_KIND:
            tables["laser"] = laser.loc[laser["campaign_id"].isin(ids)].reset_index(drop=True)
        out[name] = tables
    return out

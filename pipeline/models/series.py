"""Per-campaign time-series helpers: campaign segments, lagged designs and error history.

A feature table ``X`` carries a MultiIndex with levels ``("campaign_id", "elapsed_s")``; each
campaign is a contiguous, time-ordered block of rows. Time-series structure (lags, the error's
own history) restarts at every campaign boundary so nothing leaks from one campaign into
another. An ``X`` without a ``campaign_id`` index level is one series.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

logger = logging.getLogger(__name__)

CAMPAIGN_LEVEL = "campaign_id"


def check_xy(
    X: pd.DataFrame, y: np.ndarray, min_columns: int = 1
) -> tuple[pd.DataFrame, np.ndarray]:
    """Validate a training pair and return it as (float DataFrame, float ndarray).

    Parameters
    ----------
    X : pandas.DataFrame, shape (n, m)
        Temperatures (K rise or degC), one column per sensor, index as in :func:`segments`.
    y : array-like, shape (n,)
        Thermal error (um), rows aligned with X.
    min_columns : int
        Fewest sensor columns accepted (see :func:`check_features`).

    Returns
    -------
    tuple of (pandas.DataFrame, numpy.ndarray)
        ``X`` with float columns (a new object; the input is not modified) and ``y`` as a
        float array of shape (n,).

    Raises
    ------
    TypeError
        If X is not a DataFrame.
    ValueError
        If X has no rows or columns, if X or y holds NaN/inf, or if their lengths differ.
    """
    frame = check_features(X, min_columns=min_columns)
    target = np.asarray(y, dtype=float).ravel()
    if len(target) != len(frame):
        raise ValueError(
            f"y has {len(target)} values but X has {len(frame)} rows; pass one error per row"
        )
    if not np.isfinite(target).all():
        raise ValueError("y holds NaN or infinite values; drop or repair those rows first")
    return frame, target


def check_features(
    X: pd.DataFrame, columns: list[str] | None = None, min_columns: int = 1
) -> pd.DataFrame:
    """Validate a feature table and return its (selected) columns as floats.

    Parameters
    ----------
    X : pandas.DataFrame, shape (n, m)
        Temperatures (K rise or degC), one column per sensor.
    columns : list of str, optional
        Sensor columns a fitted model was trained on; they are selected in this order.
    min_columns : int
        Fewest sensor columns accepted: 0 for models on the error series alone, which use
        only X's index (the campaign boundaries).

    Returns
    -------
    pandas.DataFrame, shape (n, len(columns) or m)
        X's (selected) columns as floats, with X's index: X itself when it already is exactly
        that (callers do not modify it).

    Raises
    ------
    TypeError
        If X is not a DataFrame.
    ValueError
        If X has no rows or columns, lacks one of ``columns``, or holds NaN/inf.
    """
    if not isinstance(X, pd.DataFrame):
        raise TypeError(
            f"X must be a pandas DataFrame with one column per sensor, got {type(X).__name__}"
        )
    if columns is not None:
        missing = [c for c in columns if c not in X.columns]
        if missing:
            raise ValueError(
                f"X lacks the sensor columns {missing} the model was fitted on; "
                "pass the same sensors as in fit"
            )
        if list(X.columns) != list(columns):
            X = X.loc[:, list(columns)]
    if X.shape[0] == 0 or X.shape[1] < min_columns:
        raise ValueError(
            f"X has shape {X.shape}; it needs at least one row and {min_columns} sensor column(s)"
        )
    frame = X if (X.dtypes == np.float64).all() else X.astype(float)
    if not np.isfinite(frame.to_numpy()).all():
        raise ValueError("X holds NaN or infinite temperatures; drop or repair those rows first")
    return frame


def segments(X: pd.DataFrame) -> list[np.ndarray]:
    """Return the integer row positions of each campaign, in order of appearance.

    Parameters
    ----------
    X : pandas.DataFrame, shape (n, m)
        Feature table. If its index has a ``campaign_id`` level, every contiguous block of equal
        campaign ids is one segment; otherwise the whole table is one segment.

    Returns
    -------
    list of numpy.ndarray
        One int64 array of row positions (0..n-1) per campaign; together they cover every row.
        Empty list for an empty table.

    Raises
    ------
    ValueError
        If a campaign id occurs in two separate blocks (rows of one campaign are not
        contiguous); sort or group X by campaign before fitting.
    """
    n = len(X)
    if n == 0:
        return []
    if CAMPAIGN_LEVEL not in (X.index.names or []):
        return [np.arange(n, dtype=np.int64)]
    index = X.index
    level = index.names.index(CAMPAIGN_LEVEL)
    if isinstance(index, pd.MultiIndex) and not (index.codes[level] < 0).any():
        codes = np.asarray(index.codes[level])  # already factorised; -1 would be a missing id
    else:
        codes, _ = pd.factorize(index.get_level_values(level), use_na_sentinel=False)
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    block_codes = codes[starts]
    if len(np.unique(block_codes)) != len(block_codes):
        ids = index.get_level_values(level)
        repeated = pd.Index(ids[starts]).value_counts()
        raise ValueError(
            "rows of a campaign are not contiguous in X (campaign ids appearing in several "
            f"blocks: {sorted(map(str, repeated[repeated > 1].index))}); "
            "group the rows by campaign_id, time-ordered, before fitting or predicting"
        )
    ends = np.r_[starts[1:], n]
    return [np.arange(s, e, dtype=np.int64) for s, e in zip(starts, ends, strict=True)]


def _shift_padded(values: np.ndarray, lag: int, pad: np.ndarray | float) -> np.ndarray:
    """Shift rows of a (k, m) or (k,) array down by ``lag``, filling the top with ``pad``."""
    out = np.empty_like(values, dtype=float)
    k = len(values)
    cut = min(lag, k)
    out[:cut] = pad
    out[cut:] = values[: k - cut]
    return out


def lagged(X: pd.DataFrame, n_lags: int) -> pd.DataFrame:
    """Build the distributed-lag design: every column at lags 0..n_lags, per campaign.

    Parameters
    ----------
    X : pandas.DataFrame, shape (n, m)
        Temperatures (K rise or degC), columns = sensor names, index as in :func:`segments`.
    n_lags : int
        Highest lag (samples), >= 0. ``0`` returns the current values only.

    Returns
    -------
    pandas.DataFrame, shape (n, m * (n_lags + 1))
        Same index as ``X``; columns ``"<sensor>_lag<i>"`` ordered sensor-major (all lags of
        the first sensor, then the next sensor). Values before a campaign's first sample are
        taken equal to that first sample: the machine rests at its cold state before a test,
        so the temperatures were constant there. Every row therefore has a complete design row.

    Raises
    ------
    ValueError
        If ``n_lags`` is negative or not an integer.
    """
    columns = [f"{sensor}_lag{i}" for sensor in X.columns for i in range(n_lags + 1)]
    return pd.DataFrame(lagged_values(X, n_lags), index=X.index, columns=columns)


def lagged_values(X: pd.DataFrame, n_lags: int) -> np.ndarray:
    """Return the values of :func:`lagged`, shape (n, m * (n_lags + 1)), without the table.

    Raises
    ------
    ValueError
        If ``n_lags`` is negative or not an integer.
    """
    if isinstance(n_lags, bool) or not isinstance(n_lags, int | np.integer) or n_lags < 0:
        raise ValueError(f"n_lags must be a non-negative integer, got {n_lags!r}")
    values = X.to_numpy(dtype=float)
    m = values.shape[1]
    out = np.empty((len(X), m * (n_lags + 1)), dtype=float)
    for rows in segments(X):
        block = values[rows]
        for i in range(n_lags + 1):
            out[rows[:, None], np.arange(m) * (n_lags + 1) + i] = _shift_padded(block, i, block[0])
    return out


def history(
    y: np.ndarray, X_or_segments: pd.DataFrame | list[np.ndarray], n_lags: int
) -> np.ndarray:
    """Return the error's own history y_{t-1}, ..., y_{t-n_lags} per campaign.

    Parameters
    ----------
    y : numpy.ndarray, shape (n,)
        Thermal error (um), rows aligned with X.
    X_or_segments : pandas.DataFrame or list of numpy.ndarray
        The feature table (its index gives the campaigns) or the output of :func:`segments`.
    n_lags : int
        Number of past values, >= 0.

    Returns
    -------
    numpy.ndarray, shape (n, n_lags)
        Column ``i - 1`` holds y_{t-i}. Values before a campaign's first sample are 0.0: the
        thermal error is 0 at the cold reference state.

    Raises
    ------
    ValueError
        If ``n_lags`` is negative or ``y`` does not have one value per row.
    """
    if isinstance(n_lags, bool) or not isinstance(n_lags, int | np.integer) or n_lags < 0:
        raise ValueError(f"n_lags must be a non-negative integer, got {n_lags!r}")
    y = np.asarray(y, dtype=float).ravel()
    segs = segments(X_or_segments) if isinstance(X_or_segments, pd.DataFrame) else X_or_segments
    n_rows = sum(len(rows) for rows in segs)
    if n_rows != len(y):
        raise ValueError(
            f"y has {len(y)} values but the segments cover {n_rows} rows; pass y aligned with X"
        )
    out = np.zeros((len(y), n_lags), dtype=float)
    for rows in segs:
        block = y[rows]
        for i in range(1, n_lags + 1):
            out[rows, i - 1] = _shift_padded(block, i, 0.0)
    return out

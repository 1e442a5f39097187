"""What every sensitive-point selector returns, and the input contract they all share.

A selector is ``f(temperatures, error, **params) -> Selection``. ``temperatures`` is a DataFrame
of shape (n, m): columns are sensor names, values temperature rises (K) or absolute temperatures
(degC); it may hold one campaign or several concatenated (index levels ``campaign_id``,
``elapsed_s``) -- selectors work on the pooled rows. ``error`` is the thermal error, ndarray of
shape (n,) in um, aligned with the rows.

:func:`clean_inputs` applies the common rules: sensors without any finite value are ignored,
rows with a NaN in a used sensor or in the error are dropped, and sensors that are constant on
the remaining rows are ignored too (they carry no information and make correlations and
regressions undefined). Ignored sensors are never selected; each selector lists them in its
evidence with the reason.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

logger = logging.getLogger(__name__)

STATUS_USED = "used"
STATUS_ALL_NAN = "ignored: all NaN"
STATUS_CONSTANT = "ignored: constant"


@dataclass(frozen=True)
class Selection:
    """The sensitive points a method chose and the numbers it decided on.

    Attributes
    ----------
    method : str
        Registry name of the method (e.g. ``"fc_grd"``).
    sensors : list of str
        Chosen sensors, in order of preference (most preferred first).
    evidence : DataFrame
        Tidy table of what the decision rested on: one row per sensor, group or subset, as the
        method's docstring describes.
    details : dict of str to int, float or str
        Scalars for MLflow params (number of groups, lambda, rule, ...).
    """

    method: str
    sensors: list[str]
    evidence: pd.DataFrame
    details: dict[str, int | float | str]


@dataclass(frozen=True)
class CleanInputs:
    """Temperatures and error restricted to usable sensors and complete rows.

    Attributes
    ----------
    temperatures : DataFrame of shape (n_used_rows, m_used)
        Usable sensors in their original column order; no NaN.
    error : ndarray of shape (n_used_rows,)
        Thermal error, um; no NaN.
    ignored : dict of str to str
        Ignored sensor -> reason (``STATUS_ALL_NAN`` or ``STATUS_CONSTANT``).
    n_rows_dropped : int
        Rows dropped for a NaN in a used sensor or in the error.
    """

    temperatures: pd.DataFrame
    error: np.ndarray
    ignored: dict[str, str]
    n_rows_dropped: int

    def status_rows(self) -> pd.DataFrame:
        """Evidence rows (``sensor``, ``status``, ``chosen``) for the ignored sensors.

        Returns
        -------
        DataFrame
            One row per ignored sensor; ``chosen`` is False.
        """
        return pd.DataFrame(
            {
                "sensor": list(self.ignored),
                "status": list(self.ignored.values()),
                "chosen": [False] * len(self.ignored),
            }
        )

    def with_ignored(self, evidence: pd.DataFrame, integer_column: str) -> pd.DataFrame:
        """Append the ignored sensors' rows (:meth:`status_rows`) to a selector's evidence.

        Parameters
        ----------
        evidence : DataFrame
            One row per used sensor, with a ``sensor`` column.
        integer_column : str
            Integer column of ``evidence`` (rank, group) the ignored rows leave empty; it
            becomes a nullable ``Int64`` column.

        Returns
        -------
        DataFrame
            ``evidence``, then the ignored rows, on a new 0..n-1 index.
        """
        table = pd.concat([evidence, self.status_rows()], ignore_index=True)
        table[integer_column] = table[integer_column].astype("Int64")
        return table

    def counts(self) -> dict[str, int]:
        """Return the data counts every selector reports in its ``details``.

        Returns
        -------
        dict of str to int
            ``n_rows`` (complete rows used), ``n_rows_dropped``, ``n_sensors_used``,
            ``n_sensors_ignored``.
        """
        return {
            "n_rows": len(self.error),
            "n_rows_dropped": self.n_rows_dropped,
            "n_sensors_used": self.temperatures.shape[1],
            "n_sensors_ignored": len(self.ignored),
        }


def check_frame(temperatures: pd.DataFrame, error: np.ndarray) -> np.ndarray:
    """Check the shapes and types of a selector's inputs; return the error as float array.

    Parameters
    ----------
    temperatures : DataFrame of shape (n, m)
        Temperature rises (K) or temperatures (degC), one column per sensor.
    error : array-like of shape (n,)
        Thermal error, um.

    Returns
    -------
    ndarray of shape (n,)
        The error as float64 (a new array; the input is not modified).

    Raises
    ------
    TypeError
        If ``temperatures`` is not a DataFrame.
    ValueError
        If it is empty, has duplicate or non-numeric columns, or the error's shape differs.
    """
    if not isinstance(temperatures, pd.DataFrame):
        raise TypeError(
            f"temperatures must be a pandas DataFrame (rows = samples, columns = sensors), "
            f"got {type(temperatures).__name__}"
        )
    if temperatures.shape[0] == 0 or temperatures.shape[1] == 0:
        raise ValueError(
            f"temperatures is empty (shape {temperatures.shape}); pass at least one sensor "
            f"column and some rows"
        )
    if temperatures.columns.duplicated().any():
        duplicated = sorted(map(str, temperatures.columns[temperatures.columns.duplicated()]))
        raise ValueError(f"temperatures has duplicate sensor columns {duplicated}; rename them")
    non_numeric = [
        str(c) for c in temperatures.columns if not pd.api.types.is_numeric_dtype(temperatures[c])
    ]
    if non_numeric:
        raise ValueError(f"temperature columns {non_numeric} are not numeric; convert them to K")
    values = np.asarray(error, dtype=float)
    if values.shape != (temperatures.shape[0],):
        raise ValueError(
            f"error has shape {values.shape} but temperatures has {temperatures.shape[0]} rows; "
            f"pass one error value (um) per row"
        )
    return values.copy()


def clean_inputs(temperatures: pd.DataFrame, error: np.ndarray, min_rows: int = 3) -> CleanInputs:
    """Restrict the inputs to usable sensors and complete rows.

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (module docstring), as for :func:`check_frame`.
    min_rows : int, default 3
        Fewest complete rows a selector can work with.

    Returns
    -------
    CleanInputs
        The usable data and what was left out.

    Raises
    ------
    ValueError
        If the inputs are malformed (see :func:`check_frame`), no sensor is usable, the error
        is constant, or fewer than ``min_rows`` complete rows remain.
    """
    y = check_frame(temperatures, error)
    columns = [str(c) for c in temperatures.columns]
    frame = temperatures.set_axis(columns, axis=1).astype(float)
    ignored = {c: STATUS_ALL_NAN for c in columns if not np.isfinite(frame[c].to_numpy()).any()}
    kept = [c for c in columns if c not in ignored]
    if not kept:
        raise ValueError(
            f"no sensor has any finite value (all of {columns} are NaN); check the ingest"
        )
    values = frame[kept].to_numpy()
    complete = np.isfinite(values).all(axis=1) & np.isfinite(y)
    n_complete = int(complete.sum())
    if n_complete < min_rows:
        raise ValueError(
            f"only {n_complete} rows have every used sensor and the error finite, "
            f"need at least {min_rows}; drop the sensors with gaps or supply more samples"
        )
    rows = frame.loc[complete, kept]
    constant = [c for c in kept if np.ptp(rows[c].to_numpy()) == 0.0]
    ignored.update(dict.fromkeys(constant, STATUS_CONSTANT))
    used = [c for c in kept if c not in constant]
    if not used:
        raise ValueError(
            f"every sensor is constant on the complete rows ({constant}); nothing to select from"
        )
    y_used = y[complete]
    if np.ptp(y_used) == 0.0:
        raise ValueError("the thermal error is constant; no sensor can be related to it")
    if ignored:
        logger.debug("ignored sensors: %s", ignored)
    return CleanInputs(
        temperatures=rows[used],
        error=y_used,
        ignored=ignored,
        n_rows_dropped=int(len(y) - n_complete),
    )

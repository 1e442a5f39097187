"""Predict the thermal error from a table as the machine logs it, prepared exactly as in training.

The registered model (:mod:`pipeline.tracking.champion_model`) calls :func:`predict_table`:

1. each run of the table (a ``campaign_id`` group, rows contiguous and in time order; the whole
   table when there is no ``campaign_id``) sampled faster than the model's window is averaged
   into windows of ``resample_s``, as the ``separate_spindle`` stage did with the training
   campaigns (:func:`pipeline.separation.features.resample`; needs ``elapsed_s``);
2. the inputs are computed by :func:`pipeline.separation.features.model_inputs` (rises from each
   run's first row, speed responses from rest at its start);
3. the estimator predicts the rows whose inputs are all present, as in the cross-campaign scores
   (:func:`pipeline.protocol.cross_season.predict_campaign`); the others get NaN;
4. the window predictions are brought back to the table's rows: linear interpolation in time
   within the run (the nearest window before the first and after the last window's instant).
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

from pipeline.separation.features import (
    InputSpec,
    check_input_columns,
    model_inputs,
    needs_windows,
    resample,
    run_time_index,
    spec_input_values,
    window_means,
)


def _runs(table: pd.DataFrame) -> np.ndarray:
    if "campaign_id" in table:
        return table["campaign_id"].astype(str).to_numpy()
    return np.full(len(table), "run")


def predict_table(estimator, table: pd.DataFrame, spec: InputSpec) -> np.ndarray:
    """Predicted thermal error (um) of every row of ``table``.

    Parameters
    ----------
    estimator : fitted estimator
        The champion's fit on all training campaigns.
    table : DataFrame
        The machine's table (see :func:`pipeline.separation.features.model_inputs`).
    spec : InputSpec
        How the inputs were prepared in training.

    Returns
    -------
    ndarray of shape (len(table),), um
        NaN where an input is missing.
    """
    frame = table.reset_index(drop=True)
    runs = _runs(frame)
    names = pd.unique(runs)
    if len(names) == 1 and "elapsed_s" in frame:
        check_input_columns(frame.columns, spec)
        rpm = frame["rpm"] if "rpm" in frame else np.full(len(frame), np.nan)
        return predict_run(
            estimator,
            frame["elapsed_s"].to_numpy(dtype=float),
            frame[spec.sensors].to_numpy(dtype=float, na_value=np.nan),
            np.asarray(rpm, dtype=float),
            spec,
        )
    windows = [
        resample(
            (frame if len(names) == 1 else frame[runs == run]).assign(campaign_id=run),
            spec.resample_s,
        )
        for run in names
    ]
    resampled = windows[0] if len(windows) == 1 else pd.concat(windows, ignore_index=True)
    X = model_inputs(resampled, spec)
    complete = ~np.isnan(X.to_numpy()).any(axis=1)
    predicted = np.full(len(X), np.nan)
    if complete.any():
        predicted[complete] = estimator.predict(X[complete])
    if len(resampled) == len(frame):
        return predicted
    out = np.full(len(frame), np.nan)
    elapsed = frame["elapsed_s"].to_numpy(dtype=float)
    window_elapsed = resampled["elapsed_s"].to_numpy(dtype=float)
    window_runs = resampled["campaign_id"].to_numpy()
    for run in names:
        mine, theirs = runs == run, (window_runs == run) & np.isfinite(predicted)
        if theirs.any():
            out[mine] = np.interp(elapsed[mine], window_elapsed[theirs], predicted[theirs])
    return out


def linear_prediction(estimator, rows: np.ndarray) -> np.ndarray | None:
    """Apply a scikit-learn ``LinearRegression`` as its formula; None for any other estimator.

    A linear regression on one target predicts ``rows @ coef_ + intercept_``, which is what its
    ``predict`` computes, after checks of the input table that take 1-5 ms a call against
    microseconds for the product. The runtime predicts every cycle; the columns are the fit's
    by construction (:class:`InputSpec`).

    Parameters
    ----------
    estimator : fitted estimator
    rows : ndarray of shape (n, n_inputs)
        The model's inputs, complete rows, in the order of ``InputSpec.inputs``.

    Returns
    -------
    ndarray of shape (n,), um, or None
    """
    linear = sys.modules.get("sklearn.linear_model")  # imported if the estimator is one
    if linear is None or type(estimator) is not linear.LinearRegression:
        return None
    coef = np.asarray(estimator.coef_, dtype=float)
    if coef.ndim != 1 or coef.size != rows.shape[1]:
        return None
    return rows @ coef + float(estimator.intercept_)


def predict_run(
    estimator, t_s: np.ndarray, temperatures: np.ndarray, rpm: np.ndarray, spec: InputSpec
) -> np.ndarray:
    """Predicted thermal error (um) at every sample of one run given as arrays.

    What :func:`predict_table` does with a one-run table, without building the table: the
    compensation runtime calls it every cycle on the run so far.

    Parameters
    ----------
    estimator : fitted estimator
    t_s : ndarray of shape (n,), s
        Time of each sample since the run's start, increasing.
    temperatures : ndarray of shape (n, len(spec.sensors)), degC
        The readings of ``spec.sensors`` in that order; NaN is a missing (or bad) reading.
    rpm : ndarray of shape (n,), rpm
        Spindle speed (read only when ``spec.needs_speed``).
    spec : InputSpec

    Returns
    -------
    ndarray of shape (n,), um
        NaN where an input is missing.
    """
    t_s = np.asarray(t_s, dtype=float)
    windows = needs_windows(t_s, spec.resample_s)
    if windows:
        columns = np.column_stack([t_s, rpm, temperatures])
        _, means = window_means(t_s, columns, float(spec.resample_s))
        window_t, window_rpm, window_temperatures = means[:, 0], means[:, 1], means[:, 2:]
    else:
        window_t, window_rpm, window_temperatures = t_s, rpm, temperatures
    inputs = spec_input_values(spec, window_t, window_temperatures, window_rpm)
    complete = ~np.isnan(inputs).any(axis=1)
    predicted = np.full(len(inputs), np.nan)
    if complete.any():
        rows = inputs[complete]
        values = linear_prediction(estimator, rows)
        if values is None:
            index = run_time_index(np.zeros(len(rows), dtype=int), window_t[complete])
            values = estimator.predict(pd.DataFrame(rows, index=index, columns=list(spec.inputs)))
        predicted[complete] = values
    if not windows:
        return predicted
    finite = np.isfinite(predicted)
    if not finite.any():
        return np.full(len(t_s), np.nan)
    return np.interp(t_s, window_t[finite], predicted[finite])

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

import numpy as np
import pandas as pd

from pipeline.separation.features import InputSpec, model_inputs, resample


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

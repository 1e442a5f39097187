"""Spindle thermal drift: thermal error = displacement minus its cold-state value.

The PCDL paper (Miao et al. 2016, section 3) measures the Z drift of the spindle nose with an
eddy-current probe every 3 min from a cold start; the thermal error is the change from the cold
state. The cold state is the first sample or the mean of the first N samples (params). The same
reference is taken for every temperature sensor, giving the temperature rises (K) that a model
fed ``temperature_rise`` features uses.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

COLD_REFERENCES = ("first_sample", "mean_first_n")


def cold_value(values: np.ndarray, reference: str, n: int) -> float:
    """Cold-state value of a series: its first finite value or the mean of its first n finite ones.

    Parameters
    ----------
    values : ndarray of shape (n_samples,)
        Time-ordered readings (um or degC); NaN are missing readings.
    reference : {"first_sample", "mean_first_n"}
    n : int
        Number of samples averaged for ``mean_first_n``.
    """
    if reference not in COLD_REFERENCES:
        raise ValueError(
            f"params.yaml separate.cold_reference is '{reference}'; use one of {COLD_REFERENCES}"
        )
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return float("nan")
    return float(finite[0]) if reference == "first_sample" else float(np.mean(finite[:n]))


def spindle_thermal_error(
    campaigns: pd.DataFrame, samples: pd.DataFrame, axis: str, reference: str, n: int
) -> pd.DataFrame:
    """Thermal error and temperature rises of every spindle-drift campaign.

    Parameters
    ----------
    campaigns : DataFrame
        Validated spindle campaigns (``campaign_id``, ``split``, ``season``, ``synthetic``,
        ``sensors_json``).
    samples : DataFrame
        Validated spindle samples (``disp_<axis>`` in um, one column per sensor in degC).
    axis : str
        Displacement axis modelled, e.g. ``"Z"``.
    reference : {"first_sample", "mean_first_n"}
        Cold-state definition.
    n : int
        Samples averaged for ``mean_first_n``.

    Returns
    -------
    DataFrame
        One row per sample of each campaign that measured ``axis``: ``campaign_id``,
        ``source_row``, ``elapsed_s``, ``rpm``, ``split``, ``season``, ``synthetic``,
        ``displacement_um``, ``thermal_error_um``, then each sensor (degC) and
        ``rise_<sensor>`` (K).
    """
    column = f"disp_{axis}"
    frames = []
    for meta in campaigns.itertuples(index=False):
        rows = samples[samples["campaign_id"] == meta.campaign_id].sort_values("elapsed_s")
        if column not in rows or rows[column].isna().all():
            continue
        sensors = list(json.loads(meta.sensors_json))
        displacement = rows[column].to_numpy(dtype=float)
        frame = pd.DataFrame({
            "campaign_id": meta.campaign_id,
            "source_row": rows["source_row"].to_numpy(),
            "elapsed_s": rows["elapsed_s"].to_numpy(),
            "rpm": rows["rpm"].to_numpy(),
            "split": meta.split,
            "season": meta.season,
            "synthetic": bool(meta.synthetic),
            "displacement_um": displacement,
            "thermal_error_um": displacement - cold_value(displacement, reference, n),
        })  # fmt: skip
        for sensor in sensors:
            values = rows[sensor].to_numpy(dtype=float)
            frame[sensor] = values
            frame[f"rise_{sensor}"] = values - cold_value(values, reference, n)
        frames.append(frame)
    if not frames:
        raise ValueError(
            f"no valid spindle_drift campaign has a '{axis}' displacement column; check "
            "reports/validation.json and params.yaml separate.displacement_axis"
        )
    return pd.concat(frames, ignore_index=True)

"""Linear-axis positioning error: geometric part by a polynomial, thermal part by its slope.

The linear-axis patent (Chinese invention patent "Optimal selection method for the thermal
temperature-sensitive points of a machine tool's linear axis based on independent-variable
selection criteria", published 2022; steps 1, 3 and claims 2-3): the laser-interferometer
positioning error of the cold machine (pass at 0 min) is the geometric error; it is fitted by an
n-th order polynomial over position (the patent uses 4th order, its eq. 1). The positioning
error of each warm-up pass minus the geometric error is the thermal error, and a first-order fit
over position gives that pass's slope k_i (um/mm), which the patent then regresses on
temperatures (its eq. 2). Deviation from the patent: it fits the slope of the whole measured
curve and subtracts the cold slope k0 afterwards (delta_t = (k_i - k0) x); fitting the thermal
part directly gives the same k_i - k0 up to the polynomial's nonlinear terms. The bidirectional
mean (average of the + and - runs of a pass at each target) removes the reversal error before
fitting.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
from numpy.polynomial import Polynomial


def bidirectional_mean(laser: pd.DataFrame) -> pd.DataFrame:
    """Mean deviation of the + and - runs of each pass at each target.

    Parameters
    ----------
    laser : DataFrame
        Laser rows (``campaign_id``, ``elapsed_min``, ``direction``, ``target_mm``,
        ``deviation_um``); the runs of one bidirectional pass share ``elapsed_min``.

    Returns
    -------
    DataFrame
        ``campaign_id``, ``elapsed_min``, ``target_mm``, ``measured_um``, ``reversal_um``
        (+ minus -, NaN when a direction is missing).
    """
    keyed = laser.assign(target_mm=laser["target_mm"].round(3))
    by_direction = keyed.pivot_table(
        index=["campaign_id", "elapsed_min", "target_mm"],
        columns="direction",
        values="deviation_um",
        aggfunc="mean",
    )
    directions = [d for d in ("+", "-") if d in by_direction.columns]
    result = pd.DataFrame({"measured_um": by_direction[directions].mean(axis=1)})
    result["reversal_um"] = (
        by_direction["+"] - by_direction["-"] if len(directions) == 2 else np.nan
    )
    return result.reset_index()


def fit_geometric(target_mm: np.ndarray, measured_um: np.ndarray, order: int) -> np.ndarray:
    """Least-squares polynomial of the cold pass, coefficients in ascending powers.

    Parameters
    ----------
    target_mm : ndarray of shape (n,)
        Positions, mm.
    measured_um : ndarray of shape (n,)
        Bidirectional mean positioning error of the cold pass, um.
    order : int
        Polynomial order (the patent: 4).

    Returns
    -------
    ndarray of shape (order + 1,)
        c_0 .. c_order with geometric_um(x) = sum c_p x^p, x in mm (um / mm^p). The fit is
        done on a scaled domain for conditioning, then converted.
    """
    if len(target_mm) <= order:
        raise ValueError(
            f"the cold pass has {len(target_mm)} targets, too few for a polynomial of order "
            f"{order}; lower params.yaml separate.geometric_order or measure more targets"
        )
    return Polynomial.fit(target_mm, measured_um, order).convert().coef


def slope_fit(target_mm: np.ndarray, thermal_um: np.ndarray) -> tuple[float, float]:
    """First-order fit thermal_um = k x + b; returns (k in um/mm, b in um)."""
    k, b = np.polyfit(target_mm, thermal_um, 1)
    return float(k), float(b)


def separate_axis(
    campaigns: pd.DataFrame, samples: pd.DataFrame, laser: pd.DataFrame, order: int
) -> dict[str, pd.DataFrame]:
    """Separate geometric and thermal positioning error of every axis campaign.

    Parameters
    ----------
    campaigns : DataFrame
        Validated axis campaigns (``campaign_id``, ``split``, ``season``, ``axis_name``,
        ``synthetic``, ``sensors_json``).
    samples : DataFrame
        Validated axis temperatures (degC) at ``elapsed_s``.
    laser : DataFrame
        Validated laser rows.
    order : int
        Order of the geometric polynomial.

    Returns
    -------
    dict of str to DataFrame
        ``geometric``: one row per campaign and power (``coefficient`` in um/mm^power);
        ``thermal``: per pass and target, ``measured_um``, ``geometric_um``, ``thermal_um``,
        ``thermal_fit_um``; ``slopes``: per pass, ``slope_um_per_mm``, ``intercept_um`` and the
        temperature of every sensor interpolated at the pass time (degC).
    """
    means = bidirectional_mean(laser)
    geometric_rows, thermal_frames, slope_rows = [], [], []
    for meta in campaigns.itertuples(index=False):
        passes = means[means["campaign_id"] == meta.campaign_id]
        cold_minute = passes["elapsed_min"].min()
        cold = passes[passes["elapsed_min"] == cold_minute]
        coefficients = fit_geometric(
            cold["target_mm"].to_numpy(), cold["measured_um"].to_numpy(), order
        )
        geometric_rows += [
            {"campaign_id": meta.campaign_id, "power": p, "coefficient": float(c)}
            for p, c in enumerate(coefficients)
        ]
        thermal = passes.assign(
            geometric_um=Polynomial(coefficients)(passes["target_mm"].to_numpy())
        )
        thermal["thermal_um"] = thermal["measured_um"] - thermal["geometric_um"]
        temperatures = samples[samples["campaign_id"] == meta.campaign_id].sort_values("elapsed_s")
        sensors = list(json.loads(meta.sensors_json))
        fits = []
        for minute, rows in thermal.groupby("elapsed_min", sort=True):
            k, b = slope_fit(rows["target_mm"].to_numpy(), rows["thermal_um"].to_numpy())
            fits.append(pd.Series(k * rows["target_mm"] + b, index=rows.index))
            row = {
                "campaign_id": meta.campaign_id,
                "axis_name": meta.axis_name,
                "split": meta.split,
                "season": meta.season,
                "synthetic": bool(meta.synthetic),
                "elapsed_min": float(minute),
                "slope_um_per_mm": k,
                "intercept_um": b,
            }
            for sensor in sensors:
                row[sensor] = _interpolate(temperatures, sensor, float(minute) * 60.0)
            slope_rows.append(row)
        thermal["thermal_fit_um"] = pd.concat(fits)
        thermal_frames.append(thermal)
    return {
        "geometric": pd.DataFrame(geometric_rows),
        "thermal": pd.concat(thermal_frames, ignore_index=True),
        "slopes": pd.DataFrame(slope_rows),
    }


def _interpolate(temperatures: pd.DataFrame, sensor: str, elapsed_s: float) -> float:
    valid = temperatures[["elapsed_s", sensor]].dropna()
    if valid.empty:
        return float("nan")
    return float(np.interp(elapsed_s, valid["elapsed_s"], valid[sensor]))


def geometric_curve(
    tables: dict[str, pd.DataFrame], campaign_id: str, n: int = 200
) -> pd.DataFrame:
    """Evaluate one campaign's geometric polynomial on ``n`` targets across its stroke.

    Parameters
    ----------
    tables : dict of DataFrame
        The result of :func:`separate_axis` (``geometric`` and ``thermal``).
    campaign_id : str
    n : int
        Number of targets, evenly spaced from the smallest to the largest measured target.

    Returns
    -------
    DataFrame
        ``target_mm`` (mm) and ``geometric_um`` (um).
    """
    geometric = tables["geometric"]
    coefficients = geometric.loc[geometric["campaign_id"] == campaign_id, "coefficient"]
    thermal = tables["thermal"]
    targets = thermal.loc[thermal["campaign_id"] == campaign_id, "target_mm"]
    dense = np.linspace(float(targets.min()), float(targets.max()), n)
    return pd.DataFrame(
        {"target_mm": dense, "geometric_um": Polynomial(coefficients.to_numpy())(dense)}
    )

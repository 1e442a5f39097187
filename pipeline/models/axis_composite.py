"""Composite positioning-error model of a linear axis: geometric polynomial + thermal slope k(T).

The linear-axis patent (Chinese invention patent "Optimal selection method for the thermal
temperature-sensitive points of a machine tool's linear axis based on independent-variable selection
criteria", published 2022; steps 2-5, eqs. 1-4): laser runs of the axis at several warm-up times;
the cold run's error is fitted by a 4th-order polynomial P_geo(x) (eq. 1); a first-order fit of each
run gives its slope k_i; the temperature sensitive points are the best subset of the sensors for the
regression of k_i on the temperatures at each run, chosen by adjusted R^2 (max) and AICc (min) (the
patent keeps the AICc subset T1, T2, T5 out of 7); the slope model is the OLS fit
k = c0 + sum_j c_j T_j (eq. 2) and the composite model is ``E(x, T) = P_geo(x) + (k(T) - k0) x``
(eq. 3), k0 the slope at the cold run. The patent validates it on a second campaign (runs at 40
and 220 min): residuals within +-3.5 um.

Inputs are the tables of :mod:`pipeline.separation.axis` (``axis_slopes``: slope of the thermal
part and the temperature of every sensor, degC, per pass; ``axis_geometric``: polynomial
coefficients per campaign; ``axis_thermal_error``: bidirectional-mean measured error per pass and
target). Deviations from the patent, and why:

* Temperatures. The patent regresses k_i on the absolute PT100 readings and freezes eq. 4 with
  constants, i.e. k0 is the training campaign's cold slope whatever the ambient temperature of
  the campaign it is applied to (its eq. 4 even folds k0 into the constant: -2.1200 =
  -0.8353 - 1.2847, which makes k0 = 0). ``temperature="absolute"`` does that literally, with
  k0 = k(T at the training cold run). The default ``temperature="rise"`` uses the rise of every
  sensor above its reading at the cold run of the same campaign, and k0 = k(0) = c0: the same
  slope coefficients and the same selected subset on one training campaign (a constant shift of
  the regressors moves only c0), but the validation campaign's own cold run is its thermal
  reference, as in the patent's step 2 (the error of the freshly started machine is the
  geometric error). A campaign started at another ambient temperature (another season) then
  does not get a spurious thermal slope at its cold run.
* Slopes. The slopes come from the thermal part (measured minus the cold polynomial), so the
  cold run's slope is 0 by construction; the patent fits the whole curve and subtracts k0.
* Several training campaigns (the patent has one): their passes are pooled for selection and
  regression, and P_geo is the mean of their cold polynomials (the polynomial of the mean cold
  curve when the targets agree).
* The position-independent part of the thermal error (the first-order fit's intercept) is not
  modelled, as in the patent; it stays in the residual.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from numpy.polynomial import Polynomial

from pipeline.errors import InputDataError, ParamsError
from pipeline.fit_statistics import root_mean_square
from pipeline.selection.best_subset import CRITERIA as SELECTION_RULES
from pipeline.selection.best_subset import best_subset
from pipeline.selection.result import Selection
from schemas.separated import AxisSlopesModel

TEMPERATURE_MODES = ("rise", "absolute")
SLOPE_COLUMN = "slope_um_per_mm"
_FIXED_COLUMNS = frozenset(AxisSlopesModel.to_schema().columns)
_INDEX = ("campaign_id", "elapsed_s")


@dataclass(frozen=True)
class SlopeModel:
    """OLS model of the thermal slope k (um/mm) on the selected sensors.

    Attributes
    ----------
    sensors : tuple of str
        The selected sensors, in the order of ``coefficients``.
    intercept : float
        c0, um/mm (the slope at zero rise, or at 0 degC when ``temperature`` is "absolute").
    coefficients : tuple of float
        c_j, um/mm per K, one per sensor.
    temperature : str
        "rise" (K above the campaign's cold run) or "absolute" (degC).
    k0 : float
        Slope at the cold run, um/mm: c0 for "rise"; for "absolute" the mean fitted slope at
        the training campaigns' cold runs.
    std_errors, p_values : tuple of float
        OLS standard errors (um/mm, um/mm per K) and two-sided t-test p-values of c0 then c_j.
    r2, adj_r2 : float
        Coefficient of determination and its adjusted form.
    f_pvalue : float
        p-value of the regression's F test (the patent's table 8).
    n_passes : int
        Number of passes the model was fitted on.
    """

    sensors: tuple[str, ...]
    intercept: float
    coefficients: tuple[float, ...]
    temperature: str
    k0: float
    std_errors: tuple[float, ...]
    p_values: tuple[float, ...]
    r2: float
    adj_r2: float
    f_pvalue: float
    n_passes: int

    def slope(self, features: pd.DataFrame) -> np.ndarray:
        """Return k at each row of ``features`` (columns include ``sensors``), um/mm, shape (n,)."""
        return self.intercept + features[list(self.sensors)].to_numpy(dtype=float) @ np.asarray(
            self.coefficients, dtype=float
        )

    def equation(self) -> str:
        """Return the fitted equation as text, e.g. ``k = 0.0114 T1 + 0.0004``."""
        terms = " ".join(
            f"{'+' if c >= 0 else '-'} {abs(c):.4g} {s}"
            for s, c in zip(self.sensors, self.coefficients, strict=True)
        )
        unit = "K rise above the cold run" if self.temperature == "rise" else "degC"
        sign = "+" if self.intercept >= 0 else "-"
        return (
            f"k = {terms.lstrip('+ ')} {sign} {abs(self.intercept):.4g} "
            f"(k in um/mm, temperatures in {unit})"
        )


@dataclass(frozen=True)
class CompositeModel:
    """``E(x, T) = P_geo(x) + (k(T) - k0) x``, the patent's eq. 3.

    Attributes
    ----------
    geometric : tuple of float
        P_geo coefficients c_0..c_n in ascending powers of x (um / mm^p).
    slope : SlopeModel
        k(T) and k0.
    """

    geometric: tuple[float, ...]
    slope: SlopeModel

    def predict(self, target_mm: np.ndarray, features: pd.DataFrame) -> np.ndarray:
        """Positioning error at each (position, temperature) row, um.

        Parameters
        ----------
        target_mm : ndarray of shape (n,)
            Positions, mm.
        features : DataFrame of shape (n, m)
            Temperatures of the pass of each row, as :func:`pass_features` returns them.

        Returns
        -------
        ndarray of shape (n,)
        """
        x = np.asarray(target_mm, dtype=float)
        thermal_slope = self.slope.slope(features) - self.slope.k0
        return Polynomial(self.geometric)(x) + thermal_slope * x


def sensor_columns(slopes: pd.DataFrame) -> list[str]:
    """Return the temperature columns of an ``axis_slopes`` table, in table order."""
    return [c for c in slopes.columns if c not in _FIXED_COLUMNS]


def pass_features(slopes: pd.DataFrame, sensors: Sequence[str], temperature: str) -> pd.DataFrame:
    """Temperatures of the given sensors at every pass, as the regressors of k.

    Parameters
    ----------
    slopes : DataFrame
        ``axis_slopes`` rows (one per pass) of one or more campaigns.
    sensors : sequence of str
        Sensor columns to return.
    temperature : {"rise", "absolute"}
        "rise": reading minus the reading at the campaign's cold (earliest) pass, K;
        "absolute": the reading, degC.

    Returns
    -------
    DataFrame of shape (n_passes, len(sensors))
        Index (``campaign_id``, ``elapsed_s``), sorted by campaign then time.

    Raises
    ------
    ValueError
        If ``temperature`` is unknown, or a campaign lacks a reading of a sensor at a pass
        (names the campaign, sensor and passes, and what to do).
    """
    if temperature not in TEMPERATURE_MODES:
        raise ParamsError(
            f"unknown temperature mode '{temperature}'; use one of {list(TEMPERATURE_MODES)} "
            "in params.yaml model_axis.temperature"
        )
    ordered = _ordered(slopes)
    _require_readings(ordered, sensors)
    readings = ordered[list(sensors)].astype(float)
    if temperature == "rise":
        cold = readings.groupby(ordered["campaign_id"]).transform("first")
        readings = readings - cold
    index = pd.MultiIndex.from_arrays(
        [ordered["campaign_id"].to_numpy(), ordered["elapsed_min"].to_numpy() * 60.0],
        names=_INDEX,
    )
    return readings.set_axis(index, axis=0)


def pass_slopes(slopes: pd.DataFrame) -> np.ndarray:
    """Return the slope of every pass, um/mm, shape (n_passes,), in :func:`pass_features` order."""
    return _ordered(slopes)[SLOPE_COLUMN].to_numpy(dtype=float)


def candidate_sensors(slopes: pd.DataFrame, exclude: Sequence[str] = ()) -> list[str]:
    """Sensors read at every training pass, minus ``exclude``, in table order.

    Raises
    ------
    ValueError
        If no sensor is left.
    """
    sensors = [
        s for s in sensor_columns(slopes) if s not in set(exclude) and slopes[s].notna().all()
    ]
    if not sensors:
        raise InputDataError(
            f"no temperature sensor is read at every pass of the training axis campaign(s) "
            f"{sorted(pd.unique(slopes['campaign_id']))} (excluded: {list(exclude)}); check "
            "their temperature.csv or params.yaml model_axis.exclude_sensors"
        )
    return sensors


def fit_slope_model(
    slopes: pd.DataFrame, sensors: Sequence[str], temperature: str = "rise"
) -> SlopeModel:
    """OLS regression of the pass slopes on the selected temperatures (the patent's eq. 2).

    Parameters
    ----------
    slopes : DataFrame
        ``axis_slopes`` rows of the training campaign(s).
    sensors : sequence of str
        Selected sensors.
    temperature : {"rise", "absolute"}
        See :func:`pass_features`.

    Returns
    -------
    SlopeModel

    Raises
    ------
    ValueError
        If there are not more passes than coefficients.
    """
    features = pass_features(slopes, sensors, temperature)
    k = pass_slopes(slopes)
    if len(k) <= len(sensors) + 1:
        raise InputDataError(
            f"{len(k)} training passes cannot fit a slope model with {len(sensors)} sensors and "
            "an intercept; select fewer sensors or measure more passes"
        )
    # statsmodels is imported here, not with the module: a folder without axis campaigns runs the
    # stage without it (the import takes seconds).
    from statsmodels.regression.linear_model import OLS

    design = np.column_stack([np.ones(len(k)), features.to_numpy(dtype=float)])
    fit = OLS(k, design).fit()
    params = np.asarray(fit.params, dtype=float)
    model = SlopeModel(
        sensors=tuple(sensors),
        intercept=float(params[0]),
        coefficients=tuple(float(c) for c in params[1:]),
        temperature=temperature,
        k0=float(params[0]),
        std_errors=tuple(float(v) for v in fit.bse),
        p_values=tuple(float(v) for v in fit.pvalues),
        r2=float(fit.rsquared),
        adj_r2=float(fit.rsquared_adj),
        f_pvalue=float(fit.f_pvalue),
        n_passes=len(k),
    )
    if temperature == "absolute":
        cold = features.groupby(level="campaign_id").head(1)
        return replace(model, k0=float(np.mean(model.slope(cold))))
    return model


def mean_geometric(geometric: pd.DataFrame, campaign_ids: Sequence[str]) -> tuple[float, ...]:
    """Mean cold-run polynomial of the given campaigns, ascending powers (um / mm^p).

    Raises
    ------
    ValueError
        If a campaign has no geometric polynomial.
    """
    rows = geometric[geometric["campaign_id"].isin(list(campaign_ids))]
    missing = sorted(set(campaign_ids) - set(rows["campaign_id"]))
    if missing:
        raise ValueError(
            f"no geometric polynomial for axis campaign(s) {missing} in axis_geometric; "
            "rerun the separate_axis stage (dvc repro separate_axis)"
        )
    table = rows.pivot_table(index="campaign_id", columns="power", values="coefficient")
    return tuple(float(c) for c in table.mean(axis=0).sort_index())


def select_sensors(
    features: pd.DataFrame, k: np.ndarray, rule: str = "aicc", max_exhaustive: int = 25
) -> Selection:
    """Best-subset selection of the slope's sensitive points (the patent's step 2).

    Parameters
    ----------
    features : DataFrame of shape (n_passes, m)
        Candidate temperatures (:func:`pass_features`).
    k : ndarray of shape (n_passes,)
        Slopes, um/mm.
    rule : {"aicc", "adj_r2", "parsimonious"}
        Whose winner is used (:func:`pipeline.selection.best_subset.best_subset`); the winners
        of both criteria are in ``details`` (``winner_aicc``, ``winner_adj_r2``) either way.
        Subsets without an AICc (k >= n_passes - 3 sensors) are excluded from both.
    max_exhaustive : int
        Most candidates searched exhaustively.

    Returns
    -------
    Selection

    Raises
    ------
    ValueError
        If ``rule`` is unknown.
    """
    if rule not in SELECTION_RULES:
        raise ValueError(
            f"unknown selection rule '{rule}'; use one of {list(SELECTION_RULES)} in "
            "params.yaml model_axis.selection_rule"
        )
    return best_subset(features, k, criterion=rule, max_exhaustive=max_exhaustive)


def criterion_winners(selection: Selection) -> dict[str, list[str]]:
    """Return the adjusted-R^2 and AICc winners of a best-subset selection, sensor lists."""
    return {
        "adj_r2": str(selection.details["winner_adj_r2"]).split("+"),
        "aicc": str(selection.details["winner_aicc"]).split("+"),
    }


def score_campaigns(
    model: CompositeModel, slopes: pd.DataFrame, thermal: pd.DataFrame
) -> pd.DataFrame:
    """Composite prediction against the measured error at every target of every pass.

    Parameters
    ----------
    model : CompositeModel
    slopes : DataFrame
        ``axis_slopes`` rows (temperatures per pass) of the campaigns to score.
    thermal : DataFrame
        ``axis_thermal_error`` rows (``campaign_id``, ``elapsed_min``, ``target_mm``,
        ``measured_um`` = bidirectional mean) of the same campaigns.

    Returns
    -------
    DataFrame
        ``campaign_id``, ``elapsed_min``, ``target_mm``, ``measured_um``, ``predicted_um``,
        ``residual_um`` (measured minus predicted), ``k_minus_k0_um_per_mm``.

    Raises
    ------
    ValueError
        If a campaign lacks a reading of a selected sensor at one of its passes.
    """
    features = pass_features(slopes, model.slope.sensors, model.slope.temperature)
    per_pass = _ordered(slopes)[["campaign_id", "elapsed_min"]].reset_index(drop=True)
    per_pass = pd.concat([per_pass, features.reset_index(drop=True)], axis=1)
    points = thermal[["campaign_id", "elapsed_min", "target_mm", "measured_um"]].merge(
        per_pass, on=["campaign_id", "elapsed_min"], how="inner", validate="many_to_one"
    )
    measured = pd.MultiIndex.from_frame(points[["campaign_id", "elapsed_min"]])
    unmeasured = per_pass[
        ~pd.MultiIndex.from_frame(per_pass[["campaign_id", "elapsed_min"]]).isin(measured)
    ]
    if not unmeasured.empty:
        first = unmeasured.iloc[0]
        raise ValueError(
            f"axis campaign {first['campaign_id']}: pass at {first['elapsed_min']:g} min has a "
            "slope but no measured error in axis_thermal_error; the separation tables are out "
            "of step, rerun the separate_axis stage (dvc repro separate_axis)"
        )
    predicted = model.predict(points["target_mm"].to_numpy(), points)
    thermal_slope = model.slope.slope(points) - model.slope.k0
    result = points[["campaign_id", "elapsed_min", "target_mm", "measured_um"]].assign(
        predicted_um=predicted,
        residual_um=points["measured_um"].to_numpy() - predicted,
        k_minus_k0_um_per_mm=thermal_slope,
    )
    return result.sort_values(["campaign_id", "elapsed_min", "target_mm"], ignore_index=True)


def residual_band(residual_um: np.ndarray) -> dict[str, float | int]:
    """Residual band of a non-empty set of points, um.

    Parameters
    ----------
    residual_um : ndarray of shape (n,), n >= 1
        Measured minus predicted, um.

    Returns
    -------
    dict
        ``n_points``, ``residual_min_um``, ``residual_max_um``, ``residual_max_abs_um``,
        ``rmse_um``.
    """
    r = np.asarray(residual_um, dtype=float)
    return {
        "n_points": int(r.size),
        "residual_min_um": float(r.min()),
        "residual_max_um": float(r.max()),
        "residual_max_abs_um": float(np.abs(r).max()),
        "rmse_um": root_mean_square(r),
    }


def bands(points: pd.DataFrame) -> dict[str, object]:
    """Residual band overall, per campaign and per pass of each campaign.

    Parameters
    ----------
    points : DataFrame
        Output of :func:`score_campaigns`.

    Returns
    -------
    dict
        ``overall`` band plus ``by_campaign``: {campaign: {band..., ``by_pass``:
        {"<minutes>": band}}}.
    """
    by_campaign = {}
    for campaign_id, rows in points.groupby("campaign_id", sort=True):
        by_pass = {
            f"{minute:g}": residual_band(group["residual_um"].to_numpy())
            for minute, group in rows.groupby("elapsed_min", sort=True)
        }
        by_campaign[str(campaign_id)] = {
            **residual_band(rows["residual_um"].to_numpy()),
            "by_pass_min": by_pass,
        }
    return {"overall": residual_band(points["residual_um"].to_numpy()), "by_campaign": by_campaign}


def _ordered(slopes: pd.DataFrame) -> pd.DataFrame:
    return slopes.sort_values(["campaign_id", "elapsed_min"], kind="stable")


def _require_readings(slopes: pd.DataFrame, sensors: Sequence[str]) -> None:
    for campaign_id, rows in slopes.groupby("campaign_id", sort=True):
        for sensor in sensors:
            values = rows[sensor] if sensor in rows.columns else pd.Series(np.nan, rows.index)
            if values.isna().any():
                minutes = [f"{m:g}" for m in rows.loc[values.isna(), "elapsed_min"]]
                split = rows["split"].iloc[0] if "split" in rows.columns else "split unknown"
                raise InputDataError(
                    f"axis campaign {campaign_id} ({split}) has no reading of sensor {sensor} "
                    f"at pass(es) {minutes} min, but the slope model uses {sensor}; add "
                    f"'{sensor}' to params.yaml model_axis.exclude_sensors to select the "
                    f"sensitive points without it, or repair {campaign_id}'s temperature.csv"
                )

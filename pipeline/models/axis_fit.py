"""The linear-axis composite model fitted and scored on the axis campaigns (the patent).

Selects the slope's temperature sensitive points by best subset on the training axis campaigns
(adjusted R^2 and AICc, both winners reported, ``model_axis.selection_rule`` decides), fits
k(T) by OLS, builds ``E(x, T) = P_geo(x) + (k(T) - k0) x``
(:mod:`pipeline.models.axis_composite`) and scores it on the training campaigns (fit) and the
validation campaigns against the patent's +-3.5 um band; returns the report, the metrics and
the scored points that the ``model_axis`` stage writes.
"""

from __future__ import annotations

import json
import logging

import pandas as pd

from pipeline.models.axis_composite import (
    CompositeModel,
    bands,
    candidate_sensors,
    criterion_winners,
    fit_slope_model,
    mean_geometric,
    pass_features,
    pass_slopes,
    score_campaigns,
    select_sensors,
)
from pipeline.selection.result import Selection
from pipeline.settings.model_axis import ModelAxisSettings

LOGGER = logging.getLogger(__name__)


SOURCE = "the linear-axis patent (2022): sensitive points by best subset, eqs. 1-4"


def build(
    params: ModelAxisSettings, slopes: pd.DataFrame, geometric: pd.DataFrame, thermal: pd.DataFrame
) -> tuple[dict, dict, pd.DataFrame]:
    """Fit and score the composite model.

    Parameters
    ----------
    params : ModelAxisSettings
        The ``model_axis`` section of params.yaml.
    slopes, geometric, thermal : DataFrame
        ``axis_slopes``, ``axis_geometric`` and ``axis_thermal_error`` (possibly empty).

    Returns
    -------
    report : dict
        Content of ``reports/axis_model.json``.
    metrics : dict
        Flat scalars of ``metrics/axis_model.json``.
    points : DataFrame
        Scored points (:func:`pipeline.models.axis_composite.score_campaigns`) plus ``role``
        ("fit" | "validation"); empty when nothing was modelled.
    """
    band = params.patent_band_um
    base = {"source": SOURCE, "patent_band_um": band}
    if slopes.empty:
        message = "no axis_positioning campaign passed validation: no axis model"
        LOGGER.warning(message)
        return {**base, "status": "no_axis_campaign", "message": message}, {}, pd.DataFrame()
    train = slopes[slopes["split"] == "train"]
    validation = slopes[slopes["split"] == "validation"]
    if train.empty:
        message = (
            f"no training axis campaign (split: train); validation campaign(s) "
            f"{_ids(validation)} cannot be scored: no axis model"
        )
        LOGGER.warning(message)
        return {**base, "status": "no_training_campaign", "message": message}, {}, pd.DataFrame()
    temperature = params.temperature
    candidates = candidate_sensors(train, list(params.exclude_sensors))
    selection = select_sensors(
        pass_features(train, candidates, temperature),
        pass_slopes(train),
        params.selection_rule,
        params.max_exhaustive,
    )
    model = CompositeModel(
        geometric=mean_geometric(geometric, _ids(train)),
        slope=fit_slope_model(train, selection.sensors, temperature),
    )
    scored = _scored(model, train, validation, thermal)
    points = pd.concat([p.assign(role=r) for r, p in scored.items()], ignore_index=True)
    scores = {role: bands(p) for role, p in scored.items()}
    report = {
        **base,
        "status": "ok" if "validation" in scored else "no_validation_campaign",
        "message": _message(scored, train),
        "synthetic": bool(slopes["synthetic"].any()),
        "axis": sorted(map(str, pd.unique(slopes["axis_name"]))),
        "training_campaigns": _ids(train),
        "validation_campaigns": _ids(validation),
        "temperature": temperature,
        "selection": _selection_report(params, candidates, selection),
        "slope_model": _slope_report(model),
        "geometric": {
            "from_campaigns": _ids(train),
            "order": len(model.geometric) - 1,
            "coefficients_um_per_mm_power": list(model.geometric),
        },
        "scores": scores,
    }
    if "validation" in scores:
        worst = scores["validation"]["overall"]["residual_max_abs_um"]
        report["within_patent_band"] = bool(worst <= band)
    return report, _metrics(scores, model), points


def _scored(
    model: CompositeModel, train: pd.DataFrame, validation: pd.DataFrame, thermal: pd.DataFrame
) -> dict[str, pd.DataFrame]:
    """Score the model on its training campaigns (``fit``) and the validation ones, if any."""
    scored = {"fit": score_campaigns(model, train, thermal)}
    if validation.empty:
        LOGGER.warning(
            "no validation axis campaign (split: validation): the composite model is scored on "
            "its training campaign(s) %s only",
            _ids(train),
        )
    else:
        scored["validation"] = score_campaigns(model, validation, thermal)
    return scored


def _message(scored: dict[str, pd.DataFrame], train: pd.DataFrame) -> str:
    if "validation" in scored:
        return "composite model fitted on the training campaign(s), validated on the others"
    return (
        f"no validation axis campaign (split: validation): scored on the training campaign(s) "
        f"{_ids(train)} only (fit, not validation)"
    )


def _selection_report(
    params: ModelAxisSettings, candidates: list[str], selection: Selection
) -> dict:
    return {
        "method": "best_subset",
        "rule": params.selection_rule,
        "candidates": candidates,
        "excluded": list(params.exclude_sensors),
        "selected": list(selection.sensors),
        "winners": criterion_winners(selection),
        "details": dict(selection.details),
        "best_of_each_size": json.loads(selection.evidence.to_json(orient="records")),
    }


def _slope_report(model: CompositeModel) -> dict:
    slope = model.slope
    unit = "um/mm per K" if slope.temperature == "rise" else "um/mm per degC"
    return {
        "equation": slope.equation(),
        "sensors": list(slope.sensors),
        "intercept_um_per_mm": slope.intercept,
        "coefficients": dict(zip(slope.sensors, slope.coefficients, strict=True)),
        "coefficients_unit": unit,
        "std_errors": dict(zip(("const", *slope.sensors), slope.std_errors, strict=True)),
        "p_values": dict(zip(("const", *slope.sensors), slope.p_values, strict=True)),
        "k0_um_per_mm": slope.k0,
        "r2": slope.r2,
        "adj_r2": slope.adj_r2,
        "f_pvalue": slope.f_pvalue,
        "n_passes": slope.n_passes,
    }


def _metrics(scores: dict, model: CompositeModel) -> dict[str, float | int]:
    fit = scores["fit"]["overall"]
    metrics: dict[str, float | int] = {
        "fit_rmse_um": fit["rmse_um"],
        "fit_residual_max_abs_um": fit["residual_max_abs_um"],
        "n_sensors": len(model.slope.sensors),
        "n_validation_points": 0,
    }
    if "validation" in scores:
        val = scores["validation"]["overall"]
        metrics.update(
            residual_max_abs_um=val["residual_max_abs_um"],
            residual_min_um=val["residual_min_um"],
            residual_max_um=val["residual_max_um"],
            rmse_um=val["rmse_um"],
            n_validation_points=val["n_points"],
        )
    return metrics


def _ids(slopes: pd.DataFrame) -> list[str]:
    return sorted(map(str, pd.unique(slopes["campaign_id"])))

"""DVC stage ``model_axis``: the linear-axis composite thermal-error model of the patent.

``thermal model-axis`` reads the axis separation tables (``data/separated/axis_*.parquet``),
selects the slope's temperature sensitive points by best subset on the training axis campaigns
(adjusted R^2 and AICc, both winners reported, ``model_axis.selection_rule`` decides), fits
k(T) by OLS, builds ``E(x, T) = P_geo(x) + (k(T) - k0) x`` (:mod:`pipeline.axis_model`) and
scores it on the training campaigns (fit) and the validation campaigns against the patent's
+-3.5 um. Writes ``reports/axis_model.json``, ``metrics/axis_model.json`` and
``reports/axis_model.png``; without axis campaigns it writes the three files saying so.
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pipeline import paths  # noqa: E402
from pipeline.axis_model import (  # noqa: E402
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
from pipeline.config import load_section  # noqa: E402
from pipeline.errors import MissingInputError  # noqa: E402
from pipeline.selection.result import Selection  # noqa: E402

LOGGER = logging.getLogger(__name__)

SOURCE = "the patent (seeds/002_391aae131e4de351.txt): sensitive points by best subset, eqs. 1-4"


def build(params: dict, slopes: pd.DataFrame, geometric: pd.DataFrame,
          thermal: pd.DataFrame) -> tuple[dict, dict, pd.DataFrame]:  # fmt: skip
    """Fit and score the composite model.

    Parameters
    ----------
    params : dict
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
        Scored points (:func:`pipeline.axis_model.score_campaigns`) plus ``role``
        ("fit" | "validation"); empty when nothing was modelled.
    """
    band = float(params["patent_band_um"])
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
    temperature = str(params["temperature"])
    candidates = candidate_sensors(train, params.get("exclude_sensors") or [])
    selection = select_sensors(
        pass_features(train, candidates, temperature),
        pass_slopes(train),
        str(params["selection_rule"]),
        int(params["max_exhaustive"]),
    )
    model = CompositeModel(
        geometric=mean_geometric(geometric, _ids(train)),
        slope=fit_slope_model(train, selection.sensors, temperature),
    )
    scored = {"fit": score_campaigns(model, train, thermal)}
    if validation.empty:
        LOGGER.warning(
            "no validation axis campaign (split: validation): the composite model is scored on "
            "its training campaign(s) %s only", _ids(train),
        )  # fmt: skip
    else:
        scored["validation"] = score_campaigns(model, validation, thermal)
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


def _message(scored: dict[str, pd.DataFrame], train: pd.DataFrame) -> str:
    if "validation" in scored:
        return "composite model fitted on the training campaign(s), validated on the others"
    return (
        f"no validation axis campaign (split: validation): scored on the training campaign(s) "
        f"{_ids(train)} only (fit, not validation)"
    )


def _selection_report(params: dict, candidates: list[str], selection: Selection) -> dict:
    return {
        "method": "best_subset",
        "rule": str(params["selection_rule"]),
        "candidates": candidates,
        "excluded": list(params.get("exclude_sensors") or []),
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


def plot(points: pd.DataFrame, report: dict, out: Path) -> None:
    """Measured vs composite error per pass, and the residuals, of each scored campaign.

    Validation campaigns are drawn when there are any, else the training campaigns (fit).

    Parameters
    ----------
    points : DataFrame
        Scored points with ``role`` (see :func:`build`).
    report : dict
        The report (title, status, patent band).
    out : Path
        PNG path; parent folders are created.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    if points.empty:
        fig, ax = plt.subplots(figsize=(7, 2.5))
        ax.axis("off")
        ax.text(0.5, 0.5, report["message"], ha="center", va="center", wrap=True)
        fig.savefig(out, dpi=110)
        plt.close(fig)
        return
    role = "validation" if (points["role"] == "validation").any() else "fit"
    shown = points[points["role"] == role]
    campaigns = sorted(pd.unique(shown["campaign_id"]))
    fig, axes = plt.subplots(2, len(campaigns), figsize=(7 * len(campaigns), 8), squeeze=False)
    band = report["patent_band_um"]
    for column, campaign_id in enumerate(campaigns):
        rows = shown[shown["campaign_id"] == campaign_id]
        _draw_campaign(axes[0, column], axes[1, column], rows, band)
        axes[0, column].set_title(f"{campaign_id} ({role}): measured (o) and composite (-)")
        axes[1, column].set_title(f"{campaign_id}: residual = measured - composite")
    kind = "SYNTHETIC data" if report.get("synthetic") else "measured data"
    fig.suptitle(
        f"Linear-axis composite model E = P_geo(x) + (k(T) - k0) x ({kind})\n"
        f"{report['slope_model']['equation']}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def _draw_campaign(top: plt.Axes, bottom: plt.Axes, rows: pd.DataFrame, band: float) -> None:
    colours = plt.cm.plasma(np.linspace(0, 0.85, rows["elapsed_min"].nunique()))
    for colour, (minute, group) in zip(colours, rows.groupby("elapsed_min"), strict=True):
        top.plot(group["target_mm"], group["measured_um"], "o", ms=3, color=colour)
        top.plot(group["target_mm"], group["predicted_um"], "-", color=colour,
                 label=f"{minute:g} min")  # fmt: skip
        bottom.plot(group["target_mm"], group["residual_um"], "o-", ms=3, color=colour,
                    label=f"{minute:g} min")  # fmt: skip
    for level in (-band, band):
        bottom.axhline(level, color="k", ls="--", lw=1)
    bottom.text(rows["target_mm"].min(), band, f" patent: +-{band:g} um", va="bottom", fontsize=7)
    top.set(xlabel="position (mm)", ylabel="positioning error (um)")
    bottom.set(xlabel="position (mm)", ylabel="residual (um)")
    top.legend(fontsize=7)
    bottom.legend(fontsize=7)


def _read(path: Path) -> pd.DataFrame:
    if not path.exists():
        raise MissingInputError(f"{path} not found; run the separate_axis stage first (dvc repro)")
    return pd.read_parquet(path)


def write(report: dict, metrics: dict, points: pd.DataFrame) -> None:
    """Write the report, the metrics and the figure to their :mod:`pipeline.paths` places."""
    for path, content in ((paths.AXIS_MODEL_REPORT, report), (paths.AXIS_MODEL_METRICS, metrics)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")
    plot(points, report, paths.AXIS_MODEL_PLOT)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``thermal model-axis`` with the ``model_axis`` section of params.yaml."""
    parser = argparse.ArgumentParser(prog="thermal model-axis", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    params = load_section("model_axis")
    report, metrics, points = build(
        params, _read(paths.AXIS_SLOPES), _read(paths.AXIS_GEOMETRIC),
        _read(paths.AXIS_THERMAL_ERROR),
    )  # fmt: skip
    write(report, metrics, points)
    if metrics.get("n_validation_points"):
        LOGGER.info(
            "axis model k on %s: validation residual %.2f to %.2f um (max |r| %.2f um, patent "
            "+-%g um), rmse %.2f um over %d points",
            report["selection"]["selected"], metrics["residual_min_um"],
            metrics["residual_max_um"], metrics["residual_max_abs_um"],
            report["patent_band_um"], metrics["rmse_um"], metrics["n_validation_points"],
        )  # fmt: skip
    return 0

"""Scores of the cross-season protocol (the PCDL paper, Miao et al. 2016, eq. 8 and tables 6-7).

A model built on training campaign Ki is applied to every campaign Kj. For each pair the residual
e = measured - predicted (um) gives

- the residual standard deviation S = sqrt(sum((e - mean(e))^2) / (n - 1)) (the paper's eq. 8;
  blind to a constant offset), and
- the root mean square RMS = sqrt(mean(e^2)) (not in the paper; it penalises offsets, which a
  compensation applied in another season does suffer).

Per training campaign: S on its own campaign (fit accuracy), Mn and Sd the mean and standard
deviation (ddof=1) of the scores on the *other* training campaigns (prediction accuracy and its
spread, the paper's 11 values per model), and Mn_val, Sd_val the same over the validation
campaigns. Overall: S is the mean of the per-campaign S, Mn and Sd the mean and standard
deviation of all pooled prediction scores (Mn_val, Sd_val likewise).

The **compensation ratio** (not in the paper) says how much of the error a compensation removes:
per scored campaign eta = 1 - RMS(residual) / RMS(uncompensated error), the uncompensated error
being the thermal error itself on the same samples (what the candidate ``none`` leaves); 1 is
perfect, 0 no better than no compensation, negative worse. Summarised over a set of campaigns
as eta = 1 - mean RMS(residual) / mean RMS(uncompensated), so that a candidate beats ``none`` by
a fraction f of its error exactly when its summary eta is at least f.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.protocol.units import SCHEMES

SCORE_COLUMNS = {"resid_std_um": "", "rmse_um": "_rms"}
SCHEME_PREFIX = {
    "campaign": "",
    "loso": "loso_",
    "loco": "loco_",
    "forward": "forward_",
    "pooled": "pooled_",
}
"""Column prefix of each scheme's summary in :func:`candidate_summary`."""


def residual_std(residual: np.ndarray) -> float:
    """Residual standard deviation, um (ddof=1); NaN with fewer than two finite residuals.

    Parameters
    ----------
    residual : ndarray of shape (n,)
        Measured minus predicted, um; NaN entries are ignored.
    """
    finite = residual[np.isfinite(residual)]
    return float(np.std(finite, ddof=1)) if finite.size >= 2 else float("nan")


def compensation_ratio(rms_residual_um: float, rms_uncompensated_um: float) -> float:
    """Return eta = 1 - RMS(residual) / RMS(uncompensated error); NaN if the latter is not > 0."""
    if not np.isfinite(rms_uncompensated_um) or rms_uncompensated_um <= 0:
        return float("nan")
    return 1.0 - float(rms_residual_um) / float(rms_uncompensated_um)


def _mean(values: np.ndarray) -> float:
    """Mean of the non-NaN values; NaN when there is none."""
    finite = values[~np.isnan(values)]
    return float(finite.mean()) if finite.size else float("nan")


def _mean_sd(values: np.ndarray) -> tuple[float, float]:
    """:func:`_mean` and the standard deviation (ddof=1; NaN with fewer than two values)."""
    finite = values[~np.isnan(values)]
    spread = float(finite.std(ddof=1)) if finite.size >= 2 else float("nan")
    return _mean(finite), spread


def summarise(scores: pd.DataFrame) -> dict[str, float]:
    """S, Mn, Sd, Mn_val, Sd_val (residual std) and their ``_rms`` twins for a set of score rows.

    Parameters
    ----------
    scores : DataFrame
        Rows of the long score table (columns ``role`` in {"fit", "prediction",
        "validation"}, ``resid_std_um``, ``rmse_um``) for one candidate and scheme; one or many
        training units.

    Returns
    -------
    dict of str to float
        Keys ``S_um``, ``Mn_um``, ``Sd_um``, ``Mn_val_um``, ``Sd_val_um`` and the same with
        ``_rms`` before ``_um``, all in um; ``eta`` and ``eta_val``, the compensation ratio
        over the prediction and the validation rows (needs ``uncompensated_rms_um``).
    """
    role = scores["role"].to_numpy(dtype=object)
    rows = {name: role == name for name in ("fit", "prediction", "validation")}
    summary: dict[str, float] = {}
    for column, suffix in SCORE_COLUMNS.items():
        values = scores[column].to_numpy(dtype=float)
        summary[f"S{suffix}_um"] = _mean(values[rows["fit"]])
        mn, sd = _mean_sd(values[rows["prediction"]])
        summary[f"Mn{suffix}_um"], summary[f"Sd{suffix}_um"] = mn, sd
        mn_val, sd_val = _mean_sd(values[rows["validation"]])
        summary[f"Mn_val{suffix}_um"], summary[f"Sd_val{suffix}_um"] = mn_val, sd_val
    if "uncompensated_rms_um" in scores:
        rms = scores["rmse_um"].to_numpy(dtype=float)
        uncompensated = scores["uncompensated_rms_um"].to_numpy(dtype=float)
        for name, key in (("prediction", "eta"), ("validation", "eta_val")):
            scored = rows[name] & ~np.isnan(rms)
            summary[key] = (
                compensation_ratio(_mean(rms[scored]), _mean(uncompensated[scored]))
                if scored.any()
                else float("nan")
            )
    return summary


CANDIDATE_KEYS = ["axis", "model", "selection", "mode"]


def metrics_tree(scores: pd.DataFrame) -> dict:
    """Nest each candidate's scores as ``{axis: {model: {selection: {mode: {...}}}}}``.

    A candidate's entry holds its overall scores under the names of the
    :func:`candidate_summary` columns (``S_um``, ``loso_Mn_rms_um``, ``pooled_eta_val``...: the
    one name a score has in ``model_scores.csv``, ``metrics/`` and MLflow) and ``by_train_unit``:
    one summary per training unit (a training campaign, a left-out season or campaign, or the
    pooled unit), named the same way (e.g. ``by_train_unit.not_winter.loso_Mn_rms_um``).

    Parameters
    ----------
    scores : DataFrame
        The whole long score table (``schemas.CrossSeasonScoresModel``).
    """
    tree: dict = {}
    for (axis, model, selection, mode, scheme), group in scores.groupby(
        [*CANDIDATE_KEYS, "scheme"], sort=True
    ):
        entry = (
            tree.setdefault(axis, {})
            .setdefault(model, {})
            .setdefault(selection, {})
            .setdefault(mode, {})
        )
        prefix = SCHEME_PREFIX[scheme]
        entry.update({prefix + key: value for key, value in summarise(group).items()})
        units = entry.setdefault("by_train_unit", {})
        for unit, rows in group.groupby("train_unit", sort=True):
            units[str(unit)] = {prefix + key: value for key, value in summarise(rows).items()}
    return tree


REFERENCE_MODEL = "none"
PAIR = ["axis", "scheme", "train_unit", "test_campaign"]


def coverage(part: pd.DataFrame, reference: pd.DataFrame) -> float:
    """Share of the reference's prediction samples a candidate predicted too (0 to 1).

    Parameters
    ----------
    part : DataFrame
        One candidate's score rows of one scheme.
    reference : DataFrame
        ``none``'s score rows of the same axis and scheme.

    Returns
    -------
    float
        Sum over ``none``'s (training unit, campaign) pairs of role ``prediction`` of
        min(candidate samples, none's samples), over the sum of none's samples: a campaign the
        candidate could not predict (an input missing there) counts 0. NaN without reference.
    """
    wanted = reference[reference["role"] == "prediction"].set_index(PAIR)["n_samples"]
    if wanted.empty:
        return float("nan")
    got = part[part["role"] == "prediction"].set_index(PAIR)["n_samples"].reindex(wanted.index)
    return float(np.minimum(got.fillna(0).to_numpy(), wanted.to_numpy()).sum() / wanted.sum())


def candidate_summary(scores: pd.DataFrame) -> pd.DataFrame:
    """One row per (axis, model, selection, mode): the overall scores of every scheme.

    Columns are the candidate keys, then ``S_um``, ``Mn_um``... of the ``campaign`` scheme (the
    PCDL paper's protocol), ``loso_`` or ``loco_`` + the same for leave-one-season-out or
    leave-one-campaign-out, ``forward_`` + the same for the rolling origin (each campaign
    predicted by the campaigns that ended before it) and ``pooled_`` + the same for the model
    built on all training campaigns; all in um (``eta``: dimensionless); ``<prefix>coverage``,
    the share of the held-out samples ``none`` was scored on that the candidate predicted too
    (:func:`coverage`; when ``none`` was scored).
    """
    reference = dict(
        iter(scores[scores["model"] == REFERENCE_MODEL].groupby(["axis", "scheme"], sort=False))
    )
    parts: dict[tuple, dict[str, pd.DataFrame]] = {}
    for (*keys, scheme), part in scores.groupby([*CANDIDATE_KEYS, "scheme"], sort=True):
        parts.setdefault(tuple(keys), {})[scheme] = part
    rows = []
    for keys, by_scheme in parts.items():
        row = dict(zip(CANDIDATE_KEYS, keys, strict=True))
        for scheme in (s for s in SCHEMES if s in by_scheme):
            prefix, part = SCHEME_PREFIX[scheme], by_scheme[scheme]
            row.update({prefix + key: value for key, value in summarise(part).items()})
            mine = reference.get((row["axis"], scheme))
            if mine is not None:
                row[f"{prefix}coverage"] = coverage(part, mine)
        rows.append(row)
    return pd.DataFrame(rows)


def score_matrix(scores: pd.DataFrame, column: str) -> pd.DataFrame:
    """Training unit x test campaign matrix of one score column (um) for one candidate.

    Rows are training units in the order they appear, columns the training campaigns then the
    validation ones.
    """
    order = list(
        dict.fromkeys(
            scores.sort_values(["test_split", "test_campaign"], key=_split_order)["test_campaign"]
        )
    )
    units = list(dict.fromkeys(scores["train_unit"]))
    matrix = scores.pivot_table(
        index="train_unit", columns="test_campaign", values=column, aggfunc="first"
    )
    return matrix.reindex(index=units, columns=order)


def _split_order(column: pd.Series) -> pd.Series:
    return column.map({"train": 0, "validation": 1}) if column.name == "test_split" else column


HELD_OUT_PREFIXES = ("not_", "before_")
"""Training units of the held-out schemes are named ``not_<season>``, ``not_<campaign>`` or
``before_<campaign>`` (forward)."""
GROUP_COLUMNS = [*CANDIDATE_KEYS, "scheme", "split", "held_out"]


def group_score_name(scheme: str, split: str, held_out: str, statistic: str) -> str:
    """Name of a per-held-out-group score, e.g. ``loso_winter_rms_um`` or ``pooled_val_K13_eta``.

    Parameters
    ----------
    scheme : str
        ``loso``, ``loco`` (the group left out of training), ``forward`` (the campaign forecast
        by the campaigns before it) or ``pooled`` (the fit on all training campaigns, applied
        to the validation campaigns).
    split : str
        ``train`` (a held-out training season or campaign) or ``validation``.
    held_out : str
        Season (``loso`` and validation) or campaign id (``loco``, ``forward``).
    statistic : str
        ``rms_um`` (mean RMS of the residual over the group's campaigns, um) or ``eta``.
    """
    middle = "val_" if split == "validation" else ""
    return f"{SCHEME_PREFIX[scheme]}{middle}{held_out}_{statistic}"


def group_scores(scores: pd.DataFrame) -> pd.DataFrame:
    """Held-out scores per season (or campaign): how well each candidate predicts, e.g., winter.

    Groups, per candidate: for leave-one-season-out (``loso``) each season, for
    leave-one-campaign-out (``loco``) and the rolling origin (``forward``) each campaign, scored
    by the fit that did not see it (rows of role ``prediction``); for the fit on all training
    campaigns (``pooled``) the validation campaigns of each season (role ``validation``).

    Parameters
    ----------
    scores : DataFrame
        The long score table (``schemas.CrossSeasonScoresModel``).

    Returns
    -------
    DataFrame
        Columns ``axis``, ``model``, ``selection``, ``mode``, ``scheme``, ``split``,
        ``held_out``, ``n_campaigns``, ``rms_um`` (mean RMS of the residual over the group's
        campaigns, um), ``uncompensated_rms_um`` (the same for the error itself, um), ``eta``
        (1 - their ratio, as :func:`summarise`) and ``name`` (:func:`group_score_name` of
        ``rms_um``); one row per group.
    """
    held = scores[
        scores["scheme"].isin(["loso", "loco", "forward"]) & (scores["role"] == "prediction")
    ]
    names = held["train_unit"]
    for prefix in HELD_OUT_PREFIXES:
        names = names.str.removeprefix(prefix)
    held = held.assign(split="train", held_out=names)
    val = scores[(scores["scheme"] == "pooled") & (scores["role"] == "validation")]
    val = val.assign(split="validation", held_out=val["test_season"])
    rows = []
    for keys, group in pd.concat([held, val]).groupby(GROUP_COLUMNS, sort=True):
        finite = group[group["rmse_um"].notna()]
        rms = float(finite["rmse_um"].mean()) if len(finite) else float("nan")
        raw = float(finite["uncompensated_rms_um"].mean()) if len(finite) else float("nan")
        row = dict(zip(GROUP_COLUMNS, keys, strict=True))
        rows.append(
            {
                **row,
                "n_campaigns": int(group["test_campaign"].nunique()),
                "rms_um": rms,
                "uncompensated_rms_um": raw,
                "eta": compensation_ratio(rms, raw),
                "name": group_score_name(row["scheme"], row["split"], row["held_out"], "rms_um"),
            }
        )
    columns = [*GROUP_COLUMNS, "n_campaigns", "rms_um", "uncompensated_rms_um", "eta", "name"]
    return pd.DataFrame(rows, columns=columns)

"""Where the twin and the measurements disagree: residuals by phase, speed and ambient trend.

Residual = measured - twin, for the displacement Z (um, drift since the first sample) and for
each temperature sensor the twin reads (K). A positive Z residual means the twin
*under-predicts* Z (the measured value is above the twin's), a negative one that it
over-predicts.

Phases are defined from the spindle speed at the sample instants alone (``rpm``, zero-order
hold), so they work on any campaign:

``rest``
    rpm = 0 before the spindle has run in this campaign.
``warm-up``
    rpm > 0 within ``warmup_min`` after a start from rest (0 -> n).
``speed change``
    rpm > 0 within ``transient_min`` after a change between two non-zero speeds.
``steady``
    rpm > 0 otherwise (the machine near its running equilibrium).
``cool-down``
    rpm = 0 after the spindle has run.

The noise floor of a signal is estimated from the data: the robust standard deviation of its
first differences (1.4826 x median absolute deviation about their median) divided by sqrt(2),
which removes a slow drift and keeps white noise; a quantised signal whose differences are
mostly zero falls back to the trimmed standard deviation of the differences.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from pipeline.fit_statistics import root_mean_square
from pipeline.settings.discrepancy import LocaliseSettings

logger = logging.getLogger(__name__)

PHASES = ("rest", "warm-up", "steady", "speed change", "cool-down")
"""Phase labels in the order a test runs through them."""

Z_SIGNAL = "Z"
"""Signal name of the displacement in the residual tables."""


def phase_labels(
    t_s: np.ndarray, rpm: np.ndarray, warmup_min: float = 60.0, transient_min: float = 30.0
) -> np.ndarray:
    """Label each sample with its phase (see the module docstring).

    Parameters
    ----------
    t_s : ndarray of shape (n,), s
        Sample instants, increasing.
    rpm : ndarray of shape (n,), rpm
        Spindle speed at the sample instants (zero-order hold).
    warmup_min, transient_min : float
        Lengths of the warm-up and speed-change windows, min.

    Returns
    -------
    ndarray of shape (n,), object
        One of :data:`PHASES` per sample.
    """
    t = np.asarray(t_s, dtype=float)
    speed = np.abs(np.asarray(rpm, dtype=float))
    if t.shape != speed.shape:
        raise ValueError(f"t_s has shape {t.shape} but rpm {speed.shape}; give one rpm per sample")
    labels = np.empty(t.size, dtype=object)
    has_run = False
    kind = None  # what the last change was: "start" or "change"
    since = -np.inf  # instant of the last change, s
    previous = 0.0
    for i, (ti, ni) in enumerate(zip(t, speed, strict=True)):
        if i > 0 and ni != previous:
            since = ti
            kind = "start" if previous == 0 else "change"
        elif i == 0 and ni > 0:
            since, kind = ti, "start"
        if ni == 0:
            labels[i] = "cool-down" if has_run else "rest"
        else:
            has_run = True
            elapsed_min = (ti - since) / 60.0
            if kind == "start" and elapsed_min < warmup_min:
                labels[i] = "warm-up"
            elif kind == "change" and elapsed_min < transient_min:
                labels[i] = "speed change"
            else:
                labels[i] = "steady"
        previous = ni
    return labels


def noise_floor(values: np.ndarray) -> float:
    """White-noise level of a slowly varying signal, in its own unit.

    ``1.4826 MAD(diff(x)) / sqrt(2)``; when more than half the differences are equal (a
    quantised, quiet signal) the standard deviation of the differences between their 5th and
    95th percentiles is used instead. NaNs are ignored.

    Parameters
    ----------
    values : ndarray of shape (n,)

    Returns
    -------
    float
        Standard deviation of the noise; NaN with fewer than 3 finite values.
    """
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 3:
        return float("nan")
    d = np.diff(x)
    centred = d - np.median(d)
    mad = 1.4826 * float(np.median(np.abs(centred)))
    if mad == 0.0:
        lo, hi = np.percentile(centred, [5, 95])
        kept = centred[(centred >= lo) & (centred <= hi)]
        mad = float(np.std(kept)) if kept.size > 1 else 0.0
    return mad / np.sqrt(2.0)


def _speed_level(rpm: np.ndarray) -> np.ndarray:
    """Speed rounded to 100 rpm (the level a sample belongs to)."""
    return np.round(np.abs(np.asarray(rpm, dtype=float)) / 100.0) * 100.0


def residual_frame(
    campaign_id: str,
    t_s: np.ndarray,
    rpm: np.ndarray,
    z_residual_um: np.ndarray,
    t_residual_k: pd.DataFrame,
    roles: Mapping[str, str],
    settings: LocaliseSettings,
) -> pd.DataFrame:
    """Long table of one campaign's residuals, one row per sample and signal.

    Parameters
    ----------
    campaign_id : str
    t_s, rpm : ndarray of shape (n,)
        Sample instants (s) and spindle speed (rpm).
    z_residual_um : ndarray of shape (n,), um
        Measured minus twin Z.
    t_residual_k : DataFrame of shape (n, sensors), K
        Measured minus twin temperature of every sensor the twin reads.
    roles : mapping
        Sensor name -> role.
    settings : LocaliseSettings

    Returns
    -------
    DataFrame
        ``campaign_id, elapsed_min, rpm, phase, speed_rpm, signal, role, unit, residual``.
    """
    phase = phase_labels(t_s, rpm, settings.warmup_min, settings.transient_min)
    base = pd.DataFrame(
        {
            "campaign_id": campaign_id,
            "elapsed_min": np.asarray(t_s, dtype=float) / 60.0,
            "rpm": np.asarray(rpm, dtype=float),
            "phase": phase,
            "speed_rpm": _speed_level(rpm),
        }
    )
    parts = [base.assign(signal=Z_SIGNAL, role="displacement", unit="um", residual=z_residual_um)]
    for sensor in t_residual_k.columns:
        parts.append(
            base.assign(
                signal=str(sensor),
                role=roles.get(sensor, "other"),
                unit="K",
                residual=t_residual_k[sensor].to_numpy(dtype=float),
            )
        )
    return pd.concat(parts, ignore_index=True)


def summarise(residuals: pd.DataFrame, floors: Mapping[str, float]) -> pd.DataFrame:
    """Tidy summary: mean and RMS residual by signal and phase, and by signal and speed level.

    Parameters
    ----------
    residuals : DataFrame
        Concatenated :func:`residual_frame` outputs.
    floors : mapping
        Signal -> noise floor in the signal's unit.

    Returns
    -------
    DataFrame
        ``signal, role, unit, split ("phase" | "speed" | "all"), level, n, n_campaigns,
        mean, rms, noise_floor, rms_over_floor``.
    """
    rows = []
    for split, column in (("all", None), ("phase", "phase"), ("speed", "speed_rpm")):
        keys = ["signal", "role", "unit"] + ([column] if column else [])
        for key, group in residuals.groupby(keys, sort=False):
            signal, role, unit = key[:3]
            level = "all" if column is None else key[3]
            if column == "speed_rpm":
                level = f"{float(level):.0f} rpm"
            floor = float(floors.get(signal, np.nan))
            rms = root_mean_square(group["residual"])
            rows.append(
                {
                    "signal": signal,
                    "role": role,
                    "unit": unit,
                    "split": split,
                    "level": str(level),
                    "n": int(group["residual"].notna().sum()),
                    "n_campaigns": int(group["campaign_id"].nunique()),
                    "mean": float(group["residual"].mean()),
                    "rms": rms,
                    "noise_floor": floor,
                    "rms_over_floor": rms / floor if floor > 0 else float("nan"),
                }
            )
    return pd.DataFrame(rows)


def ambient_lag(
    residual_by_campaign: Mapping[str, np.ndarray],
    ambient_by_campaign: Mapping[str, np.ndarray],
    t_s_by_campaign: Mapping[str, np.ndarray],
    max_lag_min: float = 120.0,
) -> tuple[float, float]:
    """Correlation of a residual with the ambient trend and the lag that maximises it.

    For each lag L (multiples of the sampling interval up to ``max_lag_min``), the residual
    at t is paired with the ambient rise (reading minus its first value) at t - L, within each
    campaign; both are centred per campaign and pooled.

    Returns
    -------
    tuple of float
        ``(correlation, lag_min)`` at the lag of largest |correlation|; ``(nan, nan)`` when no
        campaign has an ambient series.
    """
    ids = [c for c in residual_by_campaign if c in ambient_by_campaign]
    if not ids:
        return float("nan"), float("nan")
    dt = np.median(np.concatenate([np.diff(np.asarray(t_s_by_campaign[c])) for c in ids]))
    n_lags = int(max_lag_min * 60.0 / dt) if dt > 0 else 0
    best = (float("nan"), float("nan"))
    for k in range(n_lags + 1):
        xs, ys = [], []
        for c in ids:
            r = np.asarray(residual_by_campaign[c], dtype=float)
            a = np.asarray(ambient_by_campaign[c], dtype=float)
            a = a - a[np.isfinite(a)][0] if np.isfinite(a).any() else a
            if r.size - k < 5:
                continue
            x, y = r[k:], a[: a.size - k]
            ok = np.isfinite(x) & np.isfinite(y)
            xs.append(x[ok] - x[ok].mean())
            ys.append(y[ok] - y[ok].mean())
        if not xs:
            break
        x, y = np.concatenate(xs), np.concatenate(ys)
        denom = np.sqrt(np.sum(x**2) * np.sum(y**2))
        if denom == 0:
            continue
        rho = float(np.sum(x * y) / denom)
        if not np.isfinite(best[0]) or abs(rho) > abs(best[0]):
            best = (rho, k * dt / 60.0)
    return best


@dataclass(frozen=True)
class Localisation:
    """Where the twin disagrees with the measurements.

    Attributes
    ----------
    table : DataFrame
        :func:`summarise` output.
    ambient_correlation : float
        Correlation of the Z residual with the ambient rise at ``ambient_lag_min``; NaN
        without an ambient sensor.
    ambient_lag_min : float
        Lag of the ambient trend that best matches the Z residual, min.
    findings : list of str
        Plain-language sentences, largest disagreement first.
    """

    table: pd.DataFrame
    ambient_correlation: float
    ambient_lag_min: float
    findings: list[str]


def _direction(mean: float) -> str:
    return "under-predicts" if mean > 0 else "over-predicts"


def localise(
    campaigns: Sequence,
    z_residual_um: Mapping[str, np.ndarray],
    t_residual_k: Mapping[str, pd.DataFrame],
    settings: LocaliseSettings | None = None,
    label: str = "the twin",
) -> Localisation:
    """Split the residuals of a calibrated twin and describe where they are large.

    Parameters
    ----------
    campaigns : sequence of MeasuredCampaign
        Supplies ``campaign_id``, ``t_s``, ``rpm``, ``temperatures``, ``roles``, ``z_um``.
    z_residual_um : mapping
        Campaign id -> measured minus twin Z, ndarray (n,), um.
    t_residual_k : mapping
        Campaign id -> measured minus twin temperatures, DataFrame (n, sensors), K.
    settings : LocaliseSettings, optional
    label : str
        How the model is named in the findings.

    Returns
    -------
    Localisation
    """
    settings = settings or LocaliseSettings()
    frames, floors_z, floors_t, ambient, t_map = [], [], {}, {}, {}
    for c in campaigns:
        cid = c.campaign_id
        if cid not in z_residual_um:
            continue
        t_res = t_residual_k.get(cid, pd.DataFrame(index=range(len(c.t_s))))
        frames.append(
            residual_frame(cid, c.t_s, c.rpm, z_residual_um[cid], t_res, c.roles, settings)
        )
        floors_z.append(noise_floor(c.z_um))
        for sensor in t_res.columns:
            if sensor in c.temperatures:
                floors_t.setdefault(sensor, []).append(noise_floor(c.temperatures[sensor]))
        amb = [s for s, r in c.roles.items() if r == "ambient" and s in c.temperatures]
        if amb:
            ambient[cid] = c.temperatures[amb[0]].to_numpy(dtype=float)
        t_map[cid] = np.asarray(c.t_s, dtype=float)
    if not frames:
        raise ValueError("localise: no campaign has residuals; calibrate the twin first")
    residuals = pd.concat(frames, ignore_index=True)
    floors = {Z_SIGNAL: float(np.nanmedian(floors_z))}
    floors.update({s: float(np.nanmedian(v)) for s, v in floors_t.items()})
    table = summarise(residuals, floors)
    rho, lag = ambient_lag(z_residual_um, ambient, t_map, settings.max_lag_min)
    findings = _findings(table, rho, lag, settings, label)
    return Localisation(table, rho, lag, findings)


def _findings(
    table: pd.DataFrame, rho: float, lag: float, settings: LocaliseSettings, label: str
) -> list[str]:
    """Plain-language sentences about the largest disagreements."""
    out: list[str] = []
    z = table[table["signal"] == Z_SIGNAL]
    overall = z[z["split"] == "all"].iloc[0]
    floor = overall["noise_floor"]
    out.append(
        f"overall, {label} misses the measured Z drift by {overall['rms']:.1f} um RMS "
        f"(noise floor of the probe {floor:.2f} um, {overall['n_campaigns']} campaigns)"
    )
    for split, what in (("phase", "during {}"), ("speed", "at {}")):
        rows = z[z["split"] == split]
        big = rows[np.abs(rows["mean"]) > settings.min_floor_ratio * floor]
        for _, row in big.reindex(big["mean"].abs().sort_values(ascending=False).index).iterrows():
            out.append(
                f"{label} {_direction(row['mean'])} the drift {what.format(row['level'])} by "
                f"{abs(row['mean']):.1f} um on average (RMS {row['rms']:.1f} um, "
                f"{row['n']} samples)"
            )
    speeds = z[z["split"] == "speed"]
    running = speeds[speeds["level"] != "0 rpm"]
    if len(running) >= 2:
        order = running.assign(v=running["level"].str.split().str[0].astype(float)).sort_values("v")
        rms = order["rms"].to_numpy()
        if np.all(np.diff(rms) > 0) and rms[-1] > 2 * rms[0]:
            parts = ", ".join(
                f"{r:.1f} um at {lv}" for r, lv in zip(rms, order["level"], strict=True)
            )
            out.append(f"the Z residual grows with the spindle speed ({parts} RMS)")
    if np.isfinite(rho) and abs(rho) >= settings.min_correlation:
        sign = "follows" if rho > 0 else "mirrors"
        out.append(
            f"the Z residual {sign} the ambient temperature with a {lag:.0f} min lag "
            f"(correlation {rho:+.2f})"
        )
    temps = table[(table["unit"] == "K") & (table["split"] == "phase")]
    temps = temps[np.isfinite(temps["rms_over_floor"].to_numpy(dtype=float))]
    if len(temps):
        worst = temps.loc[temps["rms_over_floor"].idxmax()]
        if worst["rms_over_floor"] > settings.min_floor_ratio:
            out.append(
                f"the largest temperature misfit is sensor {worst['signal']} ({worst['role']}) "
                f"during {worst['level']}: {label} {_direction(worst['mean'])} it by "
                f"{abs(worst['mean']):.2f} K on average (RMS {worst['rms']:.2f} K, "
                f"{worst['rms_over_floor']:.0f} x its noise floor)"
            )
    if len(out) == 1 and overall["rms"] <= settings.min_floor_ratio * floor:
        out.append(f"the Z residual of {label} is within {settings.min_floor_ratio:g} noise floors")
    return out

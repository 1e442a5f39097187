"""A small machine for the compensation tests: campaigns, a fitted bundle with fallbacks.

Three sensors and a spindle: T1 and T2 follow the spindle's heat with their own lags, T3 the
ambient; the thermal error is linear in the rises of T1 and T2 and in a speed response. The
champion is the distributed-lag model ``dl`` (lags of its inputs, so the runtime's incremental
preparation is exercised), fitted on four campaigns with the training code
(:func:`pipeline.separation.features.model_inputs`); one fallback per sensor.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from pipeline.compensation.bundle import AxisBundle, InputChecks, ModelEntry
from pipeline.models.registry import make_model
from pipeline.protocol.serving import predict_table
from pipeline.separation.features import InputSpec, SpeedResponses, model_inputs

SENSORS = ("T1", "T2", "T3")
SPEED = SpeedResponses((30.0,), (1.0,))
SPEC = InputSpec((*SENSORS, "speed_lag_30min"), "temperature_rise", "first_sample", 1, SPEED, 60.0)


def _lag(t: np.ndarray, drive: np.ndarray, tau_s: float) -> np.ndarray:
    out = np.zeros_like(drive)
    for k in range(1, len(t)):
        a = np.exp(-(t[k] - t[k - 1]) / tau_s)
        out[k] = out[k - 1] * a + drive[k - 1] * (1 - a)
    return out


def campaign(seed: int, n: int = 150, interval_s: float = 60.0) -> pd.DataFrame:
    """One campaign: ``elapsed_s``, ``rpm``, T1-T3 (degC), ``thermal_error_um``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * interval_s
    levels = rng.choice([2000.0, 4000.0, 6000.0], size=3)
    rpm = np.select([t < n * interval_s / 3, t < 2 * n * interval_s / 3], levels[:2], levels[2])
    rpm[t > 0.85 * n * interval_s] = 0.0
    krpm = rpm / 1000.0
    ambient = 20.0 + rng.normal(0, 1.5) + 0.4 * np.sin(t / 7200.0 + rng.uniform(0, 6))
    t1 = ambient + 1.2 * _lag(t, krpm, 1200.0) + rng.normal(0, 0.02, n)
    t2 = ambient + 0.6 * _lag(t, krpm, 2400.0) + rng.normal(0, 0.02, n)
    t3 = ambient + rng.normal(0, 0.02, n)
    rise = lambda x: x - x[0]  # noqa: E731
    error = -3.0 * rise(t1) - 2.0 * rise(t2) - 1.5 * _lag(t, krpm, 1800.0) + rng.normal(0, 0.1, n)
    return pd.DataFrame(
        {"elapsed_s": t, "rpm": rpm, "T1": t1, "T2": t2, "T3": t3, "thermal_error_um": error}
    )


def campaigns(seeds=(1, 2, 3, 4)) -> pd.DataFrame:
    """Several campaigns in one table, ``campaign_id`` C<seed>."""
    return pd.concat(
        [campaign(seed).assign(campaign_id=f"C{seed}") for seed in seeds], ignore_index=True
    )


def _fit(table: pd.DataFrame, spec: InputSpec, model: str):
    X = model_inputs(table, spec)
    keep = X.notna().all(axis=1).to_numpy()
    return make_model(model).fit(X[keep], table["thermal_error_um"].to_numpy()[keep])


def fitted_bundle(model: str = "dl", seeds=(1, 2, 3, 4)) -> AxisBundle:
    """The bundle of axis Z: ``model`` on every input, one fallback without each sensor."""
    table = campaigns(seeds)
    champion = ModelEntry("champion", SPEC, _fit(table, SPEC, model))
    fallbacks = []
    for sensor in SENSORS:
        spec = replace(SPEC, inputs=tuple(i for i in SPEC.inputs if i != sensor))
        fallbacks.append(ModelEntry(f"without_{sensor}", spec, _fit(table, spec, model)))
    X = model_inputs(table, replace(SPEC, inputs=SENSORS))
    ranges = {f"rise_{s}": (float(X[s].min()), float(X[s].max())) for s in SENSORS}
    card = {"axis": "Z", "model": model, "selection": "test", "mode": "static", "compensate": True}
    return AxisBundle("Z", card, champion, tuple(fallbacks), ranges, InputChecks())


def offline_prediction(bundle: AxisBundle, table: pd.DataFrame, entry: str = "champion"):
    """The offline prediction (um) of a whole campaign by one of the bundle's models."""
    model = next(e for e in (bundle.champion, *bundle.fallbacks) if e.name == entry)
    return predict_table(model.estimator, table, model.spec)

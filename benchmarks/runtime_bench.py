"""Time the compensation runtime's prediction of one cycle as the run grows (``make bench``).

Every cycle the runtime predicts the thermal error at the newest reading from the run so far
(:func:`pipeline.compensation.axis.predict_latest`, which calls
:func:`pipeline.protocol.serving.predict_run`: windows, model inputs, the estimator). The
replay proof of the ``compensation`` stage runs one cycle per sample of every held-out campaign,
so this time, times the samples, is most of that stage. Measured here on the workshop twin's
46-h run (20-s samples, 16 sensors, the speed responses, 60-s windows) with a linear regression
on every input, after 1 h, 8 h and 32 h of the run.
"""

from __future__ import annotations

import time

from sklearn.linear_model import LinearRegression

from pipeline.protocol.serving import predict_run
from pipeline.separation.features import InputSpec, SpeedResponses, model_inputs, resample
from pipeline.twin.cli import WORKSHOP_SEED
from pipeline.twin.workshop import WORKSHOP_SENSORS, simulate_workshop, workshop_plan

HISTORY_SAMPLES = (180, 1440, 5760)
"""Run lengths timed, in 20-s samples: 1 h, 8 h and 32 h."""


def cycle_times(samples: tuple[int, ...] = HISTORY_SAMPLES, repeats: int = 20) -> list[dict]:
    """Return the mean time of one cycle's prediction after each run length.

    Parameters
    ----------
    samples : tuple of int
        Run lengths, in samples of the workshop run (20 s each).
    repeats : int
        Predictions timed per length.

    Returns
    -------
    list of dict
        ``samples``, ``hours`` and ``ms_per_cycle`` (mean wall time of one prediction, ms).
    """
    run = simulate_workshop(workshop_plan(), seed=WORKSHOP_SEED)
    sensors = [sensor.name for sensor in WORKSHOP_SENSORS]
    table = run.truth[["elapsed_s", "rpm", *sensors]]
    speed = SpeedResponses()
    spec = InputSpec((*sensors, *speed.names()), "temperature_rise", "first_sample", 1, speed, 60.0)
    inputs = model_inputs(resample(table.assign(campaign_id="run"), spec.resample_s), spec)
    estimator = LinearRegression().fit(inputs, inputs.to_numpy().sum(axis=1))
    times = []
    t_s, rpm, temperatures = (
        table["elapsed_s"].to_numpy(),
        table["rpm"].to_numpy(),
        table[sensors].to_numpy(),
    )
    for n in samples:
        begin = time.perf_counter()
        for _ in range(repeats):
            predict_run(estimator, t_s[:n], temperatures[:n], rpm[:n], spec)
        elapsed = (time.perf_counter() - begin) / repeats
        hours = n * run.plan.interval_s / 3600.0
        times.append({"samples": n, "hours": hours, "ms_per_cycle": 1e3 * elapsed})
    return times


def report_lines(times: list[dict]) -> list[str]:
    """Human-readable lines of :func:`cycle_times`."""
    lines = [f"{'run so far':>12}{'samples':>9}{'ms per cycle':>14}"]
    lines += [f"{t['hours']:>10.1f} h{t['samples']:>9d}{t['ms_per_cycle']:>14.2f}" for t in times]
    return lines

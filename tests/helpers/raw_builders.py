"""Write small campaign folders in the raw contract for tests (no twin needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml


def write_spindle_campaign(
    raw: Path,
    campaign_id: str,
    *,
    n: int = 40,
    interval_s: float = 180.0,
    rpm: float = 4000.0,
    gains: tuple[float, ...] = (3.0, -1.5, 0.5),
    ambient: float = 20.0,
    seed: int = 0,
    split: str = "train",
    displacement_offset_s: float = 0.0,
    ambient_rise: float = 0.0,
) -> Path:
    """A spindle-drift campaign whose Z drift is exactly ``sum(gains * rise)`` (um).

    The ambient sensor (last) reads ``ambient`` degC, rising linearly by ``ambient_rise`` K
    over the campaign (0: constant, which the stuck-sensor check of params.yaml flags).
    """
    rng = np.random.default_rng(seed)
    folder = raw / campaign_id
    folder.mkdir(parents=True)
    t = np.arange(n) * interval_s
    sensors = {f"T{i + 1}": {"role": "other", "type": "DS18B20"} for i in range(len(gains))}
    sensors[f"T{len(gains) + 1}"] = {"role": "ambient", "type": "DS18B20"}
    meta = {
        "campaign_id": campaign_id,
        "kind": "spindle_drift",
        "machine": "test",
        "start": "2015-01-12T08:30:00",
        "synthetic": True,
        "split": split,
        "spindle_program": [
            {"from_min": 0, "to_min": n * interval_s / 120, "rpm": rpm},
            {"from_min": n * interval_s / 120, "rpm": 0},
        ],
        "sensors": sensors,
        "displacement": {"Z": {"probe": "eddy_current"}},
    }
    (folder / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    tau = rng.uniform(1500, 6000, len(gains))
    rise = rng.uniform(2, 12, len(gains)) * (1 - np.exp(-t[:, None] / tau))
    temps = ambient + rise
    header = "elapsed_s," + ",".join(sensors)
    body = np.column_stack([t, temps, ambient + ambient_rise * t / max(t[-1], 1.0)])
    np.savetxt(
        folder / "temperature.csv", body, delimiter=",", header=header, comments="", fmt="%.4f"
    )
    td = t + displacement_offset_s
    rise_d = np.column_stack([np.interp(td, t, rise[:, j]) for j in range(len(gains))])
    z = 5.0 + rise_d @ np.asarray(gains)
    np.savetxt(
        folder / "displacement.csv",
        np.column_stack([td, z]),
        delimiter=",",
        header="elapsed_s,Z",
        comments="",
        fmt="%.4f",
    )
    return folder


def write_axis_campaign(
    raw: Path,
    campaign_id: str,
    *,
    n: int = 25,
    interval_s: float = 600.0,
    passes_min: tuple[float, ...] = (0.0, 120.0, 240.0),
    targets_mm: tuple[float, ...] = (0.0, 70.0, 140.0, 210.0, 280.0),
    seed: int = 0,
) -> Path:
    """An axis-positioning campaign: three warming sensors and an ambient one, and one
    bidirectional laser pass (runs 2k-1 '+', 2k '-') at each of ``passes_min``."""
    rng = np.random.default_rng(seed)
    folder = raw / campaign_id
    folder.mkdir(parents=True)
    sensors = {
        "T1": {"role": "ball_screw", "type": "PT100"},
        "T2": {"role": "nut", "type": "PT100"},
        "T3": {"role": "bed", "type": "PT100"},
        "T4": {"role": "ambient", "type": "PT100"},
    }
    meta = {
        "campaign_id": campaign_id,
        "kind": "axis_positioning",
        "machine": "test",
        "start": "2015-05-12T08:00:00",
        "synthetic": True,
        "split": "train",
        "sensors": sensors,
        "axis": {"name": "Y", "stroke_mm": 280},
    }
    (folder / "campaign.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    t = np.arange(n) * interval_s
    rise = rng.uniform(3, 8, 3) * (1 - np.exp(-t[:, None] / rng.uniform(2000, 5000, 3)))
    temps = np.column_stack([21.0 + rise, 21.0 + t / t[-1]])
    header = "elapsed_s," + ",".join(sensors)
    np.savetxt(
        folder / "temperature.csv",
        np.column_stack([t, temps]),
        delimiter=",",
        header=header,
        comments="",
        fmt="%.4f",
    )
    lines = ["elapsed_min,run,direction,target_mm,deviation_um"]
    for k, minute in enumerate(passes_min):
        for run, direction in ((2 * k + 1, "+"), (2 * k + 2, "-")):
            targets = targets_mm if direction == "+" else targets_mm[::-1]
            for target in targets:
                deviation = 2.0 + 0.01 * target + 0.02 * minute * target / 280
                lines.append(f"{minute:.1f},{run},{direction},{target:.1f},{deviation:.3f}")
    (folder / "laser.csv").write_text("\n".join(lines) + "\n")
    return folder

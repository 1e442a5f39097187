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
) -> Path:
    """A spindle-drift campaign whose Z drift is exactly ``sum(gains * rise)`` (um)."""
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
    body = np.column_stack([t, temps, np.full(n, ambient)])
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

r"""Write a synthetic campaign in the raw campaign contract (docs/data-contract.md, version 1).

Output is byte-for-byte reproducible: YAML and CSV are written by hand with fixed number
formats (elapsed_s and minutes to 0.1, temperatures to 4 decimals, displacement and laser
deviations to 0.01 um), ``\n`` line endings, and no generation timestamp anywhere.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.thermal.loads import HeatLoad, loads_to_contract
from pipeline.thermal.program import Program
from pipeline.twin.campaigns import AxisCampaign, CampaignInfo, SpindleCampaign
from pipeline.twin.instruments import PlacedSensor
from pipeline.twin.params import SensorSpec
from pipeline.twin.workshop import WorkshopCampaign
from schemas.contract import FILE_NAMES

logger = logging.getLogger(__name__)

FORMATS = {
    "elapsed_s": "{:.1f}",
    "elapsed_min": "{:.1f}",
    "temperature": "{:.4f}",
    "displacement": "{:.2f}",
    "target_mm": "{:.1f}",
    "deviation_um": "{:.2f}",
    "rpm": "{:.0f}",
}


def _num(x: float) -> str:
    """Format a YAML number: integer form when integral, else 6 significant digits."""
    x = float(x)
    return str(int(x)) if x.is_integer() else f"{x:.6g}"


def _fmt(values: np.ndarray, pattern: str) -> list[str]:
    decimals = int(pattern.split(".")[1][0])
    rounded = np.round(np.asarray(values, dtype=float), decimals) + 0.0  # no "-0.00"
    return [pattern.format(v) for v in rounded]


def _csv(columns: dict[str, list[str]]) -> str:
    names = list(columns)
    rows = zip(*(columns[c] for c in names), strict=True)
    return ",".join(names) + "\n" + "".join(",".join(r) + "\n" for r in rows)


def _sensors_yaml(sensors: tuple[SensorSpec, ...] | tuple[PlacedSensor, ...]) -> list[str]:
    """One line per sensor: role, location (left out when None) and type."""
    lines = ["sensors:"]
    for s in sensors:
        where = "" if s.location is None else f'location: "{s.location}", '
        lines.append(f"  {s.name}: {{role: {s.role}, {where}type: {s.type}}}")
    return lines


def _program_yaml(program: Program, indent: str) -> list[str]:
    lines = []
    for entry in program.to_contract():
        fields = ", ".join(f"{k}: {_num(v)}" for k, v in entry.items())
        lines.append(f"{indent}- {{{fields}}}")
    return lines


def _loads_yaml(loads: tuple[HeatLoad, ...]) -> list[str]:
    """Return the ``heat_loads:`` lines (role, times in min, power in W, what); [] without loads."""
    if not loads:
        return []
    lines = ["heat_loads:"]
    for entry in loads_to_contract(loads):
        fields = [f"role: {entry['role']}"]
        fields += [
            f"{k}: {_num(entry[k])}" for k in ("from_min", "to_min", "power_W") if k in entry
        ]
        if entry.get("what"):
            fields.append(f"what: {json.dumps(entry['what'])}")
        lines.append(f"  - {{{', '.join(fields)}}}")
    return lines


def _header(info: CampaignInfo) -> list[str]:
    return [
        f"campaign_id: {info.campaign_id}",
        f"kind: {info.kind}",
        f"machine: {info.machine}",
        f"start: {info.start.strftime('%Y-%m-%dT%H:%M:%S')}",
        f"season: {info.season}",
        "synthetic: true",
        *([] if info.split is None else [f"split: {info.split}"]),
        f'notes: "{info.notes}"',
    ]


def _spindle_yaml(
    campaign: SpindleCampaign | WorkshopCampaign,
    probe_lines: list[str],
    loads: tuple[HeatLoad, ...] = (),
) -> list[str]:
    lines = ["spindle_program:", *_program_yaml(campaign.program, "  "), *_loads_yaml(loads)]
    return lines + _sensors_yaml(campaign.sensors) + ["displacement:", *probe_lines]


def campaign_yaml(campaign: SpindleCampaign | AxisCampaign | WorkshopCampaign) -> str:
    """Return the campaign.yaml text of a campaign."""
    lines = _header(campaign.info)
    if isinstance(campaign, SpindleCampaign):
        lines += _spindle_yaml(
            campaign,
            ['  Z: {probe: eddy_current, location: "spindle nose, probe under the tool holder"}'],
            campaign.heat_loads,
        )
    elif isinstance(campaign, WorkshopCampaign):
        axes = campaign.displacement.columns[1:]
        lines += _spindle_yaml(campaign, [f"  {a}: {{probe: eddy_current}}" for a in axes])
    else:
        lines += _sensors_yaml(campaign.sensors)
        lines += [
            "axis:",
            f"  name: {campaign.axis_name}",
            f"  stroke_mm: {_num(campaign.stroke_mm)}",
            f"  step_mm: {_num(campaign.params.step_mm)}",
            "  instrument: laser interferometer",
            "  warm_up_program:",
        ]
        lines += _program_yaml(campaign.program, "    ")
    return "\n".join(lines) + "\n"


def temperature_csv(temperature: pd.DataFrame) -> str:
    """temperature.csv text: elapsed_s to 0.1 s, temperatures to 4 decimals (degC)."""
    cols = {"elapsed_s": _fmt(temperature["elapsed_s"], FORMATS["elapsed_s"])}
    for name in temperature.columns[1:]:
        cols[name] = _fmt(temperature[name], FORMATS["temperature"])
    return _csv(cols)


def displacement_csv(displacement: pd.DataFrame) -> str:
    """displacement.csv text: elapsed_s to 0.1 s, displacements to 0.01 um."""
    cols = {"elapsed_s": _fmt(displacement["elapsed_s"], FORMATS["elapsed_s"])}
    for name in displacement.columns[1:]:
        cols[name] = _fmt(displacement[name], FORMATS["displacement"])
    return _csv(cols)


def spindle_csv(spindle: pd.DataFrame) -> str:
    """spindle.csv text: elapsed_s to 0.1 s, measured speed to 1 rpm."""
    return _csv(
        {
            "elapsed_s": _fmt(spindle["elapsed_s"], FORMATS["elapsed_s"]),
            "rpm": _fmt(spindle["rpm"], FORMATS["rpm"]),
        }
    )


def laser_csv(laser: pd.DataFrame) -> str:
    """laser.csv text: elapsed_min, run, direction, target_mm, deviation_um (0.01 um)."""
    cols = {
        "elapsed_min": _fmt(laser["elapsed_min"], FORMATS["elapsed_min"]),
        "run": [str(int(r)) for r in laser["run"]],
        "direction": [str(d) for d in laser["direction"]],
        "target_mm": _fmt(laser["target_mm"], FORMATS["target_mm"]),
        "deviation_um": _fmt(laser["deviation_um"], FORMATS["deviation_um"]),
    }
    return _csv(cols)


def _write(path: Path, text: str) -> None:
    with path.open("w", encoding="utf-8", newline="\n") as handle:
        handle.write(text)


def write_campaign(
    campaign: SpindleCampaign | AxisCampaign | WorkshopCampaign, out_dir: Path | str
) -> Path:
    """Write ``out_dir/<campaign_id>/`` in the raw contract; return the folder.

    Contract files already in the folder (campaign.yaml, temperature.csv, displacement.csv,
    spindle.csv, laser.csv) are replaced or removed; other files are left alone.

    Parameters
    ----------
    campaign : SpindleCampaign, AxisCampaign or WorkshopCampaign
        A workshop campaign also writes its measured speed, spindle.csv.
    out_dir : Path or str
        The raw directory (e.g. ``data/raw``); created if missing.
    """
    folder = Path(out_dir) / campaign.info.campaign_id
    folder.mkdir(parents=True, exist_ok=True)
    for name in FILE_NAMES:
        (folder / name).unlink(missing_ok=True)
    _write(folder / "campaign.yaml", campaign_yaml(campaign))
    _write(folder / "temperature.csv", temperature_csv(campaign.temperature))
    if isinstance(campaign, SpindleCampaign | WorkshopCampaign):
        _write(folder / "displacement.csv", displacement_csv(campaign.displacement))
        if isinstance(campaign, WorkshopCampaign):
            _write(folder / "spindle.csv", spindle_csv(campaign.spindle))
    else:
        _write(folder / "laser.csv", laser_csv(campaign.laser))
    logger.info("wrote %s (%s) to %s", campaign.info.campaign_id, campaign.info.kind, folder)
    return folder

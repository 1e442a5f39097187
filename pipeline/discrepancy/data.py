"""Measured spindle campaigns as the discrepancy workflow sees them.

A :class:`MeasuredCampaign` holds what was measured and nothing else: the sample instants, the
spindle speed, the temperature readings with each sensor's contract role, and the Z drift at
the spindle nose. It is built from the validated ingest tables
(``data/validated/spindle/{campaigns,samples}.parquet``, see :mod:`pipeline.stages.ingest` and
:mod:`pipeline.stages.validate`), so the workflow runs on any raw folder in the contract.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from pipeline.thermal.loads import HeatLoad, loads_from_contract
from pipeline.thermal.program import Program

logger = logging.getLogger(__name__)

DISPLACEMENT_COLUMN = "disp_Z"
"""Samples column of the Z displacement at the spindle nose, um."""


@dataclass
class MeasuredCampaign:
    """One spindle-drift campaign as measured.

    Attributes
    ----------
    campaign_id : str
    t_s : ndarray of shape (n,), s
        Sample instants since the start, strictly increasing.
    rpm : ndarray of shape (n,), rpm
        Spindle speed at each sample instant (right-continuous zero-order hold).
    temperatures : pandas.DataFrame of shape (n, n_sensors), degC
        One column per sensor as named in campaign.yaml; NaN = missing reading.
    roles : dict of str to str
        Sensor name -> contract role (``spindle_front_bearing``, ``ambient``, ``other``...).
    z_um : ndarray of shape (n,), um
        Thermal drift: displacement minus its first valid value (NaN = missing).
    program : Program or None
        The campaign's spindle program (rpm). None when unknown (e.g. a measured speed log):
        the speed is then held from each sample to the next.
    season : str or None
    split : str or None
    heat_loads : tuple of HeatLoad
        External heat loads of the test (``heat_loads:`` of campaign.yaml), W; empty for a
        test with only the spindle's own heat.
    """

    campaign_id: str
    t_s: np.ndarray
    rpm: np.ndarray
    temperatures: pd.DataFrame
    roles: dict[str, str]
    z_um: np.ndarray
    program: Program | None = None
    season: str | None = None
    split: str | None = None
    heat_loads: tuple[HeatLoad, ...] = ()

    def __post_init__(self) -> None:
        """Coerce arrays and check that every signal has one value per sample instant."""
        self.t_s = np.asarray(self.t_s, dtype=float)
        self.rpm = np.asarray(self.rpm, dtype=float)
        self.z_um = np.asarray(self.z_um, dtype=float)
        n = self.t_s.size
        if self.t_s.ndim != 1 or n < 2:
            raise ValueError(
                f"campaign {self.campaign_id}: t_s must be a 1-d array of at least 2 instants"
            )
        if np.any(np.diff(self.t_s) <= 0):
            raise ValueError(
                f"campaign {self.campaign_id}: t_s must be strictly increasing; sort the samples "
                "and drop duplicate instants"
            )
        for name, values in (("rpm", self.rpm), ("z_um", self.z_um)):
            if values.shape != (n,):
                raise ValueError(
                    f"campaign {self.campaign_id}: {name} has shape {values.shape}, "
                    f"expected ({n},) like t_s"
                )
        if len(self.temperatures) != n:
            raise ValueError(
                f"campaign {self.campaign_id}: temperatures has {len(self.temperatures)} rows, "
                f"expected {n} like t_s"
            )
        self.temperatures = self.temperatures.reset_index(drop=True)
        unknown = [s for s in self.temperatures.columns if s not in self.roles]
        if unknown:
            raise ValueError(
                f"campaign {self.campaign_id}: sensors {unknown} have no role; give every "
                "temperature column a role (use 'other' if none fits)"
            )
        if np.any(~np.isfinite(self.rpm)):
            raise ValueError(f"campaign {self.campaign_id}: rpm has missing values")

    def sensors_with_role(self, role: str) -> list[str]:
        """Temperature columns whose sensor has ``role``, in column order."""
        return [s for s in self.temperatures.columns if self.roles.get(s) == role]

    @classmethod
    def from_tables(
        cls, campaigns_row: Mapping[str, Any] | pd.Series, samples: pd.DataFrame
    ) -> MeasuredCampaign:
        """Build a campaign from the validated ingest tables.

        Parameters
        ----------
        campaigns_row : mapping or pandas.Series
            One row of ``data/validated/spindle/campaigns.parquet`` (``campaign_id``,
            ``sensors_json``, ``spindle_program_json``, ``has_spindle_log``, ``season``,
            ``split``, ``heat_loads_json`` if the table has it).
        samples : pandas.DataFrame
            ``data/validated/spindle/samples.parquet`` (all campaigns or only this one):
            ``campaign_id``, ``source_row``, ``elapsed_s``, ``rpm``, the sensor columns and
            ``disp_Z`` (um).

        Returns
        -------
        MeasuredCampaign

        Raises
        ------
        ValueError
            If the campaign has no samples, no Z displacement or no temperature sensor.
        """
        row = dict(campaigns_row)
        cid = str(row["campaign_id"])
        rows = samples.loc[samples["campaign_id"] == cid]
        if "source_row" in rows.columns:
            rows = rows.sort_values("source_row")
        rows = rows.sort_values("elapsed_s", kind="stable").reset_index(drop=True)
        if len(rows) < 2:
            raise ValueError(
                f"campaign {cid}: fewer than 2 samples in the samples table; run ingest and "
                "validate on its raw folder first"
            )
        if DISPLACEMENT_COLUMN not in rows.columns or rows[DISPLACEMENT_COLUMN].isna().all():
            raise ValueError(
                f"campaign {cid}: no Z displacement ({DISPLACEMENT_COLUMN}); the discrepancy "
                "workflow needs displacement.csv with a Z column"
            )
        sensors = json.loads(row.get("sensors_json") or "{}")
        roles = {str(k): str((v or {}).get("role", "other")) for k, v in sensors.items()}
        present = [s for s in rows.columns if s in roles and rows[s].notna().any()]
        if not present:
            raise ValueError(
                f"campaign {cid}: none of the sensors {sorted(roles)} has readings in samples"
            )
        z = rows[DISPLACEMENT_COLUMN].to_numpy(dtype=float)
        z = z - z[np.flatnonzero(np.isfinite(z))[0]]
        entries = json.loads(row.get("spindle_program_json") or "[]")
        logged = bool(row.get("has_spindle_log", False))
        program = Program.from_contract(entries, key="rpm") if entries and not logged else None
        rpm = rows["rpm"].to_numpy(dtype=float)
        if np.any(~np.isfinite(rpm)):
            if program is None:
                raise ValueError(f"campaign {cid}: spindle speed missing at some samples")
            rpm = program.value_at(rows["elapsed_s"].to_numpy(dtype=float))
        return cls(
            campaign_id=cid,
            t_s=rows["elapsed_s"].to_numpy(dtype=float),
            rpm=rpm,
            temperatures=rows[present].astype(float).reset_index(drop=True),
            roles={s: roles[s] for s in present},
            z_um=z,
            program=program,
            season=None if row.get("season") is None else str(row["season"]),
            split=None if row.get("split") is None else str(row["split"]),
            heat_loads=loads_from_contract(json.loads(row.get("heat_loads_json") or "[]")),
        )


def campaigns_from_tables(campaigns: pd.DataFrame, samples: pd.DataFrame) -> list[MeasuredCampaign]:
    """Build every spindle-drift campaign of the validated tables, in table order.

    Campaigns without Z displacement are skipped with a warning.
    """
    out = []
    for row in campaigns.to_dict("records"):
        if row.get("kind", "spindle_drift") != "spindle_drift":
            continue
        try:
            out.append(MeasuredCampaign.from_tables(row, samples))
        except ValueError as err:
            logger.warning("skipped: %s", err)
    return out

"""What the compensation runtime loads for one axis: the champion, its fallbacks, its ranges.

A bundle is a folder (``data/models/compensation/<axis>/``, and the artifacts
``compensation/<axis>/`` of the champion's MLflow run) holding

- ``bundle.json``: the axis, the champion's card (model, inputs, how they are prepared: the
  :class:`~pipeline.separation.features.InputSpec` the training code used), the range of every
  input seen in training, the input checks' limits (those of the ``validate`` stage) and the
  fallback models' inputs and held-out scores;
- ``estimator.joblib``: the champion's fit on all training campaigns;
- ``fallback_<sensor>.joblib``: the champion's family fitted without that sensor.

Everything a runtime on the machine's PC needs is in the folder: no ``params.yaml``, no
training data.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import joblib
import numpy as np
import pandas as pd

from pipeline.errors import MissingInputError
from pipeline.separation.features import InputSpec, input_column
from schemas import ValidationLimits

BUNDLE_FILE = "bundle.json"
ESTIMATOR_FILE = "estimator.joblib"
FALLBACK_PREFIX = "fallback_"


@dataclass(frozen=True)
class InputChecks:
    """Limits of the per-cycle input checks, as the ``validate`` stage checks campaigns.

    Attributes
    ----------
    fault_codes : tuple of float, degC
        Readings that are sensor fault codes (DS18B20 power-on 85.0, disconnected -127.0).
    temperature_range_degC : tuple of float
        Physical range of a machine-tool temperature.
    stuck_min_samples : int
        A sensor repeating one reading this many samples in a row...
    stuck_min_s : float, s
        ...over at least this long...
    stuck_min_other_change_degC : float, K
        ...while another sensor moved this much, is stuck.
    range_margin_K : float, K
        A model input further than this outside its training range is bad.
    """

    fault_codes: tuple[float, ...] = (85.0, -127.0)
    temperature_range_degC: tuple[float, float] = (-20.0, 80.0)  # noqa: N815 (unit)
    stuck_min_samples: int = 20
    stuck_min_s: float = 3600.0
    stuck_min_other_change_degC: float = 0.5  # noqa: N815 (unit)
    range_margin_K: float = 5.0  # noqa: N815 (unit)

    @classmethod
    def from_limits(cls, limits: ValidationLimits, range_margin_K: float) -> InputChecks:
        """Build from the ``validate:`` section's limits and ``compensation.range_margin_degC``."""
        return cls(
            limits.ds18b20_codes,
            limits.temperature_range_degC,
            limits.stuck_min_samples,
            limits.stuck_min_minutes * 60.0,
            limits.stuck_min_other_change_degC,
            float(range_margin_K),
        )

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {
            "fault_codes": list(self.fault_codes),
            "temperature_range_degC": list(self.temperature_range_degC),
            "stuck_min_samples": self.stuck_min_samples,
            "stuck_min_s": self.stuck_min_s,
            "stuck_min_other_change_degC": self.stuck_min_other_change_degC,
            "range_margin_K": self.range_margin_K,
        }

    @classmethod
    def from_dict(cls, record: Mapping) -> InputChecks:
        """Inverse of :meth:`to_dict`."""
        return cls(
            tuple(float(v) for v in record["fault_codes"]),
            tuple(float(v) for v in record["temperature_range_degC"]),
            int(record["stuck_min_samples"]),
            float(record["stuck_min_s"]),
            float(record["stuck_min_other_change_degC"]),
            float(record["range_margin_K"]),
        )


@dataclass(frozen=True)
class ModelEntry:
    """One model the runtime can run for an axis.

    Attributes
    ----------
    name : str
        ``champion`` or ``without_<sensor>``.
    spec : InputSpec
    estimator : fitted estimator
        Takes the inputs of ``spec`` (:func:`pipeline.protocol.serving.predict_table`).
    heldout_rms_um : float or None, um
        Its held-out RMS (ranking scheme), when scored.
    """

    name: str
    spec: InputSpec
    estimator: object = field(repr=False)
    heldout_rms_um: float | None = None


@dataclass(frozen=True)
class AxisBundle:
    """Everything the runtime needs for one axis.

    Attributes
    ----------
    axis : str
    card : dict
        The champion's card (``data/models/champion/<axis>/champion.json``).
    champion : ModelEntry
    fallbacks : tuple of ModelEntry
        In the order the runtime tries them: each without one sensor of the champion.
    input_ranges : dict of str to (float, float)
        Per model input column (``rise_T1`` in K, ``T1`` in degC, ``speed_lag_30min``), the
        range seen in training.
    checks : InputChecks
    """

    axis: str
    card: dict
    champion: ModelEntry
    fallbacks: tuple[ModelEntry, ...] = ()
    input_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    checks: InputChecks = field(default_factory=InputChecks)

    @property
    def compensate(self) -> bool:
        """Whether the champion compensates (``none``: the offset stays zero)."""
        return bool(self.card.get("compensate", True))

    @property
    def sensors(self) -> list[str]:
        """Every temperature sensor any of the axis' models reads."""
        names = [s for entry in (self.champion, *self.fallbacks) for s in entry.spec.sensors]
        return list(dict.fromkeys(names))

    @property
    def needs_speed(self) -> bool:
        """Whether any of the axis' models reads the spindle speed."""
        return any(entry.spec.needs_speed for entry in (self.champion, *self.fallbacks))


def input_ranges(rows: pd.DataFrame, specs: list[InputSpec]) -> dict[str, tuple[float, float]]:
    """Range of every model input column seen in ``rows`` (the training campaigns).

    The inputs (``rise_<sensor>`` in K or ``<sensor>`` in degC, speed responses in
    (krpm)^a) and the sensors' readings (degC).

    Parameters
    ----------
    rows : DataFrame
        Rows of the separated table.
    specs : list of InputSpec

    Returns
    -------
    dict of str to (float, float)
        Columns absent from ``rows`` or without a finite value are left out.
    """
    columns = {input_column(name, spec.features) for spec in specs for name in spec.inputs}
    columns |= {name for spec in specs for name in spec.sensors}  # the readings, degC
    ranges = {}
    for column in sorted(columns):
        if column in rows:
            values = rows[column].to_numpy(dtype=float)
            values = values[np.isfinite(values)]
            if values.size:
                ranges[column] = (float(values.min()), float(values.max()))
    return ranges


def write_bundle(folder: Path, bundle: AxisBundle) -> None:
    """Write ``bundle`` to ``folder`` (created; files of a previous bundle replaced)."""
    folder.mkdir(parents=True, exist_ok=True)
    for stale in folder.glob(f"{FALLBACK_PREFIX}*.joblib"):
        stale.unlink()
    joblib.dump(bundle.champion.estimator, folder / ESTIMATOR_FILE)
    fallbacks = []
    for entry in bundle.fallbacks:
        joblib.dump(entry.estimator, folder / f"{FALLBACK_PREFIX}{entry.name}.joblib")
        fallbacks.append(_entry_record(entry))
    record = {
        "axis": bundle.axis,
        "card": bundle.card,
        "champion": _entry_record(bundle.champion),
        "fallbacks": fallbacks,
        "input_ranges": {k: list(v) for k, v in bundle.input_ranges.items()},
        "checks": bundle.checks.to_dict(),
    }
    (folder / BUNDLE_FILE).write_text(json.dumps(record, indent=2, sort_keys=True) + "\n")


def _entry_record(entry: ModelEntry) -> dict:
    return {
        "name": entry.name,
        "input_spec": entry.spec.to_dict(),
        "heldout_rms_um": entry.heldout_rms_um,
    }


def read_bundle(folder: Path) -> AxisBundle:
    """Read the bundle written by :func:`write_bundle`.

    Raises
    ------
    MissingInputError
        When ``folder`` holds no ``bundle.json``, saying how bundles are made.
    """
    path = Path(folder) / BUNDLE_FILE
    if not path.is_file():
        raise MissingInputError(
            f"{path} not found: a compensation bundle is written by `dvc repro` (stage "
            "compensation) under data/models/compensation/<axis>/ and logged with the "
            "champion's MLflow run; point --bundle at such a folder"
        )
    record = json.loads(path.read_text(encoding="utf-8"))
    champion = _read_entry(record["champion"], Path(folder) / ESTIMATOR_FILE)
    fallbacks = tuple(
        _read_entry(item, Path(folder) / f"{FALLBACK_PREFIX}{item['name']}.joblib")
        for item in record.get("fallbacks") or []
    )
    return AxisBundle(
        str(record["axis"]),
        dict(record["card"]),
        champion,
        fallbacks,
        {k: (float(v[0]), float(v[1])) for k, v in (record.get("input_ranges") or {}).items()},
        InputChecks.from_dict(record["checks"]),
    )


def _read_entry(item: Mapping, estimator_path: Path) -> ModelEntry:
    return ModelEntry(
        str(item["name"]),
        InputSpec.from_dict(item["input_spec"]),
        joblib.load(estimator_path),
        item.get("heldout_rms_um"),
    )


def bundle_axes(root: Path) -> list[str]:
    """Axes with a bundle under ``root`` (``data/models/compensation``), sorted."""
    if not Path(root).is_dir():
        return []
    return sorted(p.name for p in Path(root).iterdir() if (p / BUNDLE_FILE).is_file())

"""Pandera models of the tables written by ``ingest`` and kept by ``validate``.

The static models describe every table in the format of ``data/ingested/*.parquet`` (and of
``data/validated/*/*.parquet``, which has the same columns). The per-campaign parts -- one column
per sensor of the campaign's sensor map, one per displacement axis, and the checks whose limits
come from ``params.yaml`` -- are added by :func:`campaign_samples_schema` and
:func:`laser_schema`. Check names are the problem ids reported by ``validate``.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pandera.pandas as pa
from pandera.typing import Series

from schemas import checks
from schemas.strict import StrictModel
from schemas.vocabulary import (
    AMBIENT_ROLE,
    AXIS_KIND,
    CAMPAIGN_ID_RE,
    DIRECTIONS,
    DISPLACEMENT_COLUMN_RE,
    DISPLACEMENT_ROW_COLUMN_RE,
    KINDS,
    SEASONS,
    SENSOR_ROLES,
    SPINDLE_KIND,
    SPLITS,
    START_STATES,
    displacement_column,
    displacement_row_column,
    is_displacement_name,
    uses_ds18b20_codes,
)

DATAFRAME_CHECK_COLUMNS = {
    "time_increasing": "elapsed_s",
    "follows_other": "follows",
    "displacement_declared": "displacement_json",
    "axis_declared": "axis_name",
    "single_ambient": "role",
    "laser_run_one_direction": "direction",
    "laser_run_one_time": "elapsed_min",
    "laser_cold_run": "elapsed_min",
    "laser_bidirectional": "direction",
    "laser_target_set": "target_mm",
    "laser_target_missing": "target_mm",
}
"""Row-wise dataframe-level checks and the column each one is about (for problem reports)."""

_ID_PATTERN = CAMPAIGN_ID_RE.pattern


@dataclass(frozen=True)
class ValidationLimits:
    """Limits of the data checks; field names are the keys of ``params.yaml`` ``validate:``.

    Attributes
    ----------
    temperature_range_degC : tuple of (float, float), degC
        Physical range of a machine-tool temperature reading.
    ds18b20_power_on_degC : float, degC
        DS18B20 power-on reset value (never a real reading on a machine tool).
    ds18b20_disconnected_degC : float, degC
        DS18B20 "device not found" value.
    interval_tolerance : float
        Relative deviation of a sampling interval from the campaign's median interval allowed.
    stuck_min_samples : int
        Identical consecutive readings from which a sensor counts as stuck...
    stuck_min_minutes : float, min
        ...spanning at least this long...
    stuck_min_other_change_degC : float, degC
        ...when another sensor changed by at least this much meanwhile.
    spike_threshold_degC : float, degC
        A reading further than this from both neighbours (same side) is a spike.
    displacement_range_um : tuple of (float, float), um
        Measuring range of the displacement probes.
    laser_target_tolerance_mm : float, mm
        Targets of different laser runs of a campaign agree within this.
    laser_deviation_range_um : tuple of (float, float), um
        Plausible range of a laser-measured positioning deviation.
    min_samples : int
        Fewest temperature samples a campaign needs to be modelled.
    air_temperature_max_degC : float, degC
        Warmest plausible air around a machine tool: the campaign's air reference (the ambient
        sensor's median reading, else the median of its coolest sensor) above this means the
        temperatures are not in degC (degF).
    displacement_min_span_um : float, um
        A displacement axis moving less than this peak to peak...
    unit_check_min_rise_degC : float, degC
        ...while a temperature sensor rises by at least this much is not in um (mm).
    min_program_coverage : float
        Samples spanning less than this share of the finite part of the ``spindle_program``
        (minutes) mean ``elapsed_s`` is not in seconds (minutes).
    max_bridged_gap_s : float, s
        Longest time from the reading before a gap of missing readings of one sensor to the
        reading after it that is bridged by linear interpolation in time; the samples of a
        longer gap (or of one at the start or end of the file) are dropped.
    """

    temperature_range_degC: tuple[float, float]  # noqa: N815 (params.yaml key)
    ds18b20_power_on_degC: float  # noqa: N815 (params.yaml key)
    ds18b20_disconnected_degC: float  # noqa: N815 (params.yaml key)
    interval_tolerance: float
    stuck_min_samples: int
    stuck_min_minutes: float
    stuck_min_other_change_degC: float  # noqa: N815 (params.yaml key)
    spike_threshold_degC: float  # noqa: N815 (params.yaml key)
    displacement_range_um: tuple[float, float]
    laser_target_tolerance_mm: float
    laser_deviation_range_um: tuple[float, float]
    min_samples: int
    air_temperature_max_degC: float  # noqa: N815 (params.yaml key)
    displacement_min_span_um: float
    unit_check_min_rise_degC: float  # noqa: N815 (params.yaml key)
    min_program_coverage: float
    max_bridged_gap_s: float = 600.0

    @property
    def ds18b20_codes(self) -> tuple[float, float]:
        """The DS18B20 fault codes (power-on, disconnected), degC."""
        return (self.ds18b20_power_on_degC, self.ds18b20_disconnected_degC)


def parse_json(text: object) -> object:
    """Return the parsed JSON of ``text``, or None when it is missing or not valid JSON."""
    if not isinstance(text, str):
        return None
    try:
        return json.loads(text)
    except ValueError:
        return None


def _is_valid_json(text: object) -> bool:
    if not isinstance(text, str):
        return False
    try:
        json.loads(text)
    except ValueError:
        return False
    return True


class CampaignsModel(StrictModel):
    """``campaigns.parquet``: one row per campaign (its campaign.yaml).

    Nullable text columns are coerced to ``str`` (an all-null column is read back as
    ``object``). ``*_json`` columns hold the yaml mappings as JSON text: ``sensors_json``
    ``{name: {role, location, type}}``, ``displacement_json`` ``{axis: {...}}``,
    ``spindle_program_json`` a list of ``{from_min, to_min?, rpm}``, ``heat_loads_json`` a list
    of ``{role, from_min, to_min?, power_W, what?}`` (``[]`` when the campaign has none; minutes
    since ``start``, W).
    """

    campaign_id: Series[str]
    kind: Series[str]
    machine: Series[str] = pa.Field(nullable=True, coerce=True)
    start: Series[pd.Timestamp]
    season: Series[str]
    season_derived: Series[bool]
    synthetic: Series[bool]
    split: Series[str]
    start_state: Series[str] = pa.Field(nullable=True, coerce=True)
    follows: Series[str] = pa.Field(nullable=True, coerce=True)
    axis_name: Series[str] = pa.Field(nullable=True, coerce=True)
    stroke_mm: Series[float] = pa.Field(nullable=True, coerce=True)
    sensors_json: Series[str]
    displacement_json: Series[str]
    spindle_program_json: Series[str]
    heat_loads_json: Series[str]
    has_spindle_log: Series[bool]
    source_dir: Series[str]

    @pa.check("campaign_id")
    @classmethod
    def campaign_id_format(cls, s: Series[str]) -> Series[bool]:
        """Check that campaign ids use letters, digits, '-' and '_' only."""
        return s.str.match(_ID_PATTERN).astype(bool)

    @pa.check("campaign_id")
    @classmethod
    def campaign_id_unique(cls, s: Series[str]) -> Series[bool]:
        """Check that no two campaigns share an id."""
        return ~s.duplicated(keep=False)

    @pa.check("kind")
    @classmethod
    def kind_known(cls, s: Series[str]) -> Series[bool]:
        """Check that ``kind`` is spindle_drift or axis_positioning."""
        return s.isin(KINDS)

    @pa.check("split")
    @classmethod
    def split_known(cls, s: Series[str]) -> Series[bool]:
        """Check that ``split`` is train or validation."""
        return s.isin(SPLITS)

    @pa.check("start_state")
    @classmethod
    def start_state_known(cls, s: Series[str]) -> Series[bool]:
        """Check that ``start_state`` is cold or warm (or not given)."""
        return s.isna() | s.isin(START_STATES)

    @pa.check("follows")
    @classmethod
    def follows_format(cls, s: Series[str]) -> Series[bool]:
        """Check that ``follows`` is a campaign id (letters, digits, '-', '_') or not given."""
        return s.isna() | s.str.match(_ID_PATTERN).fillna(False).astype(bool)

    @pa.dataframe_check
    @classmethod
    def follows_other(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that a campaign does not follow itself."""
        return df["follows"].isna() | (df["follows"] != df["campaign_id"])

    @pa.check("season")
    @classmethod
    def season_known(cls, s: Series[str]) -> Series[bool]:
        """Check that ``season`` is spring, summer, autumn or winter."""
        return s.isin(SEASONS)

    @pa.check("stroke_mm")
    @classmethod
    def stroke_positive(cls, s: Series[float]) -> Series[bool]:
        """Check that an axis stroke is positive, mm."""
        return s > 0

    @pa.check("sensors_json", "displacement_json", "spindle_program_json", "heat_loads_json")
    @classmethod
    def json_readable(cls, s: Series[str]) -> Series[bool]:
        """Check that the yaml mappings were stored as valid JSON."""
        return s.map(_is_valid_json).astype(bool)

    @pa.check("sensors_json")
    @classmethod
    def sensors_declared(cls, s: Series[str]) -> Series[bool]:
        """Check that ``sensors:`` declares at least one temperature sensor."""
        return s.map(lambda t: not _is_valid_json(t) or bool(parse_json(t))).astype(bool)

    @pa.check("displacement_json")
    @classmethod
    def displacement_axis_known(cls, s: Series[str]) -> Series[bool]:
        """Check that ``displacement:`` names axes of letters and digits (X, Y, Z, Z2...)."""

        def known(text: object) -> bool:
            axes = parse_json(text)
            return not isinstance(axes, dict) or all(is_displacement_name(a) for a in axes)

        return s.map(known).astype(bool)

    @pa.dataframe_check
    @classmethod
    def displacement_declared(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that a spindle_drift campaign declares a displacement axis."""
        declared = df["displacement_json"].map(lambda t: bool(parse_json(t))).astype(bool)
        return (df["kind"] != SPINDLE_KIND) | declared

    @pa.dataframe_check
    @classmethod
    def axis_declared(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that an axis_positioning campaign names its axis (``axis: name:``)."""
        return (df["kind"] != AXIS_KIND) | df["axis_name"].notna()


class SensorsModel(pa.DataFrameModel):
    """The sensor maps of all campaigns as a long table, one row per declared sensor.

    Built by ``pipeline.validation.campaign_checks.sensor_table`` from
    ``campaigns.sensors_json``; a missing role is the empty string.
    """

    campaign_id: Series[str]
    sensor: Series[str]
    role: Series[str]
    location: Series[str] = pa.Field(nullable=True, coerce=True)
    type: Series[str] = pa.Field(nullable=True, coerce=True)

    @pa.check("role")
    @classmethod
    def sensor_role_known(cls, s: Series[str]) -> Series[bool]:
        """Check that the role comes from the closed vocabulary of the data contract."""
        return s.isin(SENSOR_ROLES)

    @pa.dataframe_check
    @classmethod
    def single_ambient(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that at most one sensor of a campaign has the role ambient."""
        ambient = df["role"] == AMBIENT_ROLE
        count = ambient.groupby(df["campaign_id"], sort=False).transform("sum")
        return ~(ambient & (count > 1))


class SamplesModel(pa.DataFrameModel):
    """``samples.parquet``: one row per temperature.csv data row, file order kept.

    Static part only: temperature columns (one per sensor, degC) and displacement columns are
    per campaign (:func:`campaign_samples_schema`); other columns are allowed here.
    """

    campaign_id: Series[str]
    source_row: Series[np.int64] = pa.Field(ge=1)
    elapsed_s: Series[float]
    rpm: Series[float] = pa.Field(nullable=True)

    class Config:
        """Sensor and displacement columns vary by campaign."""

        strict = False

    @pa.dataframe_check
    @classmethod
    def time_increasing(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that ``elapsed_s`` strictly increases within each campaign (file order)."""
        return checks.increasing_within(df["elapsed_s"], df["campaign_id"])


class SpindleSamplesModel(SamplesModel):
    """Samples of spindle_drift campaigns: temperatures plus displacement ``disp_<A>`` (um).

    ``disp_<A>_source_row`` is the nearest displacement.csv data row (1-based) of each sample.
    """

    disp: Series[float] = pa.Field(alias=DISPLACEMENT_COLUMN_RE.pattern, regex=True, nullable=True)
    disp_source_row: Series[pd.Int64Dtype] | None = pa.Field(
        alias=DISPLACEMENT_ROW_COLUMN_RE.pattern, regex=True, nullable=True, ge=1
    )


class AxisSamplesModel(SamplesModel):
    """Samples of axis_positioning campaigns: temperatures only (degC)."""


class LaserModel(StrictModel):
    """``laser.parquet``: one row per laser.csv data row (a target of a run).

    Units: ``elapsed_min`` min since start, ``target_mm`` mm, ``deviation_um`` um.
    """

    campaign_id: Series[str]
    source_row: Series[np.int64] = pa.Field(ge=1)
    elapsed_min: Series[float]
    run: Series[np.int64]
    direction: Series[str]
    target_mm: Series[float]
    deviation_um: Series[float]

    @pa.check("direction")
    @classmethod
    def laser_direction(cls, s: Series[str]) -> Series[bool]:
        """Check that a run goes in the '+' or the '-' direction."""
        return s.isin(DIRECTIONS)

    @pa.check("elapsed_min")
    @classmethod
    def laser_elapsed_nonnegative(cls, s: Series[float]) -> Series[bool]:
        """Check that runs are measured after the start of the campaign."""
        return s >= 0

    @pa.dataframe_check
    @classmethod
    def laser_run_one_direction(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that every row of a run has the run's direction (a pass is two runs).

        Rows whose direction is not '+'/'-' are left to ``laser_direction``.
        """
        same = checks.mode_within(df["direction"], [df["campaign_id"], df["run"]])
        return same | ~df["direction"].isin(DIRECTIONS)

    @pa.dataframe_check
    @classmethod
    def laser_run_one_time(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that every row of a run has the run's elapsed_min."""
        return checks.mode_within(df["elapsed_min"], [df["campaign_id"], df["run"]])

    @pa.dataframe_check
    @classmethod
    def laser_cold_run(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that each campaign has a run at elapsed_min 0 (reported at its first row)."""
        return checks.first_row_of_group_without(
            checks.is_cold(df["elapsed_min"]), df[["campaign_id"]]
        )

    @pa.dataframe_check
    @classmethod
    def laser_bidirectional(cls, df: pd.DataFrame) -> Series[bool]:
        """Check that each pass (the runs at one elapsed_min) has a '+' and a '-' run."""
        keys = df[["campaign_id", "elapsed_min"]]
        plus = checks.first_row_of_group_without(df["direction"] == DIRECTIONS[0], keys)
        minus = checks.first_row_of_group_without(df["direction"] == DIRECTIONS[1], keys)
        return plus & minus


class ProblemsModel(StrictModel):
    """``problems.parquet``: problems ``ingest`` found while reading a campaign's files."""

    campaign_id: Series[str]
    file: Series[str]
    row: Series[pd.Int64Dtype] = pa.Field(nullable=True, ge=1)
    column: Series[str] = pa.Field(nullable=True, coerce=True)
    check: Series[str]
    problem: Series[str]
    action: Series[str]


def _with(schema: pa.DataFrameSchema, *, strict: bool, extra_checks: Sequence[pa.Check]):
    """Return a copy of ``schema`` with ``strict`` set and ``extra_checks`` appended."""
    result = copy.deepcopy(schema)
    result.strict = strict
    result.checks = [*schema.checks, *extra_checks]
    return result


def sensor_columns(
    sensors: Mapping[str, Mapping[str, object]], limits: ValidationLimits
) -> dict[str, pa.Column]:
    """Return one Pandera column per declared temperature sensor, with its reading checks.

    Parameters
    ----------
    sensors : mapping
        The campaign's sensor map ``{name: {role, location, type}}`` (campaign.yaml).
    limits : ValidationLimits

    Returns
    -------
    dict of str to pandera Column
        float64, nullable (empty cells are missing readings), checked for the physical range,
        spikes and, for DS18B20 sensors or sensors without a type, the fault codes.
    """
    low, high = limits.temperature_range_degC
    columns = {}
    for name, spec in sensors.items():
        sensor_type = spec.get("type") if isinstance(spec, Mapping) else None
        codes = limits.ds18b20_codes if uses_ds18b20_codes(sensor_type) else ()
        column_checks = [
            pa.Check(
                lambda s, c=codes: checks.in_range_except(s, low, high, c),
                name="temperature_range",
            ),
            pa.Check(
                lambda s, c=codes: checks.spike_free(s, limits.spike_threshold_degC, c),
                name="spike",
            ),
        ]
        if codes:
            column_checks += [
                pa.Check(
                    lambda s: checks.not_in(s, [limits.ds18b20_power_on_degC]),
                    name="ds18b20_power_on",
                ),
                pa.Check(
                    lambda s: checks.not_in(s, [limits.ds18b20_disconnected_degC]),
                    name="ds18b20_disconnected",
                ),
            ]
        columns[str(name)] = pa.Column(float, checks=column_checks, nullable=True)
    return columns


def displacement_columns(axes: Sequence[str], limits: ValidationLimits) -> dict[str, pa.Column]:
    """Return the ``disp_<A>`` (um, probe range checked) and ``disp_<A>_source_row`` columns."""
    low, high = limits.displacement_range_um
    columns = {}
    for axis in axes:
        columns[displacement_column(axis)] = pa.Column(
            float,
            checks=pa.Check(lambda s: s.between(low, high), name="displacement_range"),
            nullable=True,
        )
        columns[displacement_row_column(axis)] = pa.Column(
            pd.Int64Dtype(), checks=pa.Check.ge(1), nullable=True, required=False
        )
    return columns


def campaign_samples_schema(
    kind: str,
    sensors: Mapping[str, Mapping[str, object]],
    displacement_axes: Sequence[str],
    limits: ValidationLimits,
) -> pa.DataFrameSchema:
    """Return the strict schema of one campaign's samples.

    Parameters
    ----------
    kind : str
        Campaign kind; spindle_drift uses :class:`SpindleSamplesModel`, anything else
        :class:`AxisSamplesModel` as the static part.
    sensors : mapping
        Sensor map of campaign.yaml: every sensor must have a column, no other temperature
        column may exist.
    displacement_axes : sequence of str
        Axes declared under ``displacement:``; each must have a ``disp_<A>`` column, no other.
    limits : ValidationLimits

    Returns
    -------
    pandera DataFrameSchema
        Validate the campaign's rows (file order, only the columns holding data for it) with
        ``lazy=True`` to get every problem at once. Adds the sampling-interval check on
        ``elapsed_s`` and the stuck-sensor check (dataframe level) to the static model.
    """
    model = SpindleSamplesModel if kind == SPINDLE_KIND else AxisSamplesModel
    base = model.to_schema()
    regex_columns = [name for name, column in base.columns.items() if column.regex]
    schema = base.remove_columns(regex_columns)
    schema = schema.add_columns(
        {**sensor_columns(sensors, limits), **displacement_columns(displacement_axes, limits)}
    )
    schema = schema.update_column(
        "elapsed_s",
        checks=[
            *schema.columns["elapsed_s"].checks,
            pa.Check(
                lambda s: checks.interval_consistent(s, limits.interval_tolerance),
                name="sampling_interval",
                ignore_na=False,  # keep missing times in place: no interval across them
            ),
        ],
    )
    fault_codes = {
        str(name): limits.ds18b20_codes
        for name, spec in sensors.items()
        if uses_ds18b20_codes(spec.get("type") if isinstance(spec, Mapping) else None)
    }
    stuck = pa.Check(
        lambda df: checks.stuck_free(
            df,
            [str(name) for name in sensors],
            limits.stuck_min_samples,
            limits.stuck_min_other_change_degC,
            fault_codes,
            60.0 * limits.stuck_min_minutes,
        ),
        name="stuck_sensor",
    )
    return _with(schema, strict=True, extra_checks=[stuck])


def laser_schema(limits: ValidationLimits) -> pa.DataFrameSchema:
    """Return :class:`LaserModel` plus the target-set checks (tolerance from ``limits``).

    ``laser_deviation_range``: every deviation lies in ``laser_deviation_range_um``;
    ``laser_target_set``: every target of every run matches a target of the campaign's
    reference run (the cold run) within ``laser_target_tolerance_mm``;
    ``laser_target_missing``: every run measures every target of the reference run.
    """
    tolerance = limits.laser_target_tolerance_mm
    low, high = limits.laser_deviation_range_um
    schema = LaserModel.to_schema().update_column(
        "deviation_um",
        checks=[pa.Check(lambda s: s.between(low, high), name="laser_deviation_range")],
    )
    extra = [
        pa.Check(lambda df: checks.targets_in_reference(df, tolerance), name="laser_target_set"),
        pa.Check(
            lambda df: checks.runs_cover_reference(df, tolerance), name="laser_target_missing"
        ),
    ]
    return _with(schema, strict=True, extra_checks=extra)

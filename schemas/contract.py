"""The raw campaign contract (version 1) as data: the keys of ``campaign.yaml`` and the files.

``docs/data-contract.md`` is generated from this module, :mod:`schemas.vocabulary` and the
problem texts of the validate stage (``thermal contract-doc``), and the tests check the keys
against :class:`schemas.ingested.CampaignsModel`, so the document, the reader and the Pandera
models cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.vocabulary import (
    AXIS_KIND,
    DIRECTIONS,
    DS18B20_TYPE,
    KINDS,
    SEASONS,
    SPINDLE_KIND,
    SPLITS,
    START_STATES,
    STRUCTURE_ROLES,
)

VERSION = 1
"""Contract version; an extension that every version-1 reader accepts keeps it."""

ALWAYS, OPTIONAL = "always", "optional"


def _one_of(values: tuple[str, ...]) -> str:
    return " \\| ".join(f"`{v}`" for v in values)


@dataclass(frozen=True)
class Key:
    """One key of ``campaign.yaml``.

    Attributes
    ----------
    name : str
        Dotted path (``axis.stroke_mm``; ``sensors.<name>.role`` for every sensor).
    required : str
        ``always``, ``optional``, or the campaign kind that requires it.
    value : str
        What the value is (type, unit, allowed values).
    meaning : str
        What the pipeline does with it.
    column : str or None
        The ``campaigns.parquet`` column it is stored in (:class:`schemas.CampaignsModel`).
    """

    name: str
    required: str
    value: str
    meaning: str
    column: str | None


CAMPAIGN_KEYS: tuple[Key, ...] = (
    Key(
        "campaign_id",
        ALWAYS,
        "letters, digits, `-`, `_`",
        "must equal the folder name",
        "campaign_id",
    ),
    Key(
        "kind",
        ALWAYS,
        _one_of(KINDS),
        "which files the campaign has and which stages use it",
        "kind",
    ),
    Key(
        "machine",
        OPTIONAL,
        "free text",
        "the machine measured; each machine is modelled on its own campaigns (a folder may "
        "hold several); a campaign without `machine` is of the one machine the others name "
        "(quarantined when they name several); campaigns of one machine that follow each other "
        "without a break form a run",
        "machine",
    ),
    Key(
        "start",
        ALWAYS,
        "ISO 8601 date-time, e.g. `2015-01-12T08:30:00`",
        "local time of the first sample (a UTC offset, if written, is dropped: the wall clock "
        "is kept)",
        "start",
    ),
    Key(
        "season",
        OPTIONAL,
        _one_of(SEASONS),
        "the season of leave-one-season-out; when absent, from the month of `start` "
        "(December-February winter, March-May spring, June-August summer, "
        "September-November autumn)",
        "season",
    ),
    Key(
        "synthetic",
        OPTIONAL,
        "`true` \\| `false` (default `false`)",
        "generated data; shown in every report",
        "synthetic",
    ),
    Key(
        "split",
        OPTIONAL,
        f"{_one_of(SPLITS)} (default `train`)",
        "validation campaigns only report the chosen models, they never choose",
        "split",
    ),
    Key(
        "start_state",
        OPTIONAL,
        _one_of(START_STATES),
        "`cold`: at rest at the air temperature at the first sample, never linked to an "
        "earlier campaign; `warm` on a run's first campaign: the cold state is not in the data",
        "start_state",
    ),
    Key(
        "follows",
        OPTIONAL,
        "a campaign id",
        "this campaign continues that one without a break (one run, one cold reference)",
        "follows",
    ),
    Key(
        "spindle_program",
        OPTIONAL,
        "list of `{from_min, to_min, rpm}`, minutes from `start`; the last `to_min` may be "
        "omitted (open-ended)",
        "the spindle speed when there is no `spindle.csv`",
        "spindle_program_json",
    ),
    Key(
        "heat_loads",
        OPTIONAL,
        "list of `{role, from_min, to_min, power_W, what}`: a structure role ("
        + ", ".join(f"`{r}`" for r in STRUCTURE_ROLES)
        + "), minutes from `start` (the last `to_min` of a role may be omitted), W, free text; "
        "loads of one role must not overlap in time",
        "external heat put into that part during the test (heater, lamp, blower; a draught "
        "that cools it is negative): a known heat input of the physical twin; the regressions "
        "ignore it",
        "heat_loads_json",
    ),
    Key(
        "sensors",
        ALWAYS,
        "mapping: temperature.csv column -> `{role, location, type}`",
        "one entry per temperature column, in degC",
        "sensors_json",
    ),
    Key(
        "sensors.<name>.role",
        ALWAYS,
        "a sensor role (below)",
        "where the sensor is; the physical twin needs the roles, the regressions do not",
        "sensors_json",
    ),
    Key("sensors.<name>.location", OPTIONAL, "free text", "shown in reports", "sensors_json"),
    Key(
        "sensors.<name>.type",
        OPTIONAL,
        f"free text, e.g. `{DS18B20_TYPE}`, `PT100`",
        f"the {DS18B20_TYPE} fault codes (85.0, -127) are checked on `{DS18B20_TYPE}` sensors "
        "and on sensors without a type",
        "sensors_json",
    ),
    Key(
        "displacement",
        SPINDLE_KIND,
        "mapping: displacement.csv column -> `{probe}`; names `X`, `Y`, `Z` or letters and "
        "digits starting with a letter (e.g. `Z2`)",
        "every probe axis is modelled",
        "displacement_json",
    ),
    Key("axis.name", AXIS_KIND, "`X`, `Y`, `Z`", "the axis the laser measured", "axis_name"),
    Key("axis.stroke_mm", OPTIONAL, "mm, positive", "the travel of the axis", "stroke_mm"),
)
"""Every key of ``campaign.yaml``; keys not listed here are read as comments (ignored), but for
a close misspelling of a key the file lacks (``misspelt_key``, :mod:`pipeline.io.campaign_file`)."""

DERIVED_COLUMNS = {
    "season_derived": "whether `season` came from `start`",
    "has_spindle_log": "whether the folder has `spindle.csv`",
    "source_dir": "the campaign folder",
}
"""``campaigns.parquet`` columns that no key fills directly."""

LASER_COLUMNS = ("elapsed_min", "run", "direction", "target_mm", "deviation_um")
"""The columns of ``laser.csv``, in order."""


@dataclass(frozen=True)
class ContractFile:
    """One file of a campaign folder.

    Attributes
    ----------
    name : str
        File name.
    required : str
        ``always``, ``optional`` or the campaign kind that requires it.
    columns : tuple of (str, str)
        ``(column, meaning with unit)`` in file order; ``<sensor>`` / ``<axis>`` stand for one
        column per declared sensor / axis.
    """

    name: str
    required: str
    columns: tuple[tuple[str, str], ...]


FILES: tuple[ContractFile, ...] = (
    ContractFile("campaign.yaml", ALWAYS, ()),
    ContractFile(
        "temperature.csv",
        ALWAYS,
        (
            ("elapsed_s", "s since `start`, strictly increasing"),
            (
                "<sensor>",
                "degC, one column per entry of `sensors:`; an empty cell is a missing reading "
                "(bridged or dropped, see Missing readings)",
            ),
        ),
    ),
    ContractFile(
        "displacement.csv",
        SPINDLE_KIND,
        (
            (
                "elapsed_s",
                "s since `start`, strictly increasing; may differ from temperature.csv's "
                "instants (interpolated onto them)",
            ),
            (
                "<axis>",
                "um, one column per entry of `displacement:`; positive = tool away from the "
                "table / workpiece; an empty cell is a missing reading",
            ),
        ),
    ),
    ContractFile(
        "spindle.csv",
        OPTIONAL,
        (
            ("elapsed_s", "s since `start`"),
            ("rpm", "measured spindle speed, 1/min; wins over `spindle_program`"),
        ),
    ),
    ContractFile(
        "laser.csv",
        AXIS_KIND,
        (
            (
                "elapsed_min",
                "min since `start`: the time of the run; the run at 0 (cold) carries "
                "the geometric error",
            ),
            ("run", "integer numbering the runs; a bidirectional pass is two runs"),
            ("direction", f"{_one_of(DIRECTIONS)}: the direction of the run"),
            ("target_mm", "mm, the target position"),
            (
                "deviation_um",
                "um, the positioning deviation at the target as the laser software reports it",
            ),
        ),
    ),
)
"""The files of a campaign folder, in the order the document lists them."""

FILE_NAMES = tuple(f.name for f in FILES)
"""Every file name of a campaign folder (what a writer replaces when it rewrites a folder)."""

CONTRACT_FILES = {
    kind: tuple(f.name for f in FILES if f.required in (ALWAYS, kind) and f.name.endswith(".csv"))
    for kind in KINDS
}
"""The CSV files each kind of campaign must have."""

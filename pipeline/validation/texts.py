"""How each check's failures are worded: message and action per check id.

:data:`PROBLEM_TEXTS` quarantine a campaign; :data:`WARNING_TEXTS` (missing readings) do not.

The check ids are the Pandera check names of :mod:`schemas` (plus the renamed structural checks
and the campaign-level ids of :mod:`pipeline.validation`). Templates are ``str.format``
strings over the fields of a finding group (see :func:`pipeline.validation.rendering.render`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from schemas.vocabulary import SENSOR_ROLES, STRUCTURE_ROLES

RERUN = "then rerun dvc repro"
CONTRACT = "docs/data-contract.md"
CSV_EXPORT = (
    "comma-separated UTF-8 text with '.' as the decimal point and one header row (Excel: "
    "Save As > CSV UTF-8 (Comma delimited); LibreOffice: Save As > Text CSV, character set "
    "UTF-8, field delimiter ',')"
)


class TemplateFields(dict):
    """Template fields; an unknown field renders as '?' instead of failing."""

    def __missing__(self, key: str) -> str:
        return "?"


@dataclass(frozen=True)
class ProblemText:
    """How a check's failures are reported.

    ``message``/``action``/``column`` are ``str.format`` templates over the fields of a
    problem (see :func:`pipeline.validation.rendering.render`). ``row_level=False`` reports the
    problem without a row; ``collapse=True`` merges all failures of the check in a campaign
    into one problem.
    """

    message: str
    action: str
    column: str | None = None
    row_level: bool = True
    collapse: bool = False


PROBLEM_TEXTS: dict[str, ProblemText] = {
    # ---- temperature.csv / displacement.csv (samples)
    "sensor_column_missing": ProblemText(
        "sensor {column} is declared under sensors: in {campaign}/campaign.yaml but "
        "{campaign}/temperature.csv has no column {column}, or none of its cells has a reading",
        "add the readings of {column} to {campaign}/temperature.csv, or remove {column} from "
        f"sensors: in {{campaign}}/campaign.yaml, {RERUN}",
    ),
    "unknown_temperature_column": ProblemText(
        "{campaign}/temperature.csv has a column {column} that is not declared under sensors: "
        "in {campaign}/campaign.yaml",
        "declare {column} (with its role) under sensors: in {campaign}/campaign.yaml, or delete "
        f"the column from {{campaign}}/temperature.csv, {RERUN}",
    ),
    "displacement_column_missing": ProblemText(
        "axis {axis} is declared under displacement: in {campaign}/campaign.yaml but "
        "{campaign}/displacement.csv has no column {axis}, or none of its cells has a reading",
        "add the {axis} readings to {campaign}/displacement.csv, or remove {axis} from "
        f"displacement: in {{campaign}}/campaign.yaml, {RERUN}",
        column="{axis}",
    ),
    "unknown_displacement_column": ProblemText(
        "{campaign}/displacement.csv has readings in column {axis} but displacement: in "
        "{campaign}/campaign.yaml does not declare axis {axis}",
        "declare {axis} under displacement: in {campaign}/campaign.yaml (e.g. "
        f"{{axis}}: {{{{probe: eddy_current}}}}), or delete the column, {RERUN}",
        column="{axis}",
    ),
    "time_increasing": ProblemText(
        "elapsed_s does not increase at {where}: {value} s follows {previous} s",
        "make elapsed_s strictly increasing in {campaign}/{file} (remove the duplicated or "
        f"out-of-order {{rows}}), {RERUN}",
    ),
    "sampling_interval": ProblemText(
        "the sampling interval before {where} is {value} s, more than "
        "{interval_tolerance_pct} % away from the campaign's median interval {median_interval} s "
        "(dropped or extra samples)",
        "check the logger around {rows} of {campaign}/{file}: add the missing instants with "
        "empty cells or remove the extra rows; if the sampling is irregular on purpose, raise "
        f"validate.interval_tolerance in params.yaml; {RERUN}",
    ),
    "temperature_range": ProblemText(
        "{column} reads {value} degC at {where}, outside the physical range "
        "{temperature_low} to {temperature_high} degC",
        "check sensor {column} and its unit (degC); replace the impossible readings of {column} "
        f"in {{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "ds18b20_power_on": ProblemText(
        "{column} reads {value} degC at {where}: the DS18B20 power-on reset value, not a "
        "measurement",
        "replace the {value} readings of {column} in {campaign}/{file} {rows} with empty cells "
        f"(sensor power-on value) or fix the logger, {RERUN}",
    ),
    "ds18b20_disconnected": ProblemText(
        "{column} reads {value} degC at {where}: the DS18B20 'device not found' code (sensor "
        "disconnected or wiring fault)",
        "check the wiring of {column}; replace the {value} readings of {column} in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "stuck_sensor": ProblemText(
        "{column} repeats {value} degC for {n_rows} samples in a row (at least "
        "{stuck_min_minutes} min) at {where} while another "
        "sensor changed by {stuck_min_other_change} degC or more: the sensor is stuck",
        "check sensor {column} and its logger channel; replace its readings in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
    ),
    "spike": ProblemText(
        "{column} jumps to {value} degC at {where}, more than {spike_threshold} degC away from "
        "both neighbouring readings",
        "replace the spike of {column} in {campaign}/{file} {rows} with an empty cell (and check "
        f"the sensor's wiring), {RERUN}",
    ),
    "displacement_range": ProblemText(
        "displacement {axis} reads {value} um at {where}, outside the probe range "
        "{displacement_low} to {displacement_high} um",
        "check probe {axis} (gap, range, unit um); replace the out-of-range readings in "
        f"{{campaign}}/{{file}} {{rows}} with empty cells, {RERUN}",
        column="{axis}",
    ),
    "missing_value": ProblemText(
        "{column} is empty at {where}",
        f"fill in {{column}} in {{campaign}}/{{file}} {{rows}} or delete the row, {RERUN}",
    ),
    "no_samples": ProblemText(
        "{campaign}/temperature.csv has no data rows",
        f"add the temperature log to data/raw/{{campaign}}/temperature.csv, {RERUN}",
        row_level=False,
    ),
    "too_few_samples": ProblemText(
        "{campaign}/temperature.csv has {value} sample(s); at least {min_samples} are needed to "
        "separate and model a thermal error",
        "add the rest of the temperature log to {campaign}/temperature.csv, or remove the "
        f"campaign folder (a campaign of a few samples cannot be modelled), {RERUN}",
        row_level=False,
    ),
    "too_few_readings": ProblemText(
        "{campaign} keeps {value} sample(s) once the gaps of missing readings longer than "
        "validate.max_bridged_gap_s = {max_bridged_gap_s} s are dropped (the warnings of the "
        "report name them); at least {min_samples} are needed to separate and model a thermal "
        "error",
        "fill in the missing readings the warnings name in the files of {campaign}, or raise "
        f"validate.max_bridged_gap_s in params.yaml to bridge longer gaps, {RERUN}",
        row_level=False,
    ),
    "temperature_unit": ProblemText(
        "{column} ({basis}) of {campaign}/temperature.csv reads {value} degC (median), above "
        "{air_temperature_max} degC, the warmest plausible air around a machine tool: the "
        "temperatures look like degF (a workshop at 20-38 degC reads 68-100 degF)",
        "export the temperatures of {campaign}/temperature.csv in degC ((degF - 32) / 1.8); if "
        "the air really was that warm, raise validate.air_temperature_max_degC in params.yaml; "
        f"{RERUN}",
        row_level=False,
    ),
    "displacement_unit": ProblemText(
        "displacement {axis} of {campaign}/displacement.csv spans only {value} um peak to peak "
        "while the temperatures rise by {rise} K: a thermal drift of at least "
        "{displacement_min_span} um is expected, so the values look like mm, not um (or the "
        "probe did not read)",
        "export displacement {axis} of {campaign}/displacement.csv in micrometres (mm x 1000), "
        "or check probe {axis}; if the machine really stays that still, lower "
        f"validate.displacement_min_span_um in params.yaml; {RERUN}",
        column="{axis}",
        row_level=False,
    ),
    "time_unit": ProblemText(
        "{campaign}/temperature.csv spans {value} min of elapsed_s (median interval "
        "{median_interval} s) but spindle_program: in {campaign}/campaign.yaml runs "
        "{program_min} min: the samples cover less than {min_program_coverage_pct} % of the "
        "program, so elapsed_s looks like minutes, not seconds",
        "write elapsed_s in seconds since start: (minutes x 60) in every CSV of {campaign}, or "
        "correct spindle_program: to the speeds that ran; if the log really stops early, lower "
        f"validate.min_program_coverage in params.yaml; {RERUN}",
        row_level=False,
    ),
    # ---- laser.csv
    "no_laser": ProblemText(
        "{campaign} is an axis_positioning campaign but {campaign}/laser.csv has no data rows",
        f"add the laser interferometer runs to data/raw/{{campaign}}/laser.csv, {RERUN}",
        row_level=False,
    ),
    "laser_direction": ProblemText(
        "direction {value} at {where} is neither '+' nor '-'",
        f"write + or - in the direction column of {{campaign}}/{{file}} {{rows}}, {RERUN}",
    ),
    "laser_run_one_direction": ProblemText(
        "run {run} mixes directions: direction {value} at {where} differs from most rows of the "
        "run (a run goes one way; a bidirectional pass is two runs)",
        "give every row of run {run} in {campaign}/{file} the same direction, or number the "
        f"reverse rows ({{rows}}) as a run of their own, {RERUN}",
    ),
    "laser_run_one_time": ProblemText(
        "run {run} has more than one elapsed_min: {value} min at {where} differs from most rows "
        "of the run",
        f"give every row of run {{run}} in {{campaign}}/{{file}} the same elapsed_min, {RERUN}",
    ),
    "laser_elapsed_nonnegative": ProblemText(
        "elapsed_min is negative ({value} min) at {where}",
        f"correct elapsed_min (minutes since start:) in {{campaign}}/{{file}} {{rows}}, {RERUN}",
    ),
    "laser_cold_run": ProblemText(
        "{campaign}/laser.csv has no run at elapsed_min 0: the cold-machine run carries the "
        "geometric error",
        "add the cold run (elapsed_min 0) to {campaign}/laser.csv, or correct the elapsed_min of "
        f"the run measured on the cold machine to 0, {RERUN}",
        row_level=False,
    ),
    "laser_bidirectional": ProblemText(
        "the pass at elapsed_min {elapsed_min} has only '{direction}' runs; each pass needs a "
        "'+' and a '-' run (the pass starts at {where})",
        "add the missing direction of the pass at elapsed_min {elapsed_min} to "
        "{campaign}/laser.csv, or correct the elapsed_min of its other run so that both runs "
        f"agree, {RERUN}",
    ),
    "laser_target_set": ProblemText(
        "target {value} mm of run {run} at {where} matches no target of the reference (cold) run "
        "within {laser_target_tolerance} mm",
        "measure every run at the same targets: correct target_mm in {campaign}/{file} {rows}, "
        "or raise validate.laser_target_tolerance_mm in params.yaml if the positions scatter "
        f"by design, {RERUN}",
    ),
    "laser_target_missing": ProblemText(
        "run {run} ('{direction}', elapsed_min {elapsed_min}) starting at {where} lacks the "
        "target(s) {value} mm of the reference (cold) run",
        "add the missing targets to run {run} in {campaign}/{file}, or remove the incomplete "
        f"run, {RERUN}",
    ),
    "laser_deviation_range": ProblemText(
        "deviation_um reads {value} um at {where}, outside the plausible range "
        "{laser_deviation_low} to {laser_deviation_high} um of a positioning error",
        "check the unit (um) and the export of {campaign}/{file} {rows}; correct the deviations "
        f"or raise validate.laser_deviation_range_um in params.yaml, {RERUN}",
    ),
    # ---- campaign.yaml
    "metadata_missing": ProblemText(
        "{yaml_key}: is missing or empty in {campaign}/campaign.yaml",
        "add {yaml_key}: to {campaign}/campaign.yaml (see " + CONTRACT + f"), {RERUN}",
        column="{yaml_key}",
    ),
    "kind_known": ProblemText(
        "kind {value} in {campaign}/campaign.yaml is not one of spindle_drift, axis_positioning",
        f"set kind: to spindle_drift or axis_positioning in {{campaign}}/campaign.yaml, {RERUN}",
        column="kind",
    ),
    "split_known": ProblemText(
        "split {value} in {campaign}/campaign.yaml is not train or validation",
        f"set split: to train or validation in {{campaign}}/campaign.yaml (or delete it: the "
        f"default is train), {RERUN}",
        column="split",
    ),
    "season_known": ProblemText(
        "season {value} in {campaign}/campaign.yaml is not spring, summer, autumn or winter",
        "correct season: in {campaign}/campaign.yaml, or delete it to derive the season from "
        f"start:, {RERUN}",
        column="season",
    ),
    "start_state_known": ProblemText(
        "start_state {value} in {campaign}/campaign.yaml is not cold or warm",
        "set start_state: cold (the machine was at rest at the air temperature at the first "
        "sample) or warm (it had been running), or delete the key, in "
        f"{{campaign}}/campaign.yaml, {RERUN}",
        column="start_state",
    ),
    "follows_format": ProblemText(
        "follows {value} in {campaign}/campaign.yaml is not a campaign id (letters, digits, "
        "'-', '_')",
        "set follows: to the id of the campaign this one continues without a break, or delete "
        f"the key, in {{campaign}}/campaign.yaml, {RERUN}",
        column="follows",
    ),
    "follows_other": ProblemText(
        "{campaign}/campaign.yaml says the campaign follows itself",
        "set follows: to the id of the campaign that ended where this one starts, or delete "
        f"the key, in {{campaign}}/campaign.yaml, {RERUN}",
        column="follows",
        row_level=False,
    ),
    "machine_unknown": ProblemText(
        "{campaign}/campaign.yaml names no machine, and the campaigns of this folder are of "
        "several ({machines}): its sensors cannot be told from theirs",
        "write machine: with the name of the machine it measured in {campaign}/campaign.yaml, "
        f"{RERUN}",
        column="machine",
        row_level=False,
    ),
    "follows_other_machine": ProblemText(
        "{campaign}/campaign.yaml says the campaign (machine {machine}) follows {value}, a "
        "campaign of machine {other_machine}",
        "correct machine: or follows: in {campaign}/campaign.yaml (a campaign continues one of "
        f"its own machine), {RERUN}",
        column="follows",
        row_level=False,
    ),
    "machine_name_clash": ProblemText(
        "machine {value} of {campaign}/campaign.yaml and machine {other_machine} of other "
        "campaigns are both written {key} in folder and model names",
        "write the machine's name exactly as the other campaigns of that machine do, or give "
        f"the machines names that differ in letters or digits, {RERUN}",
        column="machine",
        row_level=False,
    ),
    "campaign_id_format": ProblemText(
        "campaign_id {value} has characters other than letters, digits, '-' and '_'",
        f"rename the folder data/raw/{{campaign}} and its campaign_id:, {RERUN}",
        column="campaign_id",
    ),
    "campaign_id_unique": ProblemText(
        "campaign_id {value} is used by more than one campaign (this one in {source_dir})",
        f"give every campaign folder its own id (campaign_id: = folder name), {RERUN}",
        column="campaign_id",
    ),
    "stroke_positive": ProblemText(
        "axis stroke_mm {value} in {campaign}/campaign.yaml is not positive",
        f"set axis: stroke_mm: to the travel of the axis in mm in {{campaign}}/campaign.yaml, "
        f"{RERUN}",
        column="axis.stroke_mm",
    ),
    "json_readable": ProblemText(
        "the {yaml_key}: block of {campaign}/campaign.yaml was not stored as valid JSON by "
        "ingest (value {value})",
        "check the {yaml_key}: block of {campaign}/campaign.yaml; if it is correct this is an "
        f"ingest bug (data/ingested/campaigns.parquet, column {{column}}), {RERUN}",
        column="{yaml_key}",
    ),
    "sensors_declared": ProblemText(
        "{campaign}/campaign.yaml declares no temperature sensor under sensors:",
        "add one entry per temperature.csv column under sensors: in {campaign}/campaign.yaml "
        f"(e.g. T1: {{{{role: spindle_front_bearing}}}}), {RERUN}",
        column="sensors",
    ),
    "displacement_declared": ProblemText(
        "{campaign} is a spindle_drift campaign but its campaign.yaml declares no axis under "
        "displacement:",
        "add the probe axes under displacement: in {campaign}/campaign.yaml (e.g. "
        f"Z: {{{{probe: eddy_current}}}}), {RERUN}",
        column="displacement",
    ),
    "displacement_axis_known": ProblemText(
        "displacement: in {campaign}/campaign.yaml names an axis that is not a name of letters "
        "and digits starting with a letter ({value})",
        "name the displacement axes X, Y, Z (or e.g. Z2 for a second probe) in "
        f"{{campaign}}/campaign.yaml, {RERUN}",
        column="displacement",
    ),
    "axis_declared": ProblemText(
        "{campaign} is an axis_positioning campaign but its campaign.yaml has no axis: name:",
        f"add axis: {{{{name: <X|Y|Z>, stroke_mm: <travel>}}}} to {{campaign}}/campaign.yaml, "
        f"{RERUN}",
        column="axis.name",
    ),
    "sensor_role_known": ProblemText(
        "sensor {sensor} in {campaign}/campaign.yaml has role {value}, which is not in the "
        "closed vocabulary (" + ", ".join(SENSOR_ROLES) + ")",
        "set role: of {sensor} in {campaign}/campaign.yaml to one of the roles (other for "
        f"anything else), {RERUN}",
        column="sensors.{sensor}.role",
    ),
    "single_ambient": ProblemText(
        "sensors {value} of {campaign}/campaign.yaml all have role ambient; at most one sensor "
        "of a campaign may be ambient",
        "keep role: ambient only on the sensor that measures the air around the machine and give "
        f"the others their real role (or other) in {{campaign}}/campaign.yaml, {RERUN}",
        column="sensors",
        collapse=True,
    ),
    "campaign_metadata_missing": ProblemText(
        "{campaign} has {file} data but no campaign metadata (campaign.yaml missing or unreadable)",
        f"add a valid data/raw/{{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
        collapse=True,
    ),
    # ---- ingest: reading the raw files (pipeline.io.files, pipeline.io.reader)
    "missing_file": ProblemText(
        "{campaign}/{file} is missing; a {kind} campaign needs it",
        "add {campaign}/{file} in the raw contract format (" + CONTRACT + "), or correct kind: "
        f"in {{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "unreadable_yaml": ProblemText(
        "{where} cannot be parsed as YAML: {error}",
        "fix the YAML syntax of {campaign}/campaign.yaml at the line given (indentation, "
        f"unclosed brackets or quotes), {RERUN}",
    ),
    "unreadable_csv": ProblemText(
        "{campaign}/{file} cannot be split into cells near line {line}: {error}",
        f"save {{campaign}}/{{file}} again as {CSV_EXPORT}, {RERUN}",
        row_level=False,
    ),
    "missing_column": ProblemText(
        "{campaign}/{file} has no column {column} (header: {header})",
        f"write {{expected}} in {{campaign}}/{{file}}, {RERUN}",
        row_level=False,
    ),
    "reserved_column": ProblemText(
        "the name {name} in {campaign}/{file} is reserved by the pipeline "
        "(campaign_id, source_row, elapsed_s, rpm and disp_* name its own columns)",
        "rename the sensor or column {name} in campaign.yaml and the CSV file of "
        f"{{campaign}}, {RERUN}",
        row_level=False,
    ),
    "not_a_number": ProblemText(
        "{column} holds {value} at {where}, which is not a number",
        "write a number with '.' as the decimal point, or leave the cell empty for a missing "
        f"reading, in {{campaign}}/{{file}} {{rows}}, {RERUN}",
    ),
    "time_not_increasing": ProblemText(
        "elapsed_s does not increase at {where}",
        f"sort the rows of {{campaign}}/{{file}} by time and remove duplicated instants, {RERUN}",
    ),
    "unknown_axis": ProblemText(
        "displacement column {column} of {campaign}/{file} is not an axis name (X, Y, Z, or "
        "letters and digits starting with a letter, e.g. Z2)",
        "name the displacement columns of {campaign}/{file} as declared under displacement: in "
        f"campaign.yaml (X, Y, Z or e.g. Z2), {RERUN}",
        row_level=False,
    ),
    "campaign_id_mismatch": ProblemText(
        "campaign_id {value} in {campaign}/campaign.yaml differs from the folder name {campaign}",
        "set campaign_id: {campaign} in {campaign}/campaign.yaml, or rename the folder to the "
        f"id, {RERUN}",
        row_level=False,
    ),
    "unknown_kind": ProblemText(
        "kind {value} in {campaign}/campaign.yaml is not spindle_drift or axis_positioning",
        f"set kind: spindle_drift or kind: axis_positioning in {{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "bad_start": ProblemText(
        "start {value} in {campaign}/campaign.yaml is not an ISO 8601 date-time",
        "write start: YYYY-MM-DDTHH:MM:SS (local time of the first sample) in "
        f"{{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "no_sensors": ProblemText(
        "{campaign}/campaign.yaml declares no temperature sensor under sensors:",
        "list every temperature.csv column under sensors: with its role in "
        f"{{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "bad_spindle_program": ProblemText(
        "spindle_program entry {number} in {campaign}/campaign.yaml ({entry}) lacks a finite "
        "numeric from_min or rpm",
        "write the entries of spindle_program: as {{from_min: 0, to_min: 240, rpm: 4000}} in "
        f"{{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "bad_heat_load": ProblemText(
        "heat_loads entry {number} in {campaign}/campaign.yaml ({entry}) {detail}: every entry "
        "needs a role, a finite from_min (minutes since start:) and a finite power_W (W)",
        "write entry {number} of heat_loads: as {{role: column_rear, from_min: 0, to_min: 120, "
        "power_W: 300}} (to_min may be left out if the load stayed on to the end; a draught "
        f"that cools the part is a negative power_W) in {{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
    "heat_load_times": ProblemText(
        "heat_loads entry {number} in {campaign}/campaign.yaml ({entry}) has to_min {to_min} "
        "not after its from_min {from_min}: the load is never on",
        "give entry {number} of heat_loads: a to_min after its from_min (minutes since start:), "
        "or leave to_min out if the load stayed on to the end, in {campaign}/campaign.yaml, "
        f"{RERUN}",
        row_level=False,
    ),
    "heat_load_role": ProblemText(
        "heat_loads entry {number} in {campaign}/campaign.yaml has role {value}, which is not a "
        f"structure role ({', '.join(STRUCTURE_ROLES)})",
        "set role: of entry {number} of heat_loads: in {campaign}/campaign.yaml to the "
        "structure role of the part the load heated (the role its nearest sensor would have), "
        f"{RERUN}",
        row_level=False,
    ),
    "heat_loads_overlap": ProblemText(
        "heat_loads entries {other} and {number} in {campaign}/campaign.yaml both heat {role} "
        "at the same time (their from_min..to_min overlap, or the earlier one is open-ended)",
        "give the loads on {role} in heat_loads: of {campaign}/campaign.yaml times that follow "
        "each other (to_min of the earlier <= from_min of the later; while two devices heated "
        f"the part together, one entry with their summed power_W), {RERUN}",
        row_level=False,
    ),
    "empty_file": ProblemText(
        "{campaign}/{file} is empty ({size})",
        "copy {file} of the campaign again from the logger or the instrument ("
        + CONTRACT
        + f"), or remove the folder data/raw/{{campaign}}, {RERUN}",
        row_level=False,
    ),
    "binary_file": ProblemText(
        "{campaign}/{file} is not a text file: it holds binary data ({found})",
        "replace {campaign}/{file} with the text file the contract asks for (" + CONTRACT + "; "
        f"a CSV is {CSV_EXPORT}), {RERUN}",
        row_level=False,
    ),
    "not_utf8": ProblemText(
        "{campaign}/{file} is not UTF-8 text: byte {byte} on line {line} cannot be decoded "
        "(probably saved as Latin-1 / Windows-1252)",
        f"save {{campaign}}/{{file}} again as UTF-8 (a CSV as {CSV_EXPORT}), {RERUN}",
        row_level=False,
    ),
    "semicolon_separated": ProblemText(
        "{campaign}/{file} is separated by ';' (header {header}), with decimal commas if any: "
        "a spreadsheet export with a European list separator; the contract is comma-separated "
        "with decimal points",
        f"export {{campaign}}/{{file}} again as {CSV_EXPORT} rather than editing the numbers by "
        f"hand, {RERUN}",
        row_level=False,
    ),
    "no_data_rows": ProblemText(
        "{campaign}/{file} has a header but no data rows",
        "add the readings below the header of {campaign}/{file} (the export may have stopped "
        f"early), or remove the folder data/raw/{{campaign}}, {RERUN}",
        row_level=False,
    ),
    "field_count": ProblemText(
        "{where} has {n_fields} cells but the header has {n_header}",
        "give every row of {campaign}/{file} one cell per header column (an empty cell is a "
        f"missing reading; a decimal comma splits a number in two cells), {RERUN}",
    ),
    "duplicate_column": ProblemText(
        "{campaign}/{file} has the column {column} more than once",
        "keep one column {column} in {campaign}/{file}: rename the other (and declare it in "
        f"campaign.yaml) or delete it, {RERUN}",
        row_level=False,
    ),
    "not_finite": ProblemText(
        "{column} holds {value} at {where}: not a finite number (an overflow or a logger error "
        "code)",
        "replace the cell with the measured value, or leave it empty for a missing reading, in "
        f"{{campaign}}/{{file}}, {RERUN}",
    ),
    "laser_run_number": ProblemText(
        "run {value} at {where} is not a run number (a whole number)",
        "number the runs of {campaign}/{file} with whole numbers, one per run (a bidirectional "
        f"pass is two runs, one per direction), {RERUN}",
    ),
    "missing_key": ProblemText(
        "{column}: is missing in {campaign}/campaign.yaml; every campaign needs it",
        "add {column}: to {campaign}/campaign.yaml ({hint}; see " + CONTRACT + f"), {RERUN}",
        row_level=False,
    ),
    "wrong_type": ProblemText(
        "{column}: in {campaign}/campaign.yaml is {found}; it must be {expected}",
        "write {column}: in {campaign}/campaign.yaml as "
        + "{expected} (see "
        + CONTRACT
        + f"), {RERUN}",
        row_level=False,
    ),
    "misspelt_key": ProblemText(
        "{column}: in {campaign}/campaign.yaml is not a key of the contract but looks like "
        "{suggestion}:, which the file lacks (the keys there: {allowed})",
        "rename {column}: to {suggestion}: in {campaign}/campaign.yaml (a key the contract does "
        f"not have is read as a comment, see {CONTRACT}), {RERUN}",
        row_level=False,
    ),
    "campaign_id_unsafe": ProblemText(
        "campaign_id {value} in {campaign}/campaign.yaml is not a plain id: only letters, digits, "
        "'-' and '_' are allowed (a path such as '../x' is never followed)",
        f"set campaign_id: {{campaign}} (the folder name) in {{campaign}}/campaign.yaml, {RERUN}",
        row_level=False,
    ),
}

DROPPED_SAMPLES = "{n_dropped} sample(s) dropped (temperature.csv {dropped_rows})"
WARNING_TEXTS: dict[str, ProblemText] = {
    "missing_reading_bridged": ProblemText(
        "{column} has no reading at {where}: bridged by linear interpolation in time between "
        "rows {before} and {after}, {gap_s} s apart (validate.max_bridged_gap_s = "
        "{max_bridged_gap_s} s)",
        "nothing to do; if the readings exist, fill in {column} in {campaign}/{file} {rows}, "
        f"{RERUN}",
    ),
    "missing_reading_dropped": ProblemText(
        "{column} has no reading at {where}: "
        + DROPPED_SAMPLES
        + ": the gap of {gap_s} s between rows {before} and {after} is longer than "
        "validate.max_bridged_gap_s = {max_bridged_gap_s} s",
        "fill in {column} in {campaign}/{file} {rows} to keep these samples, or raise "
        f"validate.max_bridged_gap_s in params.yaml to bridge the gap, {RERUN}",
    ),
    "missing_reading_at_start": ProblemText(
        "{column} has no reading at {where}, the start of its record: "
        + DROPPED_SAMPLES
        + ", there is no reading before them to interpolate from; the campaign now starts at "
        "temperature.csv row {first_kept}, and a run is counted from its first sample",
        f"fill in {{column}} in {{campaign}}/{{file}} {{rows}} to keep the first samples, {RERUN}",
    ),
    "missing_reading_at_end": ProblemText(
        "{column} has no reading at {where}, the end of its record: "
        + DROPPED_SAMPLES
        + ", there is no reading after them to interpolate from; the campaign now ends at "
        "temperature.csv row {last_kept}, so a campaign that continues it without follows: is "
        "linked only if it starts within separate.runs.max_gap_s of that sample",
        "fill in {column} in {campaign}/{file} {rows} to keep the last samples (or declare "
        f"follows: in the campaign that continues this one), {RERUN}",
    ),
}
"""How each gap of missing readings (empty cells) is reported: a warning, never a problem.

The campaign stays valid; the validated samples are bridged or lose the gap's samples
(:mod:`pipeline.validation.gaps`).
"""

FALLBACK_TEXT = ProblemText(
    "{column} failed the check {check} at {where} (value {value})",
    "the ingested tables must follow schemas/ingested.py: check thermal ingest's output "
    f"(data/ingested/*.parquet) and the files of data/raw/{{campaign}}, {RERUN}",
)
"""Used for Pandera's own checks (dtype, uniqueness, ...) that have no entry above."""


def text_for(check: str) -> ProblemText:
    """Return the text of check or warning id ``check`` (:data:`FALLBACK_TEXT` when none)."""
    return PROBLEM_TEXTS.get(check) or WARNING_TEXTS.get(check, FALLBACK_TEXT)


def word(check: str, fields: Mapping[str, Any]) -> tuple[str, str]:
    """Return the message and the action of ``check`` filled in with ``fields``.

    Parameters
    ----------
    check : str
        Check id (a key of :data:`PROBLEM_TEXTS`).
    fields : mapping
        Template fields (``campaign``, ``file``, ``column``, ``where``, ...); a field the
        template names but ``fields`` lacks renders as '?'.

    Returns
    -------
    tuple of (str, str)
        ``(message, action)``.
    """
    text = text_for(check)
    filled = TemplateFields(fields)
    return text.message.format_map(filled), text.action.format_map(filled)

"""Typed params.yaml sections: every key checked; a message names its path and what is allowed."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from pipeline.config import load_section
from pipeline.errors import ParamsError
from pipeline.protocol.evaluation import check_models
from pipeline.protocol.selection_runs import method_entries
from pipeline.settings.base import load_settings, parse_section
from pipeline.settings.compensation import CompensationSettings
from pipeline.settings.discrepancy import DiscrepancySettings
from pipeline.settings.evaluate import EvaluateSettings
from pipeline.settings.ingest import IngestSettings
from pipeline.settings.model_axis import ModelAxisSettings
from pipeline.settings.protocol import ProtocolSettings
from pipeline.settings.select import SelectSettings
from pipeline.settings.separate import SeparateSettings
from pipeline.settings.track import TrackSettings
from pipeline.settings.tracking import TrackingSettings
from pipeline.settings.validate import ValidateSettings

REPO = Path(__file__).resolve().parents[1]
PARAMS = REPO / "params.yaml"
MODELS = {
    "ingest": IngestSettings,
    "validate": ValidateSettings,
    "separate": SeparateSettings,
    "protocol": ProtocolSettings,
    "select": SelectSettings,
    "model_axis": ModelAxisSettings,
    "evaluate": EvaluateSettings,
    "compensation": CompensationSettings,
    "discrepancy": DiscrepancySettings,
    "tracking": TrackingSettings,
    "track": TrackSettings,
}
"""Every section of params.yaml and its model."""

NESTED = {
    "separate": ("runs", "max_gap_s"),
    "evaluate": ("champion", "min_coverage"),
    "compensation": ("limits", "default", "max_rate_um_per_s"),
    "discrepancy": ("localise", "warmup_min"),
    "track": ("promotion", "min_improvement"),
}
"""A key below the top of a section, to misspell there too."""

DEFAULTS_NOT_SHIPPED = {
    # the code's default, kept: what a section without the key has always run with
    ("separate", "cold_n"),
    ("separate", "resample_s"),
    ("separate", "speed_responses"),
    ("evaluate", "n_jobs"),
    # the same choice written two ways: empty / None stand for "every registered effect",
    # the library's plausible sizes (params.yaml lists them)
    ("discrepancy", "candidates"),
    ("discrepancy", "max_effects"),
    ("discrepancy", "identifiability"),
}
"""Keys whose default differs from the value params.yaml ships, on purpose."""


def shipped(section: str) -> dict:
    return load_section(section, PARAMS)


def misspelt(key: str) -> str:
    return key[:-1] + key[-1] * 2


def _with(mapping: dict, path: tuple[str, ...], key: str, value: object) -> dict:
    """A deep copy of ``mapping`` with ``key`` set to ``value`` in the mapping at ``path``."""
    copy = yaml.safe_load(yaml.safe_dump(mapping))
    node = copy
    for part in path:
        node = node[part]
    node[key] = value
    return copy


@pytest.mark.parametrize("section", sorted(MODELS))
def test_the_shipped_params_load_in_every_model(section):
    settings = load_settings(MODELS[section], section, PARAMS)
    assert set(settings.model_fields_set) == set(shipped(section))


@pytest.mark.parametrize("section", sorted(MODELS))
def test_a_misspelt_key_stops_with_its_path_and_the_keys_allowed(section):
    model, content = MODELS[section], shipped(section)
    key = next(iter(content))
    with pytest.raises(ParamsError) as error:
        parse_section(model, section, _with(content, (), misspelt(key), 1), PARAMS)
    allowed = ", ".join(model.model_fields)
    assert str(error.value) == (
        f"{PARAMS}: {section}.{misspelt(key)}: unknown key (did you mean '{key}'?); "
        f"allowed here: {allowed}"
    )


@pytest.mark.parametrize("section", sorted(NESTED))
def test_a_misspelt_nested_key_names_its_full_path(section):
    *parents, key = NESTED[section]
    bad = _with(shipped(section), tuple(parents), misspelt(key), 1)
    path = ".".join([section, *parents, misspelt(key)])
    with pytest.raises(ParamsError, match=rf"^params.yaml: {path}: unknown key \(did you mean"):
        parse_section(MODELS[section], section, bad)


@pytest.mark.parametrize("section", sorted(MODELS))
def test_a_wrong_type_names_the_path_and_the_value(section):
    content = shipped(section)
    key = next(iter(content))
    with pytest.raises(ParamsError, match=rf"^params.yaml: {section}.{key} = True; \w"):
        parse_section(MODELS[section], section, _with(content, (), key, True))


def test_defaults_are_the_shipped_values_but_where_kept_on_purpose():
    differ = set()
    for section, model in MODELS.items():
        loaded = load_settings(model, section, PARAMS)
        for name, info in model.model_fields.items():
            if not info.is_required():
                default = info.get_default(call_default_factory=True)
                if default != getattr(loaded, name):
                    differ.add((section, name))
    assert differ == DEFAULTS_NOT_SHIPPED


def test_every_problem_of_a_section_is_one_line_of_the_message():
    bad = {**shipped("protocol"), "buffer": 1, "rank_by": "newest"}
    lines = str(pytest.raises(ParamsError, parse_section, ProtocolSettings, "protocol", bad).value)
    assert lines.splitlines() == [
        "params.yaml: protocol.rank_by = 'newest'; input should be 'auto', 'loso', 'loco' or "
        "'forward'",
        "params.yaml: protocol.buffer: unknown key (did you mean 'buffer_campaigns'?); allowed "
        "here: buffer_campaigns, forward_min_train, forward_min_share, forward_max_origins, "
        "max_folds, rank_by",
    ]


def test_a_missing_section_or_a_missing_required_key_says_what_to_add(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump({"ingest": {}}))
    with pytest.raises(ParamsError, match="ingest.max_alignment_gap_s: missing; add it"):
        load_settings(IngestSettings, "ingest", path)
    with pytest.raises(ParamsError, match="no section 'track'"):
        load_settings(TrackSettings, "track", path)


@pytest.mark.parametrize(
    "check, argument, message",
    [
        (
            check_models,
            EvaluateSettings(candidates={"mrl": "all"}),
            r"evaluate.candidates.mrl: unknown model \(did you mean 'mlr'\?\); registered: ",
        ),
        (
            check_models,
            EvaluateSettings(candidates={"bp": "all"}, model_params={"bp": {"max_epoch": 9}}),
            r"evaluate.model_params.bp.max_epoch: unknown hyper-parameter \(did you mean "
            r"'max_epochs'\?\); bp accepts: ",
        ),
        (
            method_entries,
            {"gra_top_k": {"kk": 4}},
            r"select.methods.gra_top_k.kk: unknown key \(did you mean 'k'\?\); allowed here: ",
        ),
        (
            method_entries,
            {"fc_grdd": {}},
            r"select.methods.fc_grdd: unknown selection method \(did you mean 'fc_grd'\?\)",
        ),
    ],
)
def test_names_from_a_registry_are_checked_as_keys(check, argument, message):
    with pytest.raises(ParamsError, match=message):
        check(argument)


def test_the_shipped_registry_names_pass():
    check_models(load_settings(EvaluateSettings, "evaluate", PARAMS))
    assert set(method_entries(load_settings(SelectSettings, "select", PARAMS).methods)) == set(
        shipped("select")["methods"]
    )


@pytest.mark.parametrize(
    "command, section, key",
    [
        ("separate-spindle", "separate", "cold_reference"),
        ("validate", "validate", "spike_threshold_degC"),
        ("evaluate", "evaluate", "full_grid"),
    ],
)
def test_a_stage_with_a_misspelt_key_stops_at_its_start(tmp_path, command, section, key):
    shutil.copy(PARAMS, tmp_path / "params.yaml")
    params = yaml.safe_load((tmp_path / "params.yaml").read_text())
    params[section][misspelt(key)] = params[section].pop(key)
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    done = subprocess.run(
        [sys.executable, "-m", "pipeline", command],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    lines = done.stderr.split(f"thermal {command}: error: ", 1)[1].splitlines()
    unknown = f"params.yaml: {section}.{misspelt(key)}: unknown key (did you mean '{key}'?)"
    assert any(line.startswith(unknown) for line in lines), done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.yaml"]  # no data read or written

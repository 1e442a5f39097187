"""Controller exports: linear forms of the candidates, coefficients.json, TEMPCOMP, SINUMERIK."""

import json
import re

import numpy as np
import pandas as pd
import pytest
from numpy.polynomial import Polynomial
from sklearn.exceptions import NotFittedError

from pipeline.compensation.exports import (
    ABSOLUTE,
    RISE,
    SPEED,
    LinearForm,
    Term,
    coefficients_document,
    linear_form,
    sinumerik_mapping,
    spindle_k0_mapping,
    tempcomp_formula,
)
from pipeline.models.axis_composite import pass_features
from pipeline.models.axis_fit import build
from pipeline.models.registry import MODELS, make_model
from pipeline.separation.axis import separate_axis
from pipeline.separation.features import InputSpec, SpeedResponses, speed_responses
from pipeline.settings.model_axis import ModelAxisSettings

SENSORS = ["T1", "T2", "T3"]
SPEED_INPUTS = ["speed_lag_30min", "speed2_lag_90min"]
INPUTS = SENSORS + SPEED_INPUTS
SPEED_SPEC = SpeedResponses((30.0, 90.0), (1.0, 2.0))
WINDOW_S = 180.0
SPEC = InputSpec(tuple(INPUTS), "temperature_rise", "first_sample", 1, SPEED_SPEC, WINDOW_S)
LINEAR = {"none", "mlr", "ridge", "dl", "pcdl", "ridge_dl", "pls_dl"}


def _campaign(name, seed, n=90):
    """Rises (K), two speed responses and an error (um) with a lag, as the models expect."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * WINDOW_S
    rise = np.column_stack(
        [6 * (1 - np.exp(-t / 2500)), 3 * (1 - np.exp(-t / 7000)), 2 * (1 - np.exp(-t / 4000))]
    ) + rng.normal(0, 0.05, (n, 3))
    rpm = np.where((t // 3600) % 2 == 0, 8000.0, 3000.0 + 1000 * seed)
    speed = speed_responses(t, rpm, SPEED_SPEC)[SPEED_INPUTS].to_numpy()
    y = 2.0 * rise[:, 0] - 1.0 * rise[:, 1] + 0.5 * np.roll(rise[:, 2], 1) + 1.5 * speed[:, 0]
    y = y + rng.normal(0, 0.2, n)
    index = pd.MultiIndex.from_arrays([[name] * n, t], names=["campaign_id", "elapsed_s"])
    return pd.DataFrame(np.column_stack([rise, speed]), columns=INPUTS, index=index), y


TRAIN = [_campaign("A", 1), _campaign("B", 2)]
X_TRAIN = pd.concat([x for x, _ in TRAIN])
Y_TRAIN = np.concatenate([y for _, y in TRAIN])
X_NEW = pd.concat([_campaign("C", 3, 60)[0], _campaign("D", 4, 40)[0]])


def _apply(intercept_um, terms, X):
    """Evaluate a coefficient table on X, lags per campaign, padded with the first value."""
    out = np.full(len(X), float(intercept_um))
    for name, lag, coefficient in terms:
        by_campaign = X[name].groupby(level="campaign_id", sort=False)
        shifted = by_campaign.shift(lag).fillna(by_campaign.transform("first"))
        out += coefficient * shifted.to_numpy()
    return out


def _rows(form):
    return [(t.input, t.lag, t.coefficient) for t in form.terms]


@pytest.fixture(scope="module", params=sorted(LINEAR))
def fitted_linear(request):
    return request.param, make_model(request.param).fit(X_TRAIN, Y_TRAIN)


def test_linear_form_reproduces_every_linear_model(fitted_linear):
    name, model = fitted_linear
    form = linear_form(model, SPEC)
    assert isinstance(form, LinearForm), name
    for X in (X_TRAIN, X_NEW):
        np.testing.assert_allclose(
            _apply(form.intercept_um, _rows(form), X), model.predict(X), rtol=0, atol=1e-6
        )
    assert form.window_s == WINDOW_S
    if name == "none":
        assert form.intercept_um == 0.0 and form.terms == ()
        return
    assert {t.input for t in form.terms} == set(INPUTS)
    lags = {(t.input, t.lag) for t in form.terms}
    assert lags == {(i, lag) for i in INPUTS for lag in range(form.max_lag + 1)}, name
    units = {t.input: (t.kind, t.unit) for t in form.terms}
    assert units["T1"] == (RISE, "K")
    assert units["speed_lag_30min"] == (SPEED, "(krpm)^1")
    assert units["speed2_lag_90min"] == (SPEED, "(krpm)^2")


def test_lagged_models_really_have_lags():
    for name in ("ridge_dl", "pls_dl"):
        form = linear_form(make_model(name).fit(X_TRAIN, Y_TRAIN), SPEC)
        assert form.max_lag == 2
        assert any(t.lag == 2 and abs(t.coefficient) > 1e-9 for t in form.terms), name


@pytest.mark.parametrize("name", sorted(set(MODELS) - LINEAR))
def test_models_not_linear_in_their_inputs_get_their_reason(name):
    reason = linear_form(make_model(name), SPEC)
    assert isinstance(reason, str) and "not linear" in reason
    assert type(make_model(name)).__name__ in reason


def test_fitted_feedback_model_gets_the_reason_and_unknown_estimators_one_too():
    adl = make_model("adl").fit(X_TRAIN[SENSORS], Y_TRAIN)
    assert "AR terms" in linear_form(adl, SPEC)
    assert "no coefficient table is known" in linear_form(object(), SPEC)


def test_linear_form_needs_a_fit_and_the_spec_of_the_inputs():
    with pytest.raises(NotFittedError):
        linear_form(make_model("dl"), SPEC)
    narrow = InputSpec(("T1",), "temperature_rise", "first_sample", 1)
    with pytest.raises(ValueError, match="T2"):
        linear_form(make_model("mlr").fit(X_TRAIN, Y_TRAIN), narrow)


RANGES = {"T1": [19.0, 26.5], "rise_T1": [0.0, 7.5], "speed_lag_30min": [0.0, 8.0]}
CARD = {"axis": "Z", "model": "ridge_dl", "selection": "all_speed", "sample_interval_s": 60.0}


def test_coefficients_document_rebuilds_the_prediction_and_defines_every_input():
    model = make_model("ridge_dl").fit(X_TRAIN, Y_TRAIN)
    doc = json.loads(
        json.dumps(coefficients_document(linear_form(model, SPEC), SPEC, RANGES, CARD))
    )
    assert (doc["axis"], doc["model"], doc["selection"], doc["linear"]) == (
        "Z",
        "ridge_dl",
        "all_speed",
        True,
    )
    assert doc["output"]["unit"] == "um" and "negative" in doc["output"]["sign"]
    assert doc["sample_window_s"] == WINDOW_S
    terms = [(t["input"], t["lag_samples"], t["coefficient"]) for t in doc["terms"]]
    np.testing.assert_allclose(
        _apply(doc["intercept_um"], terms, X_NEW), model.predict(X_NEW), rtol=0, atol=1e-6
    )
    assert all(t["lag_s"] == t["lag_samples"] * WINDOW_S for t in doc["terms"])
    units = {t["input"]: t["coefficient_unit"] for t in doc["terms"]}
    assert units["T2"] == "um/K" and units["speed2_lag_90min"] == "um/(krpm)^2"
    t1 = doc["inputs"]["T1"]
    assert (t1["kind"], t1["unit"], t1["reference"]) == (RISE, "K", "first sample of the run")
    assert t1["training_range"] == {"reading_degC": [19.0, 26.5], "rise_K": [0.0, 7.5]}
    assert doc["inputs"]["T3"]["training_range"] == {"reading_degC": None, "rise_K": None}
    speed = doc["inputs"]["speed2_lag_90min"]
    assert (speed["kind"], speed["exponent"], speed["time_constant_min"]) == (SPEED, 2.0, 90.0)
    assert "exp(-dt / tau)" in speed["recursion"] and "rest" in speed["initial"]
    assert doc["inputs"]["speed_lag_30min"]["training_range"] == [0.0, 8.0]


def test_coefficients_document_other_reference_window_from_the_card_and_reason():
    spec = InputSpec(("T1",), "absolute", "mean_first_n", 5, None, None)
    form = LinearForm(-3.0, (Term("T1", 0, 1.2, ABSOLUTE, "degC"),), None)
    doc = coefficients_document(form, spec, RANGES, CARD)
    assert doc["sample_window_s"] == 60.0
    assert doc["inputs"]["T1"] == {
        "kind": ABSOLUTE,
        "sensor": "T1",
        "unit": "degC",
        "training_range": {"reading_degC": [19.0, 26.5]},
    }
    rise = InputSpec(("T1",), "temperature_rise", "mean_first_n", 5, None, 30.0)
    assert coefficients_document(form, rise, {}, CARD)["inputs"]["T1"]["reference"] == (
        "mean of the first 5 samples of the run"
    )
    reason = linear_form(make_model("bp"), SPEC)
    card = {**CARD, "model": "bp", "selection": "best_subset"}
    assert coefficients_document(reason, SPEC, RANGES, card) == {
        "axis": "Z",
        "model": "bp",
        "selection": "best_subset",
        "linear": False,
        "reason": reason,
    }


RISE_SPEC = InputSpec(("T1", "T2", "T3"), "temperature_rise", "first_sample", 1, None, 60.0)
ABS_SPEC = InputSpec(("T1", "T2"), "absolute", "first_sample", 1, None, 60.0)


def _rise(name, coefficient, lag=0):
    return Term(name, lag, coefficient, RISE, "K")


def _evaluate(formula, **values):
    assert re.fullmatch(r"[0-9A-Z.e*+\-()]+", formula), formula
    return eval(formula, {"__builtins__": {}}, values)  # noqa: S307 (checked characters)


def _bound(text):
    return float(re.search(r"over the training ranges: at most ([0-9.e+-]+) um", text)[1])


def test_tempcomp_formula_fits_and_stays_within_its_stated_rounding_error():
    form = LinearForm(0.35, (_rise("T1", 2.134),), 60.0)
    formula, text = tempcomp_formula(form, RISE_SPEC, training_ranges={"rise_T1": [0.0, 7.5]})
    assert formula == "0.002134*(T01-R01)+3.5e-4"
    assert "25 of 31 characters, 2 of 16 variables" in text and "first sample" in text
    mm = _evaluate(formula, T01=27.5, R01=20.0)
    assert mm == pytest.approx((0.35 + 2.134 * 7.5) / 1000, abs=1e-12)
    long = LinearForm(-0.3512345, (_rise("T1", -2.13456789),), 60.0)
    formula, text = tempcomp_formula(long, RISE_SPEC, training_ranges={"rise_T1": [0.0, 7.5]})
    assert formula == "-0.0021346*(T01-R01)-3.5123e-4"  # 32 characters at 6 digits
    assert "30 of 31 characters" in text and "to 5 significant digits" in text
    for rise in (0.0, 3.0, 7.5):
        error_um = abs(
            _evaluate(formula, T01=20.0 + rise, R01=20.0) * 1000 - (-0.3512345 - 2.13456789 * rise)
        )
        assert error_um <= _bound(text) + 1e-12
    assert _bound(text) < 0.005 * (0.3512345 + 2.13456789 * 7.5)


def test_tempcomp_formula_absolute_temperatures_and_named_operands():
    form = LinearForm(
        -12.0, (Term("T1", 0, 1.5, ABSOLUTE, "degC"), Term("T2", 0, -0.8, ABSOLUTE, "degC")), 60.0
    )
    formula, _ = tempcomp_formula(form, ABS_SPEC, variables={"T1": "W486", "T2": "W488"})
    assert formula == "0.0015*W486-8e-4*W488-0.012"
    assert _evaluate(formula, W486=30.0, W488=25.0) == pytest.approx((-12 + 45 - 20) / 1000)
    with pytest.raises(ValueError, match="upper case"):
        tempcomp_formula(form, ABS_SPEC, variables={"T1": "w486"})
    assert tempcomp_formula(LinearForm(0.0, (), 60.0), RISE_SPEC)[0] == "0"


def test_tempcomp_formula_rejects_too_long_and_too_many_variables_with_the_numbers():
    three = LinearForm(0.35, (_rise("T1", 2.134), _rise("T2", -1.27), _rise("T3", 0.52)), 60.0)
    formula, reason = tempcomp_formula(three, RISE_SPEC)
    # at 2 significant digits: 0.0021*(T01-R01) -0.0013*(T02-R02) +5.2e-4*(T03-R03) +3.5e-4
    assert formula is None
    assert f"needs {16 + 17 + 17 + 7} characters" in reason and "at most 31" in reason
    nine = [f"S{i}" for i in range(9)]
    spec = InputSpec(tuple(nine), "temperature_rise", "first_sample", 1, None, 60.0)
    formula, reason = tempcomp_formula(
        LinearForm(0.0, tuple(_rise(s, 1.0) for s in nine), 60.0), spec
    )
    assert formula is None and "needs 18 variables" in reason and "at most 16" in reason


def test_tempcomp_formula_rejects_state_and_non_linear_models():
    lagged = LinearForm(0.0, (_rise("T1", 2.0), _rise("T1", 0.0, 1), _rise("T2", 1.0, 2)), 60.0)
    formula, reason = tempcomp_formula(lagged, RISE_SPEC)
    assert formula is None and "T2 at lag 2" in reason and "T1 at lag 1" not in reason
    speed = LinearForm(0.0, (Term("speed_lag_30min", 0, 1.5, SPEED, "(krpm)^1"),), 60.0)
    formula, reason = tempcomp_formula(speed, SPEC)
    assert formula is None and "speed responses" in reason
    formula, reason = tempcomp_formula("BackPropagationRegressor is not linear", SPEC)
    assert formula is None and "not linear" in reason


AXIS_SENSORS = ["T1", "T2", "T3"]
GEOMETRIC = (1.5, -0.07, 1.8e-4, 1.3e-6, -3.0e-9)
AXIS_PARAMS = {
    "temperature": "rise",
    "selection_rule": "aicc",
    "exclude_sensors": [],
    "max_exhaustive": 25,
    "patent_band_um": 3.5,
}


def _axis_campaign(campaign_id, split, minutes, ambient, seed):
    """Raw-like tables of one Y-axis laser campaign whose thermal slope follows the T2 rise."""
    rng = np.random.default_rng(seed)
    t = np.asarray(minutes, dtype=float)
    temperatures = pd.DataFrame(
        {
            s: ambient + gain * (1 - np.exp(-t / tau)) + 0.05 * rng.standard_normal(t.size)
            for s, gain, tau in zip(
                AXIS_SENSORS, (8.0, 10.0, 4.0), (30.0, 60.0, 200.0), strict=True
            )
        }
    )
    slope = 0.012 * (temperatures["T2"] - temperatures["T2"].iloc[0]).to_numpy()
    targets = np.arange(0.0, 281.0, 20.0)
    laser = pd.concat(
        [
            pd.DataFrame(
                {
                    "elapsed_min": minute,
                    "run": 2 * i + j,
                    "direction": direction,
                    "target_mm": targets,
                    "deviation_um": Polynomial(GEOMETRIC)(targets)
                    + k * targets
                    + 0.05 * rng.standard_normal(targets.size),
                }
            )
            for i, (minute, k) in enumerate(zip(t, slope, strict=True))
            for j, direction in enumerate("+-")
        ],
        ignore_index=True,
    ).assign(campaign_id=campaign_id)
    campaigns = pd.DataFrame(
        {
            "campaign_id": [campaign_id],
            "split": [split],
            "season": ["spring"],
            "axis_name": ["Y"],
            "synthetic": [True],
            "sensors_json": [json.dumps(dict.fromkeys(AXIS_SENSORS, {}))],
        }
    )
    samples = temperatures.assign(campaign_id=campaign_id, elapsed_s=t * 60.0)
    return separate_axis(campaigns, samples, laser, order=4)


@pytest.fixture(scope="module")
def axis_tables():
    parts = [
        _axis_campaign("A01", "train", [0, 15, 30, 50, 75, 100, 140, 190, 250, 320], 20.0, 1),
        _axis_campaign("A02", "validation", [0, 40, 100, 160, 220], 14.0, 2),
    ]
    return {name: pd.concat([p[name] for p in parts], ignore_index=True) for name in parts[0]}


@pytest.mark.parametrize("temperature", ["rise", "absolute"])
def test_sinumerik_mapping_reproduces_the_thermal_part_of_the_axis_model(axis_tables, temperature):
    params = ModelAxisSettings(**{**AXIS_PARAMS, "temperature": temperature})
    report, _, points = build(
        params, axis_tables["slopes"], axis_tables["geometric"], axis_tables["thermal"]
    )
    report = json.loads(json.dumps(report))
    mapping = sinumerik_mapping(report, "Y")
    assert mapping["K0"]["value_mm"] == 0.0 and mapping["P0"]["value_mm"] == 0.0
    assert mapping["MD32750"]["value"] == 2 and mapping["MD32750"]["bits_set"] == [1]
    assert mapping["tan_beta"]["setting_data"].startswith("SD43910")
    tan_beta = mapping["tan_beta"]
    sensors = list(tan_beta["coefficients_per_unit"])
    temperatures = pass_features(axis_tables["slopes"], sensors, temperature).reset_index()
    temperatures["elapsed_min"] = temperatures.pop("elapsed_s") / 60.0
    rows = points.merge(temperatures, on=["campaign_id", "elapsed_min"], validate="many_to_one")
    slope = tan_beta["constant"] + sum(
        c * rows[s] for s, c in tan_beta["coefficients_per_unit"].items()
    )
    x_mm = rows["target_mm"].to_numpy()
    siemens_um = 1000.0 * (mapping["K0"]["value_mm"] + slope * (x_mm - mapping["P0"]["value_mm"]))
    geometric = Polynomial(report["geometric"]["coefficients_um_per_mm_power"])(x_mm)
    np.testing.assert_allclose(siemens_um, rows["predicted_um"] - geometric, rtol=0, atol=1e-9)
    assert 0.0 < np.abs(slope).max() < 0.01  # thermal, and far below MD32760's tan beta cap
    if temperature == "rise":
        assert tan_beta["constant"] == 0.0
        assert tan_beta["coefficients_per_unit"]["T2"] == pytest.approx(1.2e-5, rel=0.05)
    else:
        assert tan_beta["constant"] != 0.0


def test_sinumerik_mapping_is_none_without_a_linear_axis_model(axis_tables):
    report, _, _ = build(
        ModelAxisSettings(**AXIS_PARAMS),
        axis_tables["slopes"],
        axis_tables["geometric"],
        axis_tables["thermal"],
    )
    assert sinumerik_mapping(report, "X") is None
    assert sinumerik_mapping({"status": "no_axis_campaign", "message": "none"}, "Y") is None


def test_spindle_k0_mapping_converts_the_runtime_offset_to_the_error_in_mm():
    mapping = spindle_k0_mapping("Z")
    assert mapping["MD32750"]["value"] == 1 and mapping["MD32750"]["bits_set"] == [0]
    assert mapping["K0"]["setting_data"].startswith("SD43900")
    offset_um = -5.0  # the runtime's correction for a predicted error of +5 um
    assert offset_um * mapping["K0"]["mm_per_offset_um"] == pytest.approx(0.005)
    assert 5.0 * spindle_k0_mapping("Z", offset_sign=1)["K0"]["mm_per_offset_um"] == 0.005
    with pytest.raises(ValueError, match="offset_sign"):
        spindle_k0_mapping("Z", offset_sign=0)

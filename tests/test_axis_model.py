import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from numpy.polynomial import Polynomial

from pipeline import paths
from pipeline.io.reader import read_campaign
from pipeline.io.tables import tabulate
from pipeline.models import axis_fit
from pipeline.models.axis_composite import (
    CompositeModel,
    bands,
    candidate_sensors,
    fit_slope_model,
    pass_features,
    pass_slopes,
    score_campaigns,
    select_sensors,
)
from pipeline.reporting import axis_model
from pipeline.separation.axis import separate_axis
from pipeline.settings.model_axis import ModelAxisSettings
from pipeline.stages import model_axis

RAW = Path(__file__).resolve().parents[1] / "data" / "raw"
SENSORS = ["T1", "T2", "T3", "T4", "T5"]
GEOMETRIC = (1.5, -0.07, 1.8e-4, 1.3e-6, -3.0e-9)  # um / mm^p, a 4th-order polynomial
TRUE_SLOPE = {"T2": 0.012, "T4": -0.005}  # um/mm per K of rise; the other sensors play no part
NOISE_UM = 0.05
PARAMS = {
    "temperature": "rise",
    "selection_rule": "aicc",
    "exclude_sensors": [],
    "max_exhaustive": 25,
    "patent_band_um": 3.5,
}


def _planted_campaign(campaign_id, split, minutes, time_constants, ambient, seed):
    """Raw-like tables of one axis campaign whose thermal slope is linear in T2 and T4 rises."""
    rng = np.random.default_rng(seed)
    t = np.asarray(minutes, dtype=float)
    gains = [8.0, 10.0, 4.0, 6.0, 3.0]
    temperatures = pd.DataFrame(
        {
            s: ambient + g * (1 - np.exp(-t / tau)) + 0.05 * rng.standard_normal(t.size)
            for s, g, tau in zip(SENSORS, gains, time_constants, strict=True)
        }
    )
    rises = temperatures - temperatures.iloc[0]
    slope = sum(c * rises[s] for s, c in TRUE_SLOPE.items()).to_numpy()
    targets = np.arange(0.0, 281.0, 10.0)
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
                    + NOISE_UM * rng.standard_normal(targets.size),
                }
            )
            for i, (minute, k) in enumerate(zip(t, slope, strict=True))
            for j, direction in enumerate("+-")
        ],
        ignore_index=True,
    ).assign(campaign_id=campaign_id)
    samples = temperatures.assign(campaign_id=campaign_id, elapsed_s=t * 60.0)
    campaigns = pd.DataFrame(
        {
            "campaign_id": [campaign_id],
            "split": [split],
            "season": ["spring"],
            "axis_name": ["Y"],
            "synthetic": [True],
            "sensors_json": [json.dumps(dict.fromkeys(SENSORS, {}))],
        }
    )
    return campaigns, samples, laser


@pytest.fixture(scope="module")
def planted():
    train = _planted_campaign(
        "A01",
        "train",
        [0, 15, 30, 50, 75, 100, 140, 190, 250, 320, 390],
        [30, 60, 120, 200, 400],
        20.0,
        1,
    )
    valid = _planted_campaign(
        "A02", "validation", [0, 40, 100, 160, 220, 280], [50, 40, 150, 120, 300], 14.0, 2
    )
    tables = [separate_axis(*parts, order=4) for parts in (train, valid)]
    return {name: pd.concat([t[name] for t in tables], ignore_index=True) for name in tables[0]}


def _fit(tables, params=PARAMS):
    settings = ModelAxisSettings(**params)
    return axis_fit.build(settings, tables["slopes"], tables["geometric"], tables["thermal"])


def test_planted_sensors_and_coefficients_recovered(planted):
    report, _, _ = _fit(planted)
    assert report["status"] == "ok"
    assert sorted(report["selection"]["selected"]) == ["T2", "T4"]
    assert sorted(report["selection"]["winners"]["aicc"]) == ["T2", "T4"]
    coefficients = report["slope_model"]["coefficients"]
    for sensor, value in TRUE_SLOPE.items():
        assert coefficients[sensor] == pytest.approx(value, abs=5e-4)
    assert report["slope_model"]["k0_um_per_mm"] == pytest.approx(0.0, abs=1e-3)
    assert report["slope_model"]["coefficients_unit"] == "um/mm per K"
    c0, c1 = report["geometric"]["coefficients_um_per_mm_power"][:2]
    assert c0 == pytest.approx(GEOMETRIC[0], abs=0.1)
    assert c1 == pytest.approx(GEOMETRIC[1], abs=2e-3)


def test_planted_validation_band_is_near_the_noise(planted):
    report, metrics, points = _fit(planted)
    validation = report["scores"]["validation"]
    assert validation["overall"]["n_points"] == 6 * 29
    assert metrics["residual_max_abs_um"] < 6 * NOISE_UM
    assert metrics["rmse_um"] < 2 * NOISE_UM
    assert metrics["residual_min_um"] < 0 < metrics["residual_max_um"]
    assert set(validation["by_campaign"]["A02"]["by_pass_min"]) == {
        "0",
        "40",
        "100",
        "160",
        "220",
        "280",
    }
    assert report["within_patent_band"] is True
    assert set(points["role"]) == {"fit", "validation"}


def test_absolute_temperatures_give_the_same_slope_coefficients_on_one_campaign(planted):
    train = planted["slopes"].query("split == 'train'")
    rise = fit_slope_model(train, ["T2", "T4"], "rise")
    absolute = fit_slope_model(train, ["T2", "T4"], "absolute")
    np.testing.assert_allclose(absolute.coefficients, rise.coefficients, rtol=1e-8)
    cold = pass_features(train, ["T2", "T4"], "absolute").iloc[[0]]
    assert absolute.k0 == pytest.approx(float(absolute.slope(cold)[0]))
    assert absolute.intercept != pytest.approx(rise.intercept)


def test_absolute_mode_carries_the_ambient_difference_into_validation(planted):
    # the validation campaign starts 6 K colder: the patent's frozen k0 reads that as a slope
    _, rise, _ = _fit(planted)
    _, absolute, _ = _fit(planted, {**PARAMS, "temperature": "absolute"})
    assert absolute["residual_max_abs_um"] > 5 * rise["residual_max_abs_um"]


def test_pass_features_are_rises_from_each_campaigns_cold_pass(planted):
    features = pass_features(planted["slopes"], SENSORS, "rise")
    assert list(features.index.names) == ["campaign_id", "elapsed_s"]
    cold = features.groupby(level="campaign_id").head(1)
    assert (cold.to_numpy() == 0).all()
    assert len(pass_slopes(planted["slopes"])) == len(features)


def test_no_validation_campaign_scores_the_fit_only(planted, tmp_path):
    tables = {name: frame.query("campaign_id == 'A01'") for name, frame in planted.items()}
    report, metrics, points = _fit(tables)
    axis_model.plot(points, report, tmp_path / "fit.png")
    assert (tmp_path / "fit.png").stat().st_size > 0
    assert report["status"] == "no_validation_campaign"
    assert "no validation axis campaign" in report["message"]
    assert "validation" not in report["scores"]
    assert metrics["n_validation_points"] == 0 and "rmse_um" not in metrics
    assert set(points["role"]) == {"fit"}


def test_no_axis_campaign_at_all(tmp_path):
    empty = pd.DataFrame()
    report, metrics, points = axis_fit.build(ModelAxisSettings(**PARAMS), empty, empty, empty)
    axis_model.plot(points, report, tmp_path / "none.png")
    assert (tmp_path / "none.png").stat().st_size > 0
    assert report["status"] == "no_axis_campaign"
    assert metrics == {} and points.empty


def test_no_training_campaign(planted):
    tables = {name: frame.query("campaign_id == 'A02'") for name, frame in planted.items()}
    report, _, _ = _fit(tables)
    assert report["status"] == "no_training_campaign"
    assert "A02" in report["message"]


def test_selected_sensor_missing_in_validation_is_a_clear_error(planted):
    slopes = planted["slopes"].copy()
    slopes.loc[slopes["campaign_id"] == "A02", "T4"] = np.nan
    with pytest.raises(ValueError, match=r"A02 \(validation\).*sensor T4.*exclude_sensors"):
        _fit({**planted, "slopes": slopes})


def test_excluded_sensor_is_never_selected(planted):
    report, _, _ = _fit(planted, {**PARAMS, "exclude_sensors": ["T4"]})
    assert "T4" not in report["selection"]["selected"]
    assert "T4" not in report["selection"]["candidates"]


def test_parameter_errors_name_the_setting(planted):
    train = planted["slopes"].query("split == 'train'")
    with pytest.raises(ValueError, match="model_axis.temperature"):
        pass_features(train, ["T1"], "kelvin")
    with pytest.raises(ValueError, match="model_axis.selection_rule"):
        select_sensors(pass_features(train, ["T1"], "rise"), pass_slopes(train), "bic")
    with pytest.raises(ValueError, match="more passes"):
        fit_slope_model(train.head(3), ["T1", "T2"], "rise")
    with pytest.raises(ValueError, match="model_axis.exclude_sensors"):
        candidate_sensors(train, exclude=SENSORS)


def test_bands_per_campaign_and_pass():
    points = pd.DataFrame(
        {
            "campaign_id": ["X"] * 4,
            "elapsed_min": [0.0, 0.0, 40.0, 40.0],
            "residual_um": [-1.0, 0.5, 2.0, -3.0],
        }
    )
    result = bands(points)
    assert result["overall"] == {
        "n_points": 4,
        "residual_min_um": -3.0,
        "residual_max_um": 2.0,
        "residual_max_abs_um": 3.0,
        "rmse_um": pytest.approx(np.sqrt(14.25 / 4)),
    }
    assert result["by_campaign"]["X"]["by_pass_min"]["40"]["residual_min_um"] == -3.0


def test_composite_is_the_geometric_polynomial_at_the_cold_pass(planted):
    train = planted["slopes"].query("split == 'train'")
    slope = fit_slope_model(train, ["T2", "T4"], "rise")
    model = CompositeModel(geometric=GEOMETRIC, slope=slope)
    points = score_campaigns(model, train, planted["thermal"].query("campaign_id == 'A01'"))
    cold = points[points["elapsed_min"] == 0]
    np.testing.assert_allclose(cold["predicted_um"], Polynomial(GEOMETRIC)(cold["target_mm"]))


@pytest.fixture(scope="module")
def demo():
    read = [read_campaign(RAW / name, max_alignment_gap_s=200.0) for name in ("Y01", "Y02")]
    raw = tabulate(read)
    return separate_axis(raw["campaigns"], raw["samples"], raw["laser"], order=4)


def test_demo_validation_band_is_reported_and_finite(demo):
    report, metrics, _ = _fit(demo)
    assert report["training_campaigns"] == ["Y01"]
    assert report["validation_campaigns"] == ["Y02"]
    assert report["synthetic"] is True
    assert report["selection"]["selected"]
    assert set(report["selection"]["winners"]) == {"adj_r2", "aicc"}
    for key in ("residual_min_um", "residual_max_um", "residual_max_abs_um", "rmse_um"):
        assert np.isfinite(metrics[key])
    assert metrics["n_validation_points"] == 6 * 29


def test_stage_writes_report_metrics_and_figure(planted, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "params.yaml").write_text(
        "model_axis:\n" + "".join(f"  {k}: {json.dumps(v)}\n" for k, v in PARAMS.items())
    )
    paths.SEPARATED.mkdir(parents=True)
    planted["slopes"].assign(machine="vmc 450").to_parquet(paths.AXIS_SLOPES)
    planted["geometric"].assign(machine="vmc 450").to_parquet(paths.AXIS_GEOMETRIC)
    planted["thermal"].assign(machine="vmc 450").to_parquet(paths.AXIS_THERMAL_ERROR)
    assert model_axis.main([]) == 0
    report = json.loads(paths.AXIS_MODEL_REPORT.read_text())["machines"]["vmc 450"]
    metrics = json.loads(paths.AXIS_MODEL_METRICS.read_text())["machines"]["vmc 450"]
    assert report["status"] == "ok"
    assert (
        metrics["residual_max_abs_um"]
        == report["scores"]["validation"]["overall"]["residual_max_abs_um"]
    )
    assert (paths.AXIS_MODEL_PLOTS / "vmc-450.png").stat().st_size > 0


def test_stage_without_separation_tables_says_which_stage_to_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "params.yaml").write_text(yaml.safe_dump({"model_axis": PARAMS}))
    with pytest.raises(FileNotFoundError, match="separate_axis"):
        model_axis.main([])

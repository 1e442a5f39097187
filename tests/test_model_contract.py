"""One contract over every registered model (in the spirit of scikit-learn's test_common.py)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from pipeline.models.registry import MODELS, make_model

SENSORS = ["T1", "T2", "T3"]


def _campaign(name, seed, n=90):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 180.0
    rise = np.column_stack(
        [6 * (1 - np.exp(-t / 2500)), 3 * (1 - np.exp(-t / 7000)), 2 * (1 - np.exp(-t / 4000))]
    )
    rise = rise + rng.normal(0, 0.05, rise.shape)
    y = 2.0 * rise[:, 0] - 1.0 * rise[:, 1] + 0.5 * np.roll(rise[:, 2], 1) + rng.normal(0, 0.2, n)
    y[0] = 0.0
    index = pd.MultiIndex.from_arrays([[name] * n, t], names=["campaign_id", "elapsed_s"])
    return pd.DataFrame(rise, columns=SENSORS, index=index), y


A = _campaign("A", 1)
B = _campaign("B", 2)
BOTH = (pd.concat([A[0], B[0]]), np.concatenate([A[1], B[1]]))


def _predict(model, X, y=None):
    if getattr(model, "needs_error_feedback", False) and y is not None:
        return model.predict(X, y_history=y)
    return model.predict(X)


@pytest.fixture(scope="module", params=sorted(MODELS))
def fitted(request):
    name = request.param
    return name, make_model(name).fit(*BOTH)


def test_registry_rejects_unknown_names_and_hyper_parameters():
    with pytest.raises(KeyError, match="registered"):
        make_model("no_such_model")
    with pytest.raises(TypeError, match="unknown hyper-parameter"):
        make_model("mlr", no_such_parameter=1)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_unfitted_model_is_cloneable_and_refuses_to_predict(name):
    model = make_model(name)
    assert clone(model).get_params() == model.get_params()
    with pytest.raises(NotFittedError):
        model.predict(A[0])


def test_fit_returns_self_and_predict_has_one_finite_value_per_row(fitted):
    name, model = fitted
    for X, y in (A, B):
        for history in (None, y):
            predicted = _predict(model, X, history)
            assert predicted.shape == (len(X),), name
            assert np.isfinite(predicted).all(), name
    assert isinstance(getattr(model, "chosen_params_", {}), dict)


def test_same_seed_same_predictions(fitted):
    name, model = fitted
    again = clone(model).fit(*BOTH)
    np.testing.assert_allclose(_predict(again, *A), _predict(model, *A), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(_predict(again, A[0]), _predict(model, A[0]), rtol=1e-10, atol=1e-10)


def test_no_leakage_across_campaigns_in_prediction(fitted):
    name, model = fitted
    n = len(A[0])
    alone = _predict(model, A[0])
    together = _predict(model, BOTH[0])[:n]
    np.testing.assert_allclose(together, alone, rtol=1e-9, atol=1e-9, err_msg=name)
    if getattr(model, "needs_error_feedback", False):
        alone = _predict(model, *A)
        together = _predict(model, *BOTH)[:n]
        np.testing.assert_allclose(together, alone, rtol=1e-9, atol=1e-9, err_msg=name)


def test_fit_does_not_modify_its_inputs(fitted):
    name, model = fitted
    X, y = BOTH[0].copy(), BOTH[1].copy()
    clone(model).fit(X, y)
    pd.testing.assert_frame_equal(X, BOTH[0])
    np.testing.assert_array_equal(y, BOTH[1])


def test_feedback_flag_matches_the_registry(fitted):
    name, model = fitted
    if not MODELS[name].uses_temperatures and name != "none":
        assert getattr(model, "needs_error_feedback", False), name


def test_none_predicts_zero_and_ridge_has_no_lags():
    assert not make_model("none").fit(*BOTH).predict(A[0]).any()
    ridge = make_model("ridge").fit(*BOTH)
    assert ridge.lag_order_ == 0 and ridge.chosen_params_["cv_scheme"].startswith("leave-one")
    assert ridge.chosen_params_["alpha"] in ridge.alphas


@pytest.mark.parametrize("name", sorted(n for n, e in MODELS.items() if not e.uses_temperatures))
def test_models_on_the_error_series_alone_need_no_sensor_column(name):
    X, y = A[0].iloc[:, :0], A[1]
    model = make_model(name).fit(X, y)
    for history in (None, y):
        predicted = _predict(model, X, history)
        assert predicted.shape == (len(X),) and np.isfinite(predicted).all()

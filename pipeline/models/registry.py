"""Registry of candidate models: name in ``params.yaml`` -> scikit-learn estimator factory.

Every entry returns an unfitted scikit-learn estimator taking X of shape (n, m) (temperatures,
degC or K) and y of shape (n,) (thermal error, um).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sklearn.base import RegressorMixin
from sklearn.linear_model import LinearRegression


def multiple_linear_regression() -> RegressorMixin:
    """Multiple linear regression y = a0 + sum_j a_j T_j by ordinary least squares.

    The static model of the patent (sensitive-point selection for linear-axis thermal error,
    ``seeds/002``, step 4: multiple regression analysis builds the thermal error model) and the
    baseline the PCDL paper improves on.
    scikit-learn's :class:`~sklearn.linear_model.LinearRegression` is used as is.
    """
    return LinearRegression()


MODELS: dict[str, Callable[..., RegressorMixin]] = {"mlr": multiple_linear_regression}


def make_model(name: str, **params: Any) -> RegressorMixin:
    """Return a new unfitted estimator registered under ``name``.

    Raises
    ------
    KeyError
        If no model has that name; the message lists the registered ones.
    """
    if name not in MODELS:
        raise KeyError(
            f"unknown model '{name}' in params.yaml evaluate.model; registered: {sorted(MODELS)}"
        )
    return MODELS[name](**params)

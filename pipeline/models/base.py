"""The fit and predict skeletons every candidate model shares: check the inputs, then model.

:class:`ThermalErrorModel` checks the hyper-parameters and the training pair the same way for
every model, then hands the checked pair to the model's own ``_fit``. Prediction checks its
inputs and calls the model's ``_predict``: ``predict(X)`` for a :class:`TemperatureModel`,
``predict(X, y_history=None)`` for a :class:`FeedbackModel`, a model on the error's own
history (:mod:`pipeline.models.feedback`).
The shapes and units are those of :mod:`pipeline.models.registry`.
"""

from __future__ import annotations

from abc import ABCMeta, abstractmethod
from typing import ClassVar, Self

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted

from pipeline.models.feedback import check_history
from pipeline.models.series import check_features, check_xy


class ThermalErrorModel(RegressorMixin, BaseEstimator, metaclass=ABCMeta):
    """Base of the candidate models: ``fit`` checks its inputs, ``_fit`` models them.

    Subclasses implement ``_fit``; they override ``_check_params`` when a hyper-parameter can
    be out of range, and set ``min_columns = 0`` when they use only X's index.
    """

    #: Whether the model predicts from the measured error's own history (then it is scored
    #: one-step-ahead and in free run; see :mod:`pipeline.models.feedback`).
    needs_error_feedback: ClassVar[bool] = False

    #: Fewest sensor columns X must have: 0 for models on the error series alone, which use
    #: only X's index (the campaign boundaries).
    min_columns: ClassVar[int] = 1

    def fit(self, X: pd.DataFrame, y: np.ndarray) -> Self:
        """Check the hyper-parameters and the training pair, then fit (see the class docstring).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n, m)
            Temperatures (K rise or degC), index ("campaign_id", "elapsed_s") or one series;
            models on the error series alone use only the index (the campaigns).
        y : array-like of shape (n,)
            Thermal error (um), 0 at each campaign's cold start.

        Returns
        -------
        ThermalErrorModel
            self, fitted.

        Raises
        ------
        ValueError
            If a hyper-parameter is out of range, or the data are too few or too short for
            the model; the message says what to change.
        """
        self._check_params()
        frame, target = check_xy(X, y, min_columns=self.min_columns)
        self._fit(frame, target)
        return self

    def _check_params(self) -> None:
        """Raise ValueError for a hyper-parameter out of range (here: none can be)."""

    @abstractmethod
    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Fit on the checked float table X (n, m) and thermal error ``target`` (n,), um."""


class TemperatureModel(ThermalErrorModel):
    """Base of the models on the temperatures alone (current and lagged), no error history.

    Subclasses implement ``_fit``, which sets ``feature_names_in_`` (the sensor columns,
    selected by name at predict time), and ``_predict``.
    """

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """Predict the thermal error.

        Parameters
        ----------
        X : pandas.DataFrame, shape (n, m)
            Temperatures with (at least) the sensor columns seen in fit; index as in
            :func:`pipeline.models.series.segments`.

        Returns
        -------
        numpy.ndarray, shape (n,)
            Predicted thermal error (um).
        """
        check_is_fitted(self, "feature_names_in_")
        return self._predict(check_features(X, list(self.feature_names_in_)))

    @abstractmethod
    def _predict(self, X: pd.DataFrame) -> np.ndarray:
        """Prediction (n,), um, from the checked sensor columns of fit, in their order."""


class FeedbackModel(ThermalErrorModel):
    """Base of the models on the error's own history, scored one-step-ahead and in free run.

    Subclasses implement ``_fit`` and ``_predict``; ``fit`` sets ``chosen_params_``.
    """

    needs_error_feedback = True

    def predict(self, X: pd.DataFrame, y_history: np.ndarray | None = None) -> np.ndarray:
        """Predict the thermal error one-step-ahead (``y_history``) or in free run (None).

        Parameters
        ----------
        X : pandas.DataFrame of shape (n, m)
            Temperatures with the sensor columns used in fit; models on the error series
            alone use only its index (the campaigns).
        y_history : array-like of shape (n,), um, optional
            Measured error aligned with X's rows: the prediction at t uses it up to t-1.
            None: free run from pre-sample error 0 at each campaign start.

        Returns
        -------
        numpy.ndarray of shape (n,)
            Predicted thermal error (um).
        """
        return self._predict(*self._prediction_inputs(X, y_history))

    def _prediction_inputs(
        self, X: pd.DataFrame, y_history: np.ndarray | None
    ) -> tuple[pd.DataFrame, np.ndarray | None]:
        """Check that the model is fitted, then X and the history: (float X, history or None)."""
        check_is_fitted(self, "chosen_params_")
        frame = check_features(X, self._fitted_columns(), min_columns=self.min_columns)
        return frame, check_history(y_history, len(frame))

    def _fitted_columns(self) -> list[str] | None:
        """Sensor columns selected from X at predict time (None: X's columns as they are)."""
        return None

    @abstractmethod
    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Prediction (n,), um, from the checked X and measured error (None: free run)."""

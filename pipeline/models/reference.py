"""No compensation: the reference every candidate model is scored against.

A compensation is only worth applying if it leaves less error than applying none. The candidate
``none`` predicts a thermal error of zero everywhere, so its residual is the uncompensated error
itself; it runs through the same protocol, scores and champion choice as every model, and the
compensation ratio of a candidate, eta = 1 - RMS(residual) / RMS(uncompensated error), is
measured against it (:mod:`pipeline.protocol.scoring`). When no model beats it by the margin of
``params.yaml`` ``evaluate.champion.min_improvement``, it is the champion: do not compensate.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted

from pipeline.models.series import check_features, check_xy


class NoCompensation(RegressorMixin, BaseEstimator):
    """Predict a thermal error of zero (um): the machine is not compensated.

    Attributes
    ----------
    n_features_in_ : int
        Columns of X seen in fit (ignored).
    chosen_params_ : dict
        Empty: nothing is fitted.
    """

    needs_error_feedback = False

    def fit(self, X: pd.DataFrame, y: np.ndarray) -> NoCompensation:
        """Check the inputs and return self; nothing is learnt.

        Parameters
        ----------
        X : pandas.DataFrame, shape (n, m)
            Feature table (only its shape is checked).
        y : array-like, shape (n,)
            Thermal error, um (only its shape and finiteness are checked).
        """
        frame, _ = check_xy(X, y, min_columns=0)
        self.n_features_in_ = frame.shape[1]
        self.chosen_params_ = {}
        return self

    def predict(self, X: pd.DataFrame) -> np.ndarray:
        """Return zeros, ndarray of shape (n,), um."""
        check_is_fitted(self, "n_features_in_")
        return np.zeros(len(check_features(X, min_columns=0)))

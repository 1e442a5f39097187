"""Support vector regression on an embedding of the differenced thermal error (the SVR paper).

Source: Chen Ziran et al., "Time-series prediction for a time-grating CNC rotary table based on
support vector machines" (in Chinese), 2012, no. 8, pp. 1794 ff. (sections 3-4): remove the
trend by differencing, standardise, take the embedding dimension from the lag at which the PACF
cuts off (7 there), regress the next value on the embedded past with an RBF-kernel SVR,
K(x, x') = exp(-g |x - x'|^2), choose g and the penalty C by cross-validation on a coarse 2^k
grid and then a finer grid around the best, and sum the predicted differences back to the level.

Model, with d_t = y_t - y_{t-1} (per campaign, pre-sample error 0 um) and s = (d - mean) / sd::

    s_hat_t = SVR(s_{t-1}, ..., s_{t-m}),   y_hat_t = y_{t-1} + mean + sd * s_hat_t

Choices where the paper is silent or differs:

- One difference, not two: the paper's rotary table moves with second-order dynamics, the
  thermal error drifts to a plateau (first order), so the first difference removes its trend.
- Embedding m: the first lag whose pooled PACF (see :mod:`pipeline.models.identification`)
  lies inside the 95 % band 1.96 / sqrt(N), minus one, bounded to 1..``max_embedding``.
- Grid: coarse log2 g in ``COARSE_LOG2_GAMMA`` x log2 C in ``COARSE_LOG2_C`` (steps of 3), then
  log2 g, log2 C within +-1 of the best in steps of 1 (``fine_step``); the paper's grid limits
  were lost in the capture; 24 grid points x ``n_folds`` fits keep a fit near a second. The
  score is the mean squared one-step error of the standardised difference over the folds.
- Folds never shuffle time: one campaign -> forward-chaining blocks (scikit-learn
  ``TimeSeriesSplit``, ``n_folds`` splits: train on the past, validate on the next block);
  several campaigns -> leave-campaigns-out with whole campaigns in ``n_folds`` contiguous
  groups (scikit-learn ``GroupKFold`` on consecutive campaign groups), so no campaign is in
  both training and validation (leave-one-campaign-out when there are at most ``n_folds``
  campaigns; grouping ~9 campaigns into 3 folds keeps a fit near a second).
- Prediction: one-step-ahead uses the measured error's differences and level y_{t-1}; free
  run feeds back its own predicted levels (pre-sample error 0).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import pandas as pd
from sklearn.model_selection import GroupKFold, TimeSeriesSplit
from sklearn.svm import SVR

from pipeline.models.arma import difference
from pipeline.models.base import FeedbackModel
from pipeline.models.feedback import feedback_predict
from pipeline.models.identification import (
    first_inside_lag,
    partial_autocorrelation,
    pooled_autocorrelation,
    white_noise_band,
)
from pipeline.models.series import history, segments

logger = logging.getLogger(__name__)

#: Coarse grid exponents (base 2) of the kernel parameter g and the penalty C.
COARSE_LOG2_GAMMA = (-9.0, -6.0, -3.0, 0.0)
COARSE_LOG2_C = (-2.0, 1.0, 4.0, 7.0)


class EmbeddedSVR(FeedbackModel):
    """RBF support vector regression of the next error difference on the embedded past.

    Uses no temperatures: X's columns are ignored, its index gives the campaigns.

    Parameters
    ----------
    max_embedding : int, default 10
        Largest embedding dimension m.
    epsilon : float, default 0.1
        Width of the SVR's insensitive tube (standardised difference units).
    n_folds : int, default 3
        Cross-validation folds (forward-chaining blocks, or groups of whole campaigns).
    fine_step : float, default 1.0
        Step (log2 units) of the fine grid around the best coarse point.

    Attributes
    ----------
    embedding_ : int
        m.
    pacf_ : numpy.ndarray
        Pooled PACF of the training differences at lags 0..m_max + 1.
    difference_mean_, difference_scale_ : float
        Mean and standard deviation of the training differences (um per sample).
    svr_ : sklearn.svm.SVR
        The regressor refitted on all training rows with the chosen g and C.
    cv_results_ : pandas.DataFrame
        log2_gamma, log2_C, stage (coarse / fine) and cv_mse of every grid point.
    chosen_params_ : dict
        embedding, gamma, C, epsilon, cv_mse, n_folds, cv.
    """

    min_columns = 0

    def __init__(
        self,
        max_embedding: int = 10,
        epsilon: float = 0.1,
        n_folds: int = 3,
        fine_step: float = 1.0,
    ):
        self.max_embedding = max_embedding
        self.epsilon = epsilon
        self.n_folds = n_folds
        self.fine_step = fine_step

    def _check_params(self) -> None:
        """Raise ValueError unless ``max_embedding`` >= 1 and ``n_folds`` >= 2."""
        if int(self.max_embedding) < 1 or int(self.n_folds) < 2:
            raise ValueError(
                f"max_embedding must be >= 1 and n_folds >= 2, got {self.max_embedding} "
                f"and {self.n_folds}"
            )

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Difference, embed, grid-search g and C by time-ordered cross-validation, refit.

        Raises
        ------
        ValueError
            If the campaigns are too short to embed, or the error's differences are constant.
        """
        segs = segments(X)
        shortest = min(len(rows) for rows in segs)
        if shortest < 2 * int(self.n_folds) + 2:
            raise ValueError(
                f"a campaign of {shortest} samples is too short to embed and cross-validate; "
                f"each campaign needs at least {2 * int(self.n_folds) + 2} samples"
            )
        diffs = np.empty(len(target))
        for rows in segs:
            diffs[rows] = difference(target[rows], 1)
        self.difference_mean_ = float(diffs.mean())
        self.difference_scale_ = float(diffs.std())
        if self.difference_scale_ <= 0.0:
            raise ValueError(
                "the thermal error changes by the same amount at every sample, so its "
                "differences carry nothing to learn; check the error column"
            )
        self.embedding_, self.pacf_ = self._embedding([diffs[rows] for rows in segs])
        features = self._standardise(history(diffs, segs, self.embedding_))
        response = self._standardise(diffs)
        folds = self._folds(segs)
        self.cv_results_ = self._grid_search(features, response, folds)
        best = self.cv_results_.loc[self.cv_results_["cv_mse"].idxmin()]
        self.svr_ = self._svr(best["log2_gamma"], best["log2_C"]).fit(features, response)
        self.chosen_params_ = {
            "embedding": self.embedding_,
            "gamma": float(2.0 ** best["log2_gamma"]),
            "C": float(2.0 ** best["log2_C"]),
            "epsilon": float(self.epsilon),
            "cv_mse": float(best["cv_mse"]),
            "n_folds": len(folds),
            "cv": "leave-campaigns-out" if len(segs) > 1 else "forward-chaining blocks",
        }
        logger.debug("SVR: embedding %d, %s", self.embedding_, self.chosen_params_)

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Previous level plus the predicted difference (um), from the measured or own levels."""
        m = self.embedding_

        def step(rows: np.ndarray, levels: np.ndarray) -> np.ndarray:
            past_diffs = levels[:, :m] - levels[:, 1 : m + 1]
            scaled = self._decision(self._standardise(past_diffs))
            return levels[:, 0] + self.difference_mean_ + self.difference_scale_ * scaled

        return feedback_predict(step, segments(X), m + 1, measured)

    def _decision(self, features: np.ndarray) -> np.ndarray:
        """Return the fitted SVR's prediction, sum_i a_i exp(-g |s_i - x|^2) + b.

        What ``SVR.predict`` returns (to rounding), without its per-call input checks: free run
        predicts one sample at a time, and those checks cost 15 times the sum.
        """
        vectors = self.svr_.support_vectors_
        squared = ((features[:, None, :] - vectors[None, :, :]) ** 2).sum(axis=2)
        kernel = np.exp(-float(self.svr_.gamma) * squared)
        return kernel @ self.svr_.dual_coef_[0] + self.svr_.intercept_[0]

    def _embedding(self, pieces: Sequence[np.ndarray]) -> tuple[int, np.ndarray]:
        """Embedding m = (first lag with the PACF inside the 95 % band) - 1, in 1..max_embedding."""
        n_lags = min(int(self.max_embedding) + 1, min(len(piece) for piece in pieces) - 1)
        pacf = partial_autocorrelation(pooled_autocorrelation(pieces, n_lags))
        inside = first_inside_lag(pacf, white_noise_band(sum(len(p) for p in pieces)))
        limit = int(self.max_embedding)
        embedding = limit if inside is None else min(max(inside - 1, 1), limit)
        return embedding, pacf

    def _standardise(self, diffs: np.ndarray) -> np.ndarray:
        """(d - mean) / sd with the training differences' moments."""
        return (diffs - self.difference_mean_) / self.difference_scale_

    def _folds(self, segs: Sequence[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
        """Time-ordered folds: forward chaining in one campaign, campaign groups otherwise."""
        n_rows = sum(len(rows) for rows in segs)
        if len(segs) == 1:
            return list(TimeSeriesSplit(n_splits=int(self.n_folds)).split(np.arange(n_rows)))
        n_groups = min(int(self.n_folds), len(segs))
        campaign_group = np.arange(len(segs)) * n_groups // len(segs)
        groups = np.concatenate(
            [np.full(len(rows), g) for rows, g in zip(segs, campaign_group, strict=True)]
        )
        splitter = GroupKFold(n_splits=n_groups)
        return list(splitter.split(np.arange(n_rows), groups=groups))

    def _svr(self, log2_gamma: float, log2_c: float) -> SVR:
        """RBF SVR with g = 2^log2_gamma and C = 2^log2_c."""
        return SVR(kernel="rbf", gamma=2.0**log2_gamma, C=2.0**log2_c, epsilon=self.epsilon)

    def _grid_search(
        self, features: np.ndarray, response: np.ndarray, folds: Sequence[tuple]
    ) -> pd.DataFrame:
        """Coarse 2^k grid, then a finer grid around the best coarse point."""
        scores: dict[tuple[float, float], tuple[str, float]] = {}

        def score(log2_gamma: float, log2_c: float, stage: str) -> None:
            if (log2_gamma, log2_c) in scores:
                return
            errors = []
            for train, test in folds:
                model = self._svr(log2_gamma, log2_c).fit(features[train], response[train])
                errors.append(np.mean((model.predict(features[test]) - response[test]) ** 2))
            scores[(log2_gamma, log2_c)] = (stage, float(np.mean(errors)))

        for log2_gamma in COARSE_LOG2_GAMMA:
            for log2_c in COARSE_LOG2_C:
                score(log2_gamma, log2_c, "coarse")
        best_gamma, best_c = min(scores, key=lambda key: scores[key][1])
        offsets = (-self.fine_step, 0.0, self.fine_step)
        for d_gamma in offsets:
            for d_c in offsets:
                score(best_gamma + d_gamma, best_c + d_c, "fine")
        return pd.DataFrame(
            [
                {"log2_gamma": g, "log2_C": c, "stage": stage, "cv_mse": mse}
                for (g, c), (stage, mse) in scores.items()
            ]
        )

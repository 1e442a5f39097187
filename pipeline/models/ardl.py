"""Autoregressive distributed-lag (ARDL) model of the thermal error on the selected temperatures.

Source: the PCDL paper (Miao et al. 2016, "Improvement of forecasting robustness of time series
model for thermal error on CNC machine tool", Optics and Precision Engineering 24(10), 2480-2489;
introduction) cites Miao et al. [5, 6], who modelled the thermal error of CNC machine tools with
distributed-lag and autoregressive distributed-lag (ADL) models ([6]: "Application of the
autoregressive distributed lag model in CNC machine tool thermal error modelling", Acta Metrologica
Sinica 34(3), 2013). The reference's equations are not among the sources; the standard ARDL form and
estimator are those of statsmodels ``statsmodels.tsa.ardl.ARDL`` (constant trend, every sensor at
lags 0..q)::

    y_t = c + sum_{i=1..p} a_i y_{t-i} + sum_j sum_{k=0..q} b_{j,k} T_{j,t-k} + e_t

Campaigns: statsmodels' ARDL and ``ardl_select_order`` take one contiguous series and drop its
first max-lag rows (``hold_back``). Here each campaign is a series of its own: the per-campaign
lagged designs (no lag reaches into another campaign) are stacked, the first
H = max(max_ar, max_dl) rows of every campaign are held back exactly as statsmodels does, and
the model is estimated by ordinary least squares (statsmodels ``OLS``, which is what ARDL
runs). On a single campaign the coefficients equal statsmodels ``ARDL(..., hold_back=H)``.

Order selection: p in 1..max_ar and one distributed-lag order q in 0..max_dl common to all
sensors, by ``ic`` over the same held-back rows (as ``ardl_select_order``). statsmodels
searches a separate q per sensor, (max_dl + 2)^m combinations, about 10^7 for ten sensors; the
common order keeps the search at max_ar x (max_dl + 1) fits.

Prediction, per campaign: temperatures before the first sample equal the first sample (the
machine rests at its cold state), the error before it is 0 um. One-step-ahead uses the measured
error as the AR history, free run its own predictions.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
from statsmodels.regression.linear_model import OLS

from pipeline.models.base import FeedbackModel
from pipeline.models.feedback import linear_feedback_predict
from pipeline.models.identification import check_criterion
from pipeline.models.series import history, lagged, lagged_values, segments

logger = logging.getLogger(__name__)


class AutoregressiveDistributedLag(FeedbackModel):
    """ARDL(p, q) with orders by information criterion, estimated across campaigns.

    Parameters
    ----------
    max_ar : int, default 4
        Largest autoregressive order p (>= 1).
    max_dl : int, default 4
        Largest distributed-lag order q of the temperatures (>= 0).
    ic : {"aic", "bic"}, default "aic"
        Information criterion choosing (p, q).

    Attributes
    ----------
    columns_ : list of str
        Sensor columns used, in order.
    ar_order_, dl_order_ : int
        Chosen p and q.
    intercept_ : float
        c (um).
    ar_ : numpy.ndarray of shape (p,)
        a_1..a_p.
    dl_ : numpy.ndarray of shape (m, q + 1)
        b_{j,k} (um/K), row j = sensor ``columns_[j]``, column k = lag k.
    criteria_ : pandas.DataFrame
        p, q and the criterion of every candidate.
    chosen_params_ : dict
        ar_order, dl_order, ic, ic_value, hold_back.
    """

    def __init__(self, max_ar: int = 4, max_dl: int = 4, ic: str = "aic"):
        self.max_ar = max_ar
        self.max_dl = max_dl
        self.ic = ic

    def _check_params(self) -> None:
        """Raise ValueError unless ``ic`` is known, ``max_ar`` >= 1 and ``max_dl`` >= 0."""
        check_criterion(self.ic)
        if int(self.max_ar) < 1 or int(self.max_dl) < 0:
            raise ValueError(
                f"max_ar must be >= 1 and max_dl >= 0, got {self.max_ar} and {self.max_dl}"
            )

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Choose (p, q) by the criterion and estimate the ARDL by stacked OLS.

        Raises
        ------
        ValueError
            If a campaign is too short for the held-back rows plus a fit.
        """
        segs = segments(X)
        hold_back = max(int(self.max_ar), int(self.max_dl))
        shortest = min(len(rows) for rows in segs)
        if shortest <= hold_back + 2:
            raise ValueError(
                f"a campaign of {shortest} samples is too short for lags up to {hold_back}; "
                f"lower max_ar / max_dl or use campaigns of more than {hold_back + 2} samples"
            )
        self.columns_ = list(X.columns)
        estimation = np.concatenate([rows[hold_back:] for rows in segs])
        y_lags = history(target, segs, int(self.max_ar))[estimation]
        x_lags = lagged(X, int(self.max_dl))
        response = target[estimation]
        rows = []
        for p in range(1, int(self.max_ar) + 1):
            for q in range(int(self.max_dl) + 1):
                result = OLS(response, self._design(y_lags, x_lags, p, q, estimation)).fit()
                rows.append({"p": p, "q": q, "ic": float(getattr(result, self.ic))})
        self.criteria_ = pd.DataFrame(rows)
        best = self.criteria_.loc[self.criteria_["ic"].idxmin()]
        p, q = int(best["p"]), int(best["q"])
        params = OLS(response, self._design(y_lags, x_lags, p, q, estimation)).fit().params
        self.ar_order_, self.dl_order_ = p, q
        self.intercept_ = float(params[0])
        self.ar_ = np.asarray(params[1 : p + 1], dtype=float)
        self.dl_ = np.asarray(params[p + 1 :], dtype=float).reshape(len(self.columns_), q + 1)
        self.chosen_params_ = {
            "ar_order": p,
            "dl_order": q,
            "ic": self.ic,
            "ic_value": float(best["ic"]),
            "hold_back": hold_back,
        }
        logger.debug("ARDL(%d, %d) on %s", p, q, self.columns_)

    def _fitted_columns(self) -> list[str]:
        """Return the sensor columns used in fit."""
        return self.columns_

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Predict c plus the lagged temperature terms plus the AR terms on the error, um."""
        base = self.intercept_ + lagged_values(X, self.dl_order_) @ self.dl_.ravel()
        return linear_feedback_predict(base, self.ar_, segments(X), measured)

    def _design(
        self,
        y_lags: np.ndarray,
        x_lags: pd.DataFrame,
        p: int,
        q: int,
        estimation: np.ndarray,
    ) -> np.ndarray:
        """[1, y_{t-1..t-p}, T_{j,t-0..t-q} for each sensor j] on the estimation rows."""
        columns = [f"{sensor}_lag{k}" for sensor in self.columns_ for k in range(q + 1)]
        temperatures = x_lags[columns].to_numpy()[estimation]
        return np.column_stack([np.ones(len(estimation)), y_lags[:, :p], temperatures])

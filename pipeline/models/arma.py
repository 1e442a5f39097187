"""ARMA model of the thermal error's own history, identified as in the TS-BP paper.

Source: Li Xingda, Gu Qunying, Li Zihan and Yang Jianguo, "Modeling for thermal error based on time
series-neural network", Modular Machine Tool & Automatic Manufacturing Technique 2015(9), 13-16
(section 1.1): zero-mean the error series, test its stationarity by the reverse-arrangement test,
identify AR / MA / ARMA from the cut-off or tailing of the ACF and PACF, fix the order by an
information criterion and estimate the parameters by least squares on the long-autoregression
residuals (LSA / LAR); the paper arrives at ARMA(4,3).

Model, with z_t = w_t - mu the zero-mean (differenced) error w_t = (1 - B)^d y_t, um::

    z_t = sum_{i=1..p} phi_i z_{t-i} + e_t + sum_{j=1..q} theta_j e_{t-j}

Implementation (standard forms where the capture lost the paper's equations):

- Differencing: the paper tests stationarity but does not say what it did had the test failed;
  here the error is differenced (per campaign, pre-sample error 0) until a majority of the
  training campaigns pass the test, at most ``max_diff`` times. A warm-up curve usually needs
  d = 2 (its first difference still trends from fast heating to saturation).
- Order: candidates from :func:`pipeline.models.identification.identify`, each estimated by
  Hannan-Rissanen (statsmodels ``hannan_rissanen``, the paper's LSA/LAR estimator: long AR,
  then least squares on lagged values and residuals) and ranked by the information criterion
  of the exact Gaussian likelihood at those estimates (statsmodels ``ARIMA.loglike``); the
  best ``n_refit`` are refitted by maximum likelihood (statsmodels ``ARIMA``, state space,
  stationary and invertible, started from the Hannan-Rissanen estimates) and the criterion
  of that fit decides. (Ranking by the Hannan-Rissanen residual variance alone favoured
  over-parameterised orders.)
- Several campaigns: statsmodels takes one series, so the campaigns are joined by
  ``GAP_LENGTH`` missing values; the Kalman filter predicts through the gap, so each campaign
  starts close to the unconditional distribution and no error history crosses a campaign.
- Prediction: the ARMA difference equation with the fitted parameters, per campaign, with
  pre-sample error 0 um (so pre-sample z = -mu) and pre-sample innovations 0. One-step-ahead
  uses the measured error up to t-1 (innovations e_t = z_t - z_hat_t); free run feeds back its
  own predictions (innovations 0).
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.special import comb
from statsmodels.tsa.arima.estimators.hannan_rissanen import hannan_rissanen
from statsmodels.tsa.arima.model import ARIMA
from threadpoolctl import threadpool_limits

from pipeline.models.base import FeedbackModel
from pipeline.models.identification import check_criterion, identify
from pipeline.models.series import segments
from pipeline.models.stationarity import reverse_arrangement_test

logger = logging.getLogger(__name__)

#: Missing values joining two campaigns in the maximum-likelihood fit (samples).
GAP_LENGTH = 30
#: Shortest campaign the stationarity test and identification can use (samples).
MIN_CAMPAIGN_LENGTH = 10


class ARMAErrorModel(FeedbackModel):
    """ARMA(p, q) on the (differenced) zero-mean thermal error, the TS-BP paper's TS module.

    Uses no temperatures: X's columns are ignored, its index gives the campaigns.

    Parameters
    ----------
    max_p, max_q : int, default 6, 4
        Largest AR and MA orders considered (the paper's ARMA(4,3) lies inside).
    ic : {"bic", "aic"}, default "bic"
        Information criterion fixing the order.
    max_diff : int, default 2
        Largest number of differences taken to pass the reverse-arrangement test.
    alpha : float, default 0.05
        Significance level of the reverse-arrangement test.
    n_refit : int, default 3
        Number of best Hannan-Rissanen candidates refitted by maximum likelihood.
    maxiter : int, default 50
        Iteration limit of each maximum-likelihood fit.

    Attributes
    ----------
    order_ : tuple of int
        (p, d, q).
    ar_, ma_ : numpy.ndarray of shape (p,), (q,)
        phi_1..phi_p and theta_1..theta_q.
    mean_ : float
        mu, mean of the differenced training error (um per sample^d).
    sigma2_ : float
        Innovation variance (um^2).
    identification_ : pipeline.models.identification.Identification
        ACF/PACF identification of the training series.
    stationarity_z_ : list of float
        z statistic of the reverse-arrangement test of each campaign at the chosen d.
    criteria_ : pandas.DataFrame
        Candidate orders (p, q) with ``hr_ic``, the criterion at the Hannan-Rissanen estimates,
        and ``mle_ic``, the criterion after maximum likelihood (those refitted; else NaN).
    chosen_params_ : dict
        p, d, q, identified family, ic and its value, mean_um.
    """

    min_columns = 0

    def __init__(
        self,
        max_p: int = 6,
        max_q: int = 4,
        ic: str = "bic",
        max_diff: int = 2,
        alpha: float = 0.05,
        n_refit: int = 3,
        maxiter: int = 50,
    ):
        self.max_p = max_p
        self.max_q = max_q
        self.ic = ic
        self.max_diff = max_diff
        self.alpha = alpha
        self.n_refit = n_refit
        self.maxiter = maxiter

    def _check_params(self) -> None:
        """Raise ValueError unless ``ic`` is a known criterion."""
        check_criterion(self.ic)

    def _fit(self, X: pd.DataFrame, target: np.ndarray) -> None:
        """Identify and estimate the ARMA model of the training error.

        Raises
        ------
        ValueError
            If a campaign is shorter than 10 samples or the error is constant.
        """
        segs = segments(X)
        short = [len(rows) for rows in segs if len(rows) < MIN_CAMPAIGN_LENGTH]
        if short:
            raise ValueError(
                f"campaigns of {short} samples are too short for an ARMA model; each campaign "
                f"needs at least {MIN_CAMPAIGN_LENGTH} samples"
            )
        pieces = [target[rows] for rows in segs]
        n_diff, z_stats = self._choose_differencing(pieces)
        differenced = [difference(piece, n_diff) for piece in pieces]
        self.mean_ = float(np.concatenate(differenced).mean())
        centred = [piece - self.mean_ for piece in differenced]
        self.identification_ = identify(centred, self.max_p, self.max_q)
        joined = join_campaigns(centred)
        self.criteria_ = self._rank_candidates(joined, self.identification_.candidates)
        best = self._refit_best(joined)
        p, q = int(best["p"]), int(best["q"])
        self.order_ = (p, n_diff, q)
        self.stationarity_z_ = z_stats
        self.chosen_params_ = {
            "p": p,
            "d": n_diff,
            "q": q,
            "identified": self.identification_.kind,
            "ic": self.ic,
            "ic_value": float(best["mle_ic"]),
            "mean_um": self.mean_,
        }
        logger.debug("ARMA error model: order %s (%s)", self.order_, self.identification_.kind)

    def _predict(self, X: pd.DataFrame, measured: np.ndarray | None) -> np.ndarray:
        """Run the ARIMA(p, d, q) recursion of :func:`arma_recursion`, campaign by campaign."""
        return arma_recursion(self.ar_, self.ma_, self.mean_, self.order_[1], segments(X), measured)

    def _choose_differencing(self, pieces: Sequence[np.ndarray]) -> tuple[int, list[float]]:
        """Smallest d <= max_diff at which most campaigns pass the reverse-arrangement test."""
        for n_diff in range(self.max_diff + 1):
            results = [
                reverse_arrangement_test(difference(piece, n_diff), alpha=self.alpha)
                for piece in pieces
            ]
            if 2 * sum(r.stationary for r in results) > len(results):
                return n_diff, [r.z for r in results]
        logger.warning(
            "the thermal error is still non-stationary after %d differences "
            "(reverse-arrangement test); fitting the ARMA model anyway",
            self.max_diff,
        )
        return self.max_diff, [r.z for r in results]

    def _rank_candidates(
        self, joined: np.ndarray, candidates: Sequence[tuple[int, int]]
    ) -> pd.DataFrame:
        """Rank candidates by the exact criterion at their Hannan-Rissanen estimates.

        Hannan-Rissanen (the paper's LSA/LAR) runs on the campaigns placed end to end; its
        estimates are scored by the exact Gaussian likelihood of the gap-joined series (one
        Kalman filter pass). Non-stationary or non-invertible estimates rank last.
        """
        observed = joined[np.isfinite(joined)]
        rows = []
        for p, q in candidates:
            if p == 0 and q == 0:
                params, valid = np.array([observed @ observed / len(observed)]), True
            else:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    hr, _ = hannan_rissanen(observed, ar_order=p, ma_order=q, demean=False)
                params = np.r_[hr.ar_params, hr.ma_params, hr.sigma2]
                valid = bool(hr.is_stationary and hr.is_invertible and hr.sigma2 > 0)
            criterion = np.inf
            if valid:
                with warnings.catch_warnings(), threadpool_limits(limits=1):
                    warnings.simplefilter("ignore")
                    llf = ARIMA(joined, order=(p, 0, q), trend="n").loglike(params)
                criterion = _criterion(llf, p + q + 1, len(observed), self.ic)
            rows.append({"p": p, "q": q, "hr_ic": criterion, "start": params})
        return pd.DataFrame(rows).sort_values("hr_ic", kind="stable").reset_index(drop=True)

    def _refit_best(self, joined: np.ndarray) -> pd.Series:
        """Maximum-likelihood fits of the best candidates; keep parameters of the winner."""
        mle_ic = np.full(len(self.criteria_), np.nan)
        fits = {}
        for i in range(min(self.n_refit, len(self.criteria_))):
            p, q = int(self.criteria_.at[i, "p"]), int(self.criteria_.at[i, "q"])
            start = (
                self.criteria_.at[i, "start"]
                if np.isfinite(self.criteria_.at[i, "hr_ic"])
                else None
            )
            try:
                # One BLAS thread: the Kalman filter's 10 x 10 products are up to 50 times
                # slower when threads compete for the cores.
                with warnings.catch_warnings(), threadpool_limits(limits=1):
                    warnings.simplefilter("ignore")
                    result = ARIMA(joined, order=(p, 0, q), trend="n").fit(
                        start_params=start,
                        method_kwargs={"maxiter": self.maxiter},
                        cov_type="none",
                    )
            except (np.linalg.LinAlgError, ValueError) as error:
                logger.warning("ARMA(%d,%d) maximum-likelihood fit failed: %s", p, q, error)
                continue
            mle_ic[i] = getattr(result, self.ic)
            fits[i] = result
        if not fits:
            raise ValueError(
                "no candidate ARMA order could be fitted by maximum likelihood; check that the "
                "thermal error varies within each campaign"
            )
        self.criteria_ = self.criteria_.drop(columns="start").assign(mle_ic=mle_ic)
        winner = int(np.nanargmin(mle_ic))
        result = fits[winner]
        self.ar_ = np.asarray(result.arparams, dtype=float)
        self.ma_ = np.asarray(result.maparams, dtype=float)
        self.sigma2_ = float(result.params[-1])
        return self.criteria_.loc[winner]


def _criterion(llf: float, n_params: int, n_obs: int, ic: str) -> float:
    """AIC = -2 llf + 2 k or BIC = -2 llf + k ln N."""
    penalty = 2.0 if ic == "aic" else np.log(n_obs)
    return float(-2.0 * llf + penalty * n_params)


def join_campaigns(pieces: Sequence[np.ndarray]) -> np.ndarray:
    """Place the campaigns' series end to end, separated by ``GAP_LENGTH`` missing values."""
    gap = np.full(GAP_LENGTH, np.nan)
    return np.concatenate([part for piece in pieces for part in (piece, gap)][:-1])


def difference(series: np.ndarray, n_diff: int) -> np.ndarray:
    """(1 - B)^d of one campaign's series, with pre-sample values 0 (length kept).

    Parameters
    ----------
    series : numpy.ndarray of shape (n,)
        Thermal error of one campaign (um).
    n_diff : int
        d >= 0.

    Returns
    -------
    numpy.ndarray of shape (n,)
        The d-th difference; the series is taken as 0 before its first sample (cold state).
    """
    out = np.asarray(series, dtype=float)
    for _ in range(n_diff):
        out = np.diff(out, prepend=0.0)
    return out


def arma_recursion(
    ar: np.ndarray,
    ma: np.ndarray,
    mean: float,
    n_diff: int,
    segs: Sequence[np.ndarray],
    measured: np.ndarray | None,
) -> np.ndarray:
    """Run the ARIMA(p, d, q) predictor campaign by campaign.

    Parameters
    ----------
    ar, ma : numpy.ndarray of shape (p,), (q,)
        phi and theta of the zero-mean differenced error z_t = (1 - B)^d y_t - mean.
    mean : float
        mu (um per sample^d).
    n_diff : int
        d.
    segs : sequence of numpy.ndarray
        Row positions of each campaign.
    measured : numpy.ndarray of shape (n,), um, or None
        Measured error for one-step-ahead prediction; None for free run.

    Returns
    -------
    numpy.ndarray of shape (n,)
        y_hat_t = mu + z_hat_t - sum_{k=1..d} c_k y_{t-k}, with (1 - B)^d = sum_k c_k B^k and
        z_hat_t = sum_i phi_i z_{t-i} + sum_j theta_j e_{t-j}. Pre-sample y = 0 (so z = -mu),
        pre-sample e = 0. One-step: y_{t-k} and e from the measured error; free run: y_{t-k}
        from the predictions, e = 0.
    """
    p, q = len(ar), len(ma)
    # c_k of (1 - B)^d for k = 1..d, applied to past levels.
    diff_coef = np.array([(-1.0) ** k * comb(n_diff, k) for k in range(1, n_diff + 1)])
    n_rows = sum(len(rows) for rows in segs)
    predictions = np.empty(n_rows, dtype=float)
    for rows in segs:
        levels = np.zeros(n_diff)  # y_{t-1}, ..., y_{t-d}
        past_z = np.full(p, -mean)  # z_{t-1}, ..., z_{t-p}
        past_e = np.zeros(q)  # e_{t-1}, ..., e_{t-q}
        for row in rows:
            z_hat = float(ar @ past_z + ma @ past_e)
            prediction = mean + z_hat - float(diff_coef @ levels)
            predictions[row] = prediction
            level = prediction if measured is None else measured[row]
            z = level + float(diff_coef @ levels) - mean
            past_z = np.r_[z, past_z[:-1]] if p else past_z
            past_e = np.r_[z - z_hat, past_e[:-1]] if q else past_e
            levels = np.r_[level, levels[:-1]] if n_diff else levels
    return predictions

"""Pandera model of ``reports/cross_season_scores.csv`` written by ``evaluate``.

One row per (axis, model, selection, mode, training unit, test campaign): the model built on the
training unit (one campaign, the training campaigns of all seasons but one or of all campaigns
but one, or all of them) and scored on the test campaign (the PCDL paper's cross-season scheme,
extended by leave-one-season-out or leave-one-campaign-out).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pandera.pandas as pa
from pandera.typing import Series

from schemas.strict import StrictModel
from schemas.vocabulary import SPLITS

SCORE_ROLES = ("fit", "prediction", "validation")
"""``fit``: scored on a campaign it was built on; ``prediction``: on another train campaign;
``validation``: on a validation campaign."""
MODES = ("static", "one_step", "free_run")
"""``static``: from temperatures only; ``one_step``: with the measured error up to the previous
sample; ``free_run``: the model's own predictions fed back as error history."""
SCHEMES = ("campaign", "loso", "loco", "forward", "pooled")
"""Training unit: one campaign; all training campaigns but one season's (leave-one-season-out);
all but one campaign (leave-one-campaign-out, when there is one season); the campaigns that
ended before one started (rolling origin, forward in time); all of them."""


class CrossSeasonScoresModel(StrictModel):
    """Long table of cross-season scores (um).

    ``rmse_um`` is the RMS of the residual e = measured - predicted; ``resid_std_um`` its
    standard deviation with n - 1 (the PCDL paper's S), undefined (NaN) for one sample;
    ``uncompensated_rms_um`` the RMS of the thermal error itself on the same samples (what no
    compensation leaves) and ``eta`` = 1 - rmse_um / uncompensated_rms_um, the compensation
    ratio (NaN when the error is zero). ``machine``, the machine the scores are of, is written
    by the ``evaluate`` stage beside each machine's rows.
    """

    machine: Series[str] | None
    axis: Series[str]
    model: Series[str]
    selection: Series[str]
    mode: Series[str] = pa.Field(isin=MODES)
    scheme: Series[str] = pa.Field(isin=SCHEMES)
    train_unit: Series[str]
    test_campaign: Series[str]
    test_split: Series[str] = pa.Field(isin=SPLITS)
    test_season: Series[str]
    role: Series[str] = pa.Field(isin=SCORE_ROLES)
    n_samples: Series[np.int64] = pa.Field(ge=1)
    rmse_um: Series[float] = pa.Field(ge=0)
    resid_std_um: Series[float] = pa.Field(ge=0, nullable=True)
    uncompensated_rms_um: Series[float] = pa.Field(ge=0)
    eta: Series[float] = pa.Field(le=1, nullable=True)

    @pa.dataframe_check
    @classmethod
    def role_consistent(cls, df: pd.DataFrame) -> Series[bool]:
        """Check roles: validation split -> validation; campaign scheme: fit = own campaign."""
        validation = df["test_split"] == "validation"
        own = df["train_unit"] == df["test_campaign"]
        per_campaign = df["scheme"] == "campaign"
        expected = np.where(own, "fit", "prediction")
        consistent = np.where(
            validation,
            df["role"] == "validation",
            np.where(per_campaign, df["role"] == expected, df["role"] != "validation"),
        )
        return pd.Series(consistent, index=df.index)

    @pa.dataframe_check
    @classmethod
    def one_score_per_pair(cls, df: pd.DataFrame) -> Series[bool]:
        """Check for one row per axis, model, selection, mode, training unit, test campaign."""
        keys = ["axis", "model", "selection", "mode", "train_unit", "test_campaign"]
        return ~df.duplicated(keys, keep=False)

"""Pandera model of ``reports/cross_season_scores.csv`` written by ``evaluate``.

One row per (model, selection, train campaign, test campaign): the model trained on the train
campaign and scored on the test campaign (the PCDL paper's cross-season scheme).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pandera.pandas as pa
from pandera.typing import Series

from schemas.vocabulary import SPLITS

SCORE_ROLES = ("fit", "prediction", "validation")
"""``fit``: scored on its own campaign; ``prediction``: on another train campaign;
``validation``: on a validation campaign."""


class CrossSeasonScoresModel(pa.DataFrameModel):
    """Long table of cross-season scores (um).

    ``rmse_um`` is the RMS of the residual e = measured - predicted; ``resid_std_um`` its
    standard deviation with n - 1 (the PCDL paper's S), undefined (NaN) for one sample.
    """

    model: Series[str]
    selection: Series[str]
    train_campaign: Series[str]
    test_campaign: Series[str]
    test_split: Series[str] = pa.Field(isin=SPLITS)
    role: Series[str] = pa.Field(isin=SCORE_ROLES)
    n_samples: Series[np.int64] = pa.Field(ge=1)
    rmse_um: Series[float] = pa.Field(ge=0)
    resid_std_um: Series[float] = pa.Field(ge=0, nullable=True)

    class Config:
        """Exactly these columns."""

        strict = True

    @pa.dataframe_check
    @classmethod
    def role_consistent(cls, df: pd.DataFrame) -> Series[bool]:
        """Check roles: fit = own campaign, validation = validation split, else prediction."""
        own = df["train_campaign"] == df["test_campaign"]
        validation = df["test_split"] == "validation"
        expected = np.where(validation, "validation", np.where(own, "fit", "prediction"))
        return df["role"] == pd.Series(expected, index=df.index)

    @pa.dataframe_check
    @classmethod
    def one_score_per_pair(cls, df: pd.DataFrame) -> Series[bool]:
        """Check for one row per model, selection, train campaign and test campaign."""
        keys = ["model", "selection", "train_campaign", "test_campaign"]
        return ~df.duplicated(keys, keep=False)

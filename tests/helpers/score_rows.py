"""Rows of the cross-season score table, for the scoring and tracking-layout tests."""

from __future__ import annotations

import pandas as pd


def score_rows(train, values, scheme="campaign", mode="static"):
    """Score rows of unit ``train`` for (test campaign, split, role, S um); RMS is 2 S."""
    return [
        {
            "axis": "Z",
            "model": "mlr",
            "selection": "all",
            "mode": mode,
            "scheme": scheme,
            "train_unit": train,
            "test_campaign": test,
            "test_split": split,
            "role": role,
            "resid_std_um": v,
            "rmse_um": 2 * v,
            "uncompensated_rms_um": 10.0 * v,
        }
        for test, split, role, v in values
    ]


def two_campaigns_and_a_season() -> pd.DataFrame:
    """Scores of K1, K2 (one-campaign units) and the LOSO unit not_winter, on K1, K2, V1."""
    return pd.DataFrame(
        score_rows(
            "K1",
            [
                ("K1", "train", "fit", 1.0),
                ("K2", "train", "prediction", 3.0),
                ("V1", "validation", "validation", 6.0),
            ],
        )
        + score_rows(
            "K2",
            [
                ("K1", "train", "prediction", 2.0),
                ("K2", "train", "fit", 0.5),
                ("V1", "validation", "validation", 4.0),
            ],
        )
        + score_rows(
            "not_winter",
            [
                ("K1", "train", "prediction", 7.0),
                ("K2", "train", "fit", 0.2),
                ("V1", "validation", "validation", 5.0),
            ],
            scheme="loso",
        )
    )

"""The champion as an MLflow pyfunc model, logged and registered with the alias ``champion``.

``mlflow.pyfunc.load_model("models:/<name>@champion").predict(table)`` takes a temperature table
(:func:`pipeline.champion.temperature_features`: one column per chosen sensor in degC, rows in
time order, optional ``campaign_id`` and ``elapsed_s``) and returns the predicted thermal error
(um) per row. The estimator is the candidate's fit on all training campaigns; models on the
error's own history predict in free run.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import joblib
import mlflow
import pandas as pd
from mlflow.tracking import MlflowClient

from pipeline.champion import temperature_features

logger = logging.getLogger(__name__)

ALIAS = "champion"
TRACKING_URI_ENV = "MLFLOW_TRACKING_URI"
REQUIREMENTS = (
    "numpy==2.4.6",
    "pandas==3.1.1",
    "scikit-learn==1.9.1",
    "scipy==1.17.1",
    "statsmodels==0.15.0",
    "joblib==1.6.0",
)


class ChampionModel(mlflow.pyfunc.PythonModel):
    """Predict the thermal error (um) from a temperature table."""

    def load_context(self, context) -> None:
        """Load the fitted estimator and its card from the model's artifacts."""
        self.estimator = joblib.load(context.artifacts["estimator"])
        self.card = json.loads(Path(context.artifacts["card"]).read_text(encoding="utf-8"))

    def predict(self, context, model_input: pd.DataFrame, params=None) -> pd.Series:
        """Thermal error, um, one value per row of ``model_input``."""
        X = temperature_features(pd.DataFrame(model_input), self.card)
        return pd.Series(
            self.estimator.predict(X), index=model_input.index, name="thermal_error_um"
        )


def log_and_register(
    tracking_uri: str, run_id: str, registered_name: str, estimator: Path, card: Path
) -> str:
    """Log the champion to run ``run_id``, register it as ``registered_name`` and alias it.

    Returns
    -------
    str
        The registered model version.
    """
    previous_uri = os.environ.get(TRACKING_URI_ENV)
    package = Path(__file__).resolve().parents[1]
    mlflow.set_tracking_uri(tracking_uri)
    # Not ``with start_run``: leaving the block would mark the parent run FINISHED before the
    # rest of the pipeline execution is logged; the run is handed back still RUNNING.
    mlflow.start_run(run_id=run_id)
    try:
        info = mlflow.pyfunc.log_model(
            name=ALIAS,
            python_model=ChampionModel(),
            artifacts={"estimator": str(estimator), "card": str(card)},
            code_paths=[str(package)],
            pip_requirements=list(REQUIREMENTS),
            registered_model_name=registered_name,
        )
    finally:
        mlflow.end_run(status="RUNNING")
        # set_tracking_uri also sets the environment variable: restore the caller's.
        mlflow.set_tracking_uri(previous_uri)
    version = str(info.registered_model_version)
    MlflowClient(tracking_uri=tracking_uri).set_registered_model_alias(
        registered_name, ALIAS, version
    )
    logger.info("registered %s version %s with alias @%s", registered_name, version, ALIAS)
    return version

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
from pathlib import Path

import joblib
import mlflow
import pandas as pd
from mlflow.tracking import MlflowClient

from pipeline.champion import temperature_features

logger = logging.getLogger(__name__)

ALIAS = "champion"
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
    mlflow.set_tracking_uri(tracking_uri)
    package = Path(__file__).resolve().parents[1]
    with mlflow.start_run(run_id=run_id, nested=False):
        info = mlflow.pyfunc.log_model(
            name=ALIAS,
            python_model=ChampionModel(),
            artifacts={"estimator": str(estimator), "card": str(card)},
            code_paths=[str(package)],
            pip_requirements=list(REQUIREMENTS),
            registered_model_name=registered_name,
        )
    version = str(info.registered_model_version)
    MlflowClient(tracking_uri=tracking_uri).set_registered_model_alias(
        registered_name, ALIAS, version
    )
    logger.info("registered %s version %s with alias @%s", registered_name, version, ALIAS)
    return version

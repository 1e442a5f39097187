"""``params.yaml`` ``tracking:``: the MLflow store of the ``track`` and ``discrepancy`` stages.

``$MLFLOW_TRACKING_URI``, when set, wins over ``default_tracking_uri``
(:func:`pipeline.tracking.location.resolve_tracking_uri`).
"""

from __future__ import annotations

from pydantic import Field

from pipeline.settings.base import Settings

DEFAULT_TRACKING_URI = "sqlite:///mlflow.db"
"""The store when neither ``$MLFLOW_TRACKING_URI`` nor ``params.yaml`` names one."""


class TrackingSettings(Settings):
    """The ``tracking`` section.

    Attributes
    ----------
    default_tracking_uri : str
        The store used when ``$MLFLOW_TRACKING_URI`` is not set.
    local_artifact_dir : str
        Local SQLite store only: artifacts go to ``<folder of the db>/<this>/<experiment>/``.
    """

    default_tracking_uri: str = Field(DEFAULT_TRACKING_URI, min_length=1)
    local_artifact_dir: str = Field("mlartifacts", min_length=1)

"""``params.yaml`` ``track:``: the MLflow experiment, the registered champions and their gate."""

from __future__ import annotations

from pydantic import Field, StrictFloat, field_validator

from pipeline.settings.base import Settings


class PromotionSettings(Settings):
    """The promotion gate (``track.promotion``, :mod:`pipeline.protocol.promotion`).

    Attributes
    ----------
    min_improvement : float
        A new champion takes the alias ``champion`` only when, on the campaigns the current one
        was not trained on, it leaves at least this fraction less RMS than the current one.
    """

    min_improvement: StrictFloat = 0.05

    @field_validator("min_improvement")
    @classmethod
    def _fraction(cls, value: float) -> float:
        if not 0 <= value < 1:
            raise ValueError(
                "use a fraction in [0, 1), e.g. 0.05: a new model must leave 5 % less RMS than "
                "the champion"
            )
        return value


class TrackSettings(Settings):
    """The ``track`` section.

    Attributes
    ----------
    experiment : str
        The MLflow experiment of the pipeline's runs.
    registered_model : str
        Each axis' champion is registered as ``<this>-<axis>``, alias ``champion``.
    promotion : PromotionSettings
    """

    experiment: str = Field("thermal-error", min_length=1)
    registered_model: str = Field("thermal-error-spindle", min_length=1)
    promotion: PromotionSettings = PromotionSettings()

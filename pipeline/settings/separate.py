"""``params.yaml`` ``separate:``: the thermal error of the spindle and the axis campaigns.

``separate_spindle`` reads every key but ``geometric_order`` (:mod:`pipeline.separation.spindle`,
runs of campaigns :mod:`pipeline.separation.runs`, speed responses
:mod:`pipeline.separation.features`); ``separate_axis`` reads ``geometric_order``; ``evaluate``
references the twin's drift as the measured one (``cold_reference``, ``cold_n``).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, StrictBool, StrictFloat, StrictInt, field_validator

from pipeline.settings.base import Settings

ALL_AXES = "all"
"""``displacement_axis`` value (the default): every axis the campaigns declare."""

Positive = Annotated[StrictFloat, Field(gt=0)]


class RunSettings(Settings):
    """How runs of campaigns cut from one record are found (``separate.runs``).

    Attributes
    ----------
    detect : bool
        Detect links from the start times; False: only declared ``follows`` links.
    max_gap_s : float, s
        Longest gap between A's last and B's first sample for a detected link.
    max_temperature_jump_degC : float, degC
        A detected link is dropped when the temperatures jump more than this across the cut.
    min_stitch_um : float, um
        Smallest displacement jump ever stitched.
    """

    detect: StrictBool = True
    max_gap_s: StrictFloat = Field(900.0, ge=0)
    max_temperature_jump_degC: StrictFloat = Field(1.0, ge=0)  # noqa: N815 (params.yaml key)
    min_stitch_um: StrictFloat = Field(1.0, ge=0)


class SpeedResponseSettings(Settings):
    """Which speed responses are offered as model inputs (``separate.speed_responses``).

    Attributes
    ----------
    time_constants_min : tuple of float, min
        Time constants of the first-order lags of (rpm/1000)^a; none: no speed responses.
    exponents : tuple of float
        Powers a of the speed.
    """

    time_constants_min: tuple[Positive, ...] = ()
    exponents: tuple[Positive, ...] = Field((1.0,), min_length=1)


class SeparateSettings(Settings):
    """The ``separate`` section.

    Attributes
    ----------
    displacement_axis : tuple of str or None
        Displacement axes to separate; None (``all`` in params.yaml): every axis a campaign
        declares. One name or a list of names.
    cold_reference : str
        A run's reference: ``first_sample`` or ``mean_first_n``.
    cold_n : int
        Samples averaged for ``mean_first_n``.
    resample_s : float or None, s
        Campaigns sampled faster are averaged into windows of this length; None or 0: never.
    runs : RunSettings
    speed_responses : SpeedResponseSettings or None
        None: no speed responses.
    geometric_order : int
        Polynomial order of the geometric positioning error of the axis campaigns.
    """

    displacement_axis: tuple[str, ...] | None = None
    cold_reference: Literal["first_sample", "mean_first_n"] = "first_sample"
    cold_n: StrictInt = Field(1, ge=1)
    resample_s: StrictFloat | None = Field(None, ge=0)
    runs: RunSettings = RunSettings()
    speed_responses: SpeedResponseSettings | None = None
    geometric_order: StrictInt = Field(ge=0)

    @field_validator("displacement_axis", mode="before")
    @classmethod
    def _axes(cls, value: Any) -> Any:
        """``all`` (or nothing) -> None; one name -> a list of one."""
        if value is None or value == ALL_AXES:
            return None
        if not isinstance(value, str | list | tuple):
            raise ValueError(f"use {ALL_AXES}, one axis name or a list of them, e.g. [Z]")
        return [value] if isinstance(value, str) else value

"""``params.yaml`` ``validate:``: the limits of the checks of a campaign (``pipeline.validation``).

Every limit but ``max_bridged_gap_s`` is required: the section states every threshold a
campaign is held to. Also read by ``compensation``, whose runtime checks each cycle's readings
as ``validate`` checks a campaign, and by ``discrepancy --raw``.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BeforeValidator, Field, StrictFloat, StrictInt

from pipeline.settings.base import Settings
from schemas import ValidationLimits


def _pair(value: Any) -> Any:
    """Accept ``[low, high]``: two numbers, the first below the second."""
    pair = isinstance(value, list | tuple) and len(value) == 2
    if not pair or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise ValueError("use [low, high], two numbers, e.g. [-20.0, 80.0]")
    if not value[0] < value[1]:
        raise ValueError("low must be below high: use [low, high]")
    return value


Range = Annotated[tuple[StrictFloat, StrictFloat], BeforeValidator(_pair)]


class ValidateSettings(Settings):
    """The ``validate`` section; its fields are those of :class:`schemas.ValidationLimits`.

    Attributes
    ----------
    temperature_range_degC, displacement_range_um, laser_deviation_range_um : tuple of float
        Plausible ranges (low, high) of a temperature (degC), a probe's displacement (um) and a
        laser-measured positioning deviation (um).
    ds18b20_power_on_degC, ds18b20_disconnected_degC : float, degC
        The DS18B20 fault codes.
    interval_tolerance : float
        Relative deviation of a sampling interval from the campaign's median allowed.
    stuck_min_samples : int
    stuck_min_minutes : float, min
    stuck_min_other_change_degC : float, degC
        A sensor identical for this many samples, spanning this long, while another moved
        this much, is stuck.
    spike_threshold_degC : float, degC
        A reading further than this from both neighbours (same side) is a spike.
    laser_target_tolerance_mm : float, mm
        Targets of different laser runs of a campaign agree within this.
    min_samples : int
        Fewest temperature samples a campaign needs to be modelled.
    air_temperature_max_degC, displacement_min_span_um, unit_check_min_rise_degC : float
        Unit checks (degF for degC, mm for um).
    min_program_coverage : float
        Unit check of ``elapsed_s`` against the ``spindle_program`` (minutes for seconds).
    max_bridged_gap_s : float, s
        Longest gap of missing readings of one sensor bridged by linear interpolation.
    """

    temperature_range_degC: Range  # noqa: N815 (params.yaml key)
    ds18b20_power_on_degC: StrictFloat  # noqa: N815 (params.yaml key)
    ds18b20_disconnected_degC: StrictFloat  # noqa: N815 (params.yaml key)
    interval_tolerance: StrictFloat = Field(ge=0)
    stuck_min_samples: StrictInt = Field(ge=1)
    stuck_min_minutes: StrictFloat = Field(ge=0)
    stuck_min_other_change_degC: StrictFloat = Field(ge=0)  # noqa: N815 (params.yaml key)
    spike_threshold_degC: StrictFloat = Field(gt=0)  # noqa: N815 (params.yaml key)
    displacement_range_um: Range
    laser_target_tolerance_mm: StrictFloat = Field(ge=0)
    laser_deviation_range_um: Range
    min_samples: StrictInt = Field(ge=1)
    air_temperature_max_degC: StrictFloat  # noqa: N815 (params.yaml key)
    displacement_min_span_um: StrictFloat = Field(ge=0)
    unit_check_min_rise_degC: StrictFloat = Field(ge=0)  # noqa: N815 (params.yaml key)
    min_program_coverage: StrictFloat = Field(ge=0, le=1)
    max_bridged_gap_s: StrictFloat = Field(600.0, ge=0)

    def limits(self) -> ValidationLimits:
        """Return the limits as the checks take them."""
        return ValidationLimits(**self.model_dump())

"""``params.yaml`` ``compensation:``: limits and fallback timing of the compensation runtime.

Every controller takes a bounded offset, changed at a bounded rate (SINUMERIK MD32760 caps the
change of the temperature compensation per interpolation cycle; FANUC raises an alarm on a jump
of 9999 increments; LinuxCNC's external offsets are limited in value, velocity and
acceleration). The runtime (:mod:`pipeline.compensation`) applies the same two bounds itself,
per axis, before anything is written, so the controller's own limits are a second line, never
the first.
"""

from __future__ import annotations

from pydantic import Field, StrictFloat, StrictInt, field_validator

from pipeline.settings.base import Settings

DEFAULT_AXIS = "default"


class AxisLimits(Settings):
    """Bounds of one axis' offset.

    Attributes
    ----------
    max_offset_um : float, um
        Largest magnitude of the offset written.
    max_rate_um_per_s : float, um/s
        Largest change of the offset per second of machine time (slew).
    """

    max_offset_um: StrictFloat = Field(200.0, gt=0)
    max_rate_um_per_s: StrictFloat = Field(0.5, gt=0)


class CompensationSettings(Settings):
    """The ``compensation`` section: how the runtime checks its inputs, falls back, bounds.

    Attributes
    ----------
    limits : dict of str to AxisLimits
        Per axis; ``default`` applies to every axis not named.
    offset_sign : {-1, 1}
        Offset written = sign x predicted thermal error (-1: the correction that cancels it).
    cycle_s : float, s
        Period of a source without its own clock (a file, OPC UA without a time node).
    stall_s : float, s
        No new reading for this long: the source is stalled.
    hold_s : float, s
        Stalled source, or no model left for an axis: the last good offset is held this long...
    decay_s : float, s
        ...then decays to zero with this time constant.
    range_margin_degC : float, K
        A reading further than this outside the range seen in training is bad.
    recover_cycles : int
        Good cycles in a row before an axis returns from a fallback to its champion.
    write_retries : int
        A refused write is retried this many times in the cycle, then reported.
    retry_wait_s : float, s
        Wait between retries.
    """

    limits: dict[str, AxisLimits] = Field(default_factory=lambda: {DEFAULT_AXIS: AxisLimits()})
    offset_sign: StrictInt = -1
    cycle_s: StrictFloat = Field(10.0, gt=0)
    stall_s: StrictFloat = Field(60.0, gt=0)
    hold_s: StrictFloat = Field(300.0, ge=0)
    decay_s: StrictFloat = Field(600.0, gt=0)
    range_margin_degC: StrictFloat = Field(5.0, ge=0)  # noqa: N815 (params.yaml key)
    recover_cycles: StrictInt = Field(3, ge=1)
    write_retries: StrictInt = Field(3, ge=0)
    retry_wait_s: StrictFloat = Field(0.2, ge=0)

    @field_validator("offset_sign")
    @classmethod
    def _sign(cls, value: int) -> int:
        if value not in (-1, 1):
            raise ValueError(
                "use -1 (write the correction, minus the predicted error) or 1 (write the error)"
            )
        return value

    def limits_of(self, axis: str) -> AxisLimits:
        """Return the limits of ``axis`` (its own entry, else ``default``, else the defaults)."""
        return self.limits.get(axis) or self.limits.get(DEFAULT_AXIS) or AxisLimits()

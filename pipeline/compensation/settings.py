"""The ``compensation:`` section of ``params.yaml``: limits and fallback timing of the runtime.

Every controller takes a bounded offset, changed at a bounded rate (SINUMERIK MD32760 caps the
change of the temperature compensation per interpolation cycle; FANUC raises an alarm on a jump
of 9999 increments; LinuxCNC's external offsets are limited in value, velocity and
acceleration). The runtime applies the same two bounds itself, per axis, before anything is
written, so the controller's own limits are a second line, never the first.
"""

from __future__ import annotations

from collections.abc import Mapping

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pipeline.errors import ParamsError

DEFAULT_AXIS = "default"


class AxisLimits(BaseModel):
    """Bounds of one axis' offset.

    Attributes
    ----------
    max_offset_um : float, um
        Largest magnitude of the offset written.
    max_rate_um_per_s : float, um/s
        Largest change of the offset per second of machine time (slew).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_offset_um: float = Field(200.0, gt=0)
    max_rate_um_per_s: float = Field(0.5, gt=0)


class CompensationSettings(BaseModel):
    """How the runtime checks its inputs, falls back and bounds its offsets.

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

    model_config = ConfigDict(extra="forbid", frozen=True)

    limits: dict[str, AxisLimits] = Field(default_factory=lambda: {DEFAULT_AXIS: AxisLimits()})
    offset_sign: int = Field(-1)
    cycle_s: float = Field(10.0, gt=0)
    stall_s: float = Field(60.0, gt=0)
    hold_s: float = Field(300.0, ge=0)
    decay_s: float = Field(600.0, gt=0)
    range_margin_degC: float = Field(5.0, ge=0)  # noqa: N815 (params.yaml key)
    recover_cycles: int = Field(3, ge=1)
    write_retries: int = Field(3, ge=0)
    retry_wait_s: float = Field(0.2, ge=0)

    def limits_of(self, axis: str) -> AxisLimits:
        """Return the limits of ``axis`` (its own entry, else ``default``, else the defaults)."""
        return self.limits.get(axis) or self.limits.get(DEFAULT_AXIS) or AxisLimits()

    @classmethod
    def from_params(cls, section: Mapping | None) -> CompensationSettings:
        """Build from the ``compensation:`` section.

        Raises
        ------
        ParamsError
            Naming each wrong key path (``compensation.limits.Z.max_rate_um_per_s``), what is
            wrong and the keys allowed.
        """
        try:
            settings = cls.model_validate(dict(section or {}))
        except ValidationError as error:
            lines = []
            for problem in error.errors():
                where = ".".join(str(part) for part in ("compensation", *problem["loc"]))
                lines.append(f"{where}: {problem['msg']}")
            allowed = sorted(cls.model_fields)
            raise ParamsError(
                "params.yaml " + "; ".join(lines) + f" (keys allowed in compensation: {allowed}; "
                f"in a limits entry: {sorted(AxisLimits.model_fields)})"
            ) from None
        if settings.offset_sign not in (-1, 1):
            raise ParamsError(
                f"params.yaml compensation.offset_sign is {settings.offset_sign}; use -1 "
                "(write the correction, minus the predicted error) or 1 (write the error)"
            )
        return settings

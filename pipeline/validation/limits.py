"""The check limits of the ``validate`` stage, read from ``params.yaml`` ``validate:``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pipeline.errors import ParamsError
from schemas import ValidationLimits


def limits_from_params(section: Mapping[str, Any]) -> ValidationLimits:
    """Build the check limits from the ``validate:`` section of ``params.yaml``.

    Parameters
    ----------
    section : mapping
        Keys are the fields of :class:`schemas.ValidationLimits` (all required).

    Returns
    -------
    ValidationLimits

    Raises
    ------
    ValueError
        Naming the missing, unknown or malformed ``validate.<key>``.
    """
    names = list(ValidationLimits.__dataclass_fields__)
    missing = [n for n in names if n not in section]
    unknown = sorted(set(section) - set(names))
    if missing or unknown:
        raise ParamsError(
            f"params.yaml validate: missing keys {missing}, unknown keys {unknown}; "
            f"the section needs exactly {names}"
        )
    values: dict[str, Any] = {}
    for name in names:
        raw = section[name]
        try:
            if name.endswith("_range_degC") or name.endswith("_range_um"):
                low, high = (float(v) for v in raw)
                if not low < high:
                    raise ValueError("low must be below high")
                values[name] = (low, high)
            elif name in ("stuck_min_samples", "min_samples"):
                values[name] = int(raw)
            else:
                values[name] = float(raw)
        except (TypeError, ValueError) as err:
            raise ParamsError(
                f"params.yaml validate.{name} = {raw!r} is not valid ({err}); use "
                + ("[low, high]" if "_range_" in name else "a number")
            ) from err
    return ValidationLimits(**values)

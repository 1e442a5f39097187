"""External heat loads of a test: a heater (or a lamp, a hot-air blower) on part of the machine.

The raw contract writes them in ``campaign.yaml`` as ``heat_loads:``, a list of
``{role, from_min, to_min?, power_W, what?}`` entries: the structure role of the part the load
heats (the sensor-role vocabulary), when it was on (minutes since the campaign start; the last
entry of a role may be open-ended) and the heat it put into the part, W (a heater's electrical
power; a draught that cools the part is a negative load). Loads on the same role are one
piecewise-constant :class:`~pipeline.thermal.program.Program` of power (key ``power_W``); loads
on different roles may overlap in time.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipeline.thermal.program import Program

POWER_KEY = "power_W"
"""Name of the power field of a ``heat_loads`` entry, W."""


@dataclass(frozen=True)
class HeatLoad:
    """The external heat put into one part of the machine over time.

    Attributes
    ----------
    role : str
        Structure role of the heated part (e.g. ``"column_rear"``).
    program : Program
        Power over time, W (key :data:`POWER_KEY`); 0 outside its segments.
    what : str
        Free text: the device and where it sits (e.g. ``"300 W heater mat, column rear face"``).
    """

    role: str
    program: Program
    what: str = ""

    def power_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Power at each instant (right-continuous), W, same shape as ``t_s``."""
        return self.program.value_at(t_s)

    def to_contract(self) -> list[dict[str, Any]]:
        """Return the load's ``heat_loads`` entries (each with ``role``; ``what`` if given)."""
        entries = []
        for entry in self.program.to_contract():
            out: dict[str, Any] = {"role": self.role, **entry}
            if self.what:
                out["what"] = self.what
            entries.append(out)
        return entries


def loads_from_contract(entries: Iterable[Mapping[str, Any]]) -> tuple[HeatLoad, ...]:
    """Build the loads of a campaign from its ``heat_loads`` entries, one per role.

    Parameters
    ----------
    entries : iterable of mapping
        ``{role, from_min, to_min?, power_W, what?}`` each.

    Returns
    -------
    tuple of HeatLoad
        One per role, in order of first appearance.

    Raises
    ------
    ValueError
        If an entry has no ``role``, lacks ``from_min`` or ``power_W``, has a power that is not
        finite, or two entries of one role overlap in time; the message names the entry
        (1-based) and says how to write it.
    """
    by_role: dict[str, list[tuple[int, Mapping[str, Any]]]] = {}
    for number, entry in enumerate(entries, start=1):
        role = entry.get("role")
        if not isinstance(role, str) or not role:
            raise ValueError(
                f"heat_loads entry {number} ({dict(entry)}) has no role; write it as "
                "{role: column_rear, from_min: 0, to_min: 120, power_W: 300}"
            )
        power = entry.get(POWER_KEY)
        if not isinstance(power, int | float) or not np.isfinite(float(power)):
            raise ValueError(
                f"heat_loads entry {number} ({dict(entry)}) needs a finite {POWER_KEY} (W)"
            )
        by_role.setdefault(role, []).append((number, entry))
    loads = []
    for role, numbered in by_role.items():
        try:
            program = Program.from_contract([e for _, e in numbered], key=POWER_KEY)
        except ValueError as err:
            numbers = ", ".join(str(n) for n, _ in numbered)
            raise ValueError(f"heat_loads entries {numbers} (role {role}): {err}") from err
        what = "; ".join(dict.fromkeys(str(e["what"]) for _, e in numbered if e.get("what")))
        loads.append(HeatLoad(role, program, what))
    return tuple(loads)


def loads_to_contract(loads: Sequence[HeatLoad]) -> list[dict[str, Any]]:
    """Return the ``heat_loads`` list of ``loads`` (the inverse of :func:`loads_from_contract`)."""
    return [entry for load in loads for entry in load.to_contract()]

"""``params.yaml`` ``model_axis:``: the linear-axis composite model of the patent.

Read by :func:`pipeline.models.axis_fit.build`: E(x, T) = P_geo(x) + (k(T) - k0) x, validated on
the validation axis campaign(s).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, StrictFloat, StrictInt

from pipeline.settings.base import Settings


class ModelAxisSettings(Settings):
    """The ``model_axis`` section.

    Attributes
    ----------
    temperature : str
        ``rise`` (K above each campaign's cold run; k0 = c0) or ``absolute`` (degC, the patent
        literally).
    selection_rule : str
        The best-subset winner used: ``aicc``, ``adj_r2`` or ``parsimonious``.
    exclude_sensors : tuple of str
        Sensors never offered to the selection.
    max_exhaustive : int
        Best subset: exhaustive search up to this many candidate sensors.
    patent_band_um : float, um
        The patent's validation residual band, +- this.
    """

    temperature: Literal["rise", "absolute"]
    selection_rule: Literal["aicc", "adj_r2", "parsimonious"]
    exclude_sensors: tuple[str, ...] = ()
    max_exhaustive: StrictInt = Field(ge=1)
    patent_band_um: StrictFloat = Field(gt=0)

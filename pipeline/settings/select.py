"""``params.yaml`` ``select:``: the sensitive-point selection methods and what they select on.

The names of ``methods`` and their parameters are those of the selection registry
(:mod:`pipeline.selection.registry`), checked against it by
:func:`pipeline.protocol.selection_runs.method_entries` when the ``select`` stage starts.
"""

from __future__ import annotations

from typing import Any, Literal

from pipeline.settings.base import Settings


class SelectSettings(Settings):
    """The ``select`` section.

    Attributes
    ----------
    features : str
        ``temperature_rise`` (T minus T at the run's cold reference) or ``absolute`` (degC).
    methods : dict of str to dict
        Name -> the method's parameters; ``method:`` runs a registry method under another name,
        ``inputs:`` (``temperatures`` or ``temperatures_and_speed``) the inputs it is offered.
    """

    features: Literal["temperature_rise", "absolute"] = "temperature_rise"
    methods: dict[str, dict[str, Any] | None]

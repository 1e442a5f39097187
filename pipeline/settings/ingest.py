"""``params.yaml`` ``ingest:``: how the raw campaign folders are read (:mod:`pipeline.io`)."""

from __future__ import annotations

from pydantic import Field, StrictFloat

from pipeline.settings.base import Settings


class IngestSettings(Settings):
    """The ``ingest`` section.

    Attributes
    ----------
    max_alignment_gap_s : float, s
        Displacement samples are aligned to the temperature time base by linear interpolation;
        a temperature instant further than this from any displacement sample gets none.
    """

    max_alignment_gap_s: StrictFloat = Field(ge=0)

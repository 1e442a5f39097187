"""``params.yaml`` ``protocol:``: how each model is scored on campaigns it has not seen.

Read by ``select`` and ``evaluate`` (and ``compensation``, which rebuilds the training units):
the hv-block buffer and the rolling origin of the held-out training units
(:mod:`pipeline.protocol.units`) and the score that ranks (:mod:`pipeline.protocol.ranking`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, StrictFloat, StrictInt

from pipeline.settings.base import Settings


class ProtocolSettings(Settings):
    """The ``protocol`` section.

    Attributes
    ----------
    buffer_campaigns : int
        hv-block buffer: campaigns of the same run on either side of a held-out campaign that
        are left out of training too (0: plain leave-one-out).
    forward_min_train : int
        Rolling origin: training campaigns that must have ended before the first forecast one
        started.
    forward_min_share : float
        Rolling origin: share of all training campaigns (0 to 1, rounded up) that must have
        ended before a forecast one started.
    forward_max_origins : int
        Rolling origin: at most this many fits; above this many forecast campaigns,
        consecutive ones share one fit (each fit is on every campaign before its origin, so one
        fit per forecast would cost campaigns squared).
    max_folds : int
        Leave-one-out schemes: at most this many fits; above this many seasons (or campaigns),
        consecutive ones are left out together in that many blocks.
    rank_by : str
        The held-out score that ranks: ``auto`` (the scheme the campaigns allow), ``loso``,
        ``loco`` or ``forward``.
    """

    buffer_campaigns: StrictInt = Field(1, ge=0)
    forward_min_train: StrictInt = Field(1, ge=1)
    forward_min_share: StrictFloat = Field(0.5, ge=0, le=1)
    forward_max_origins: StrictInt = Field(5, ge=1)
    max_folds: StrictInt = Field(10, ge=2)
    rank_by: Literal["auto", "loso", "loco", "forward"] = "auto"

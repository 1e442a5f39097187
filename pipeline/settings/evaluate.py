"""``params.yaml`` ``evaluate:``: the candidates scored, their hyper-parameters, the champion rule.

The model names (the keys of ``candidates`` and ``model_params``) are those of the model
registry (:mod:`pipeline.models.registry`), checked against it by
:func:`pipeline.protocol.candidates.candidate_list`; the selections those of ``select.methods``.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BeforeValidator, Field, StrictBool, StrictFloat, StrictInt

from pipeline.settings.base import Settings


def _selection_names(value: Any) -> Any:
    """Accept a selection name or a list of them, as written in params.yaml."""
    names = [value] if isinstance(value, str) else value
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise ValueError("use a selection method's name or a list of them, e.g. [all, best_subset]")
    return value


Selections = Annotated[str | list[str], BeforeValidator(_selection_names)]


class ChampionSettings(Settings):
    """How the axis' champion is chosen (``evaluate.champion``).

    Attributes
    ----------
    min_improvement : float
        A model must leave at least this fraction less held-out RMS than no compensation (on
        the same samples), else the champion is ``none`` (do not compensate).
    min_coverage : float
        ...and have predicted this share of the held-out samples ``none`` was scored on.
    """

    min_improvement: StrictFloat = Field(0.1, ge=0, lt=1)
    min_coverage: StrictFloat = Field(0.95, ge=0, le=1)


class EvaluateSettings(Settings):
    """The ``evaluate`` section.

    Attributes
    ----------
    candidates : dict of str to str or list of str
        Model -> the selection(s) that feed it; ``twin: roles`` is the physical twin.
    full_grid : bool
        Every model on every ``select.methods`` entry.
    model_params : dict of str to dict
        Hyper-parameters by model, e.g. ``{bp: {max_epochs: 3000}}``.
    n_jobs : int
        Parallel fits (joblib processes; -1: every core); a loop projected to take less than
        :data:`pipeline.progress.SERIAL_UNDER_S` runs in the stage's own process.
    champion : ChampionSettings
    """

    candidates: dict[str, Selections]
    full_grid: StrictBool = False
    model_params: dict[str, dict[str, Any]] = {}
    n_jobs: StrictInt = 1
    champion: ChampionSettings = ChampionSettings()

"""Which model runs on which input selection, and the parallel run of all of them.

``params.yaml`` ``evaluate.candidates`` maps each model to the selection method (or the list of
methods) that feeds it: the sources' defaults (DL on FC-GRD, PCDL on the grey-relational top k,
MLR on the best subset), the plain baselines (``mlr`` and ``ridge`` on ``all``, every
temperature, no lag, no speed) and ``ridge`` on ``all_speed`` (every temperature and speed
response under a cross-validated penalty); ``evaluate.full_grid: true`` runs every model on
every selection instead. Models that use no input (``none``, ``arma``, ``ar_reduced``,
``tv_ar``, ``svr``) always run on selection ``none``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

from joblib import delayed
from threadpoolctl import threadpool_limits

from pipeline.models.registry import MODELS, make_model
from pipeline.progress import run_jobs
from pipeline.protocol.cross_season import Candidate, UnitResult, fit_and_score
from pipeline.protocol.units import CampaignSeries, TrainingUnit
from pipeline.settings.base import unknown_name_error

LOGGER = logging.getLogger(__name__)

NO_SELECTION = "none"


def candidate_list(
    pairs: Mapping[str, str], selections: Mapping[str, object], full_grid: bool
) -> list[Candidate]:
    """Return the candidates to score.

    Parameters
    ----------
    pairs : mapping of str to str or list of str
        ``evaluate.candidates``: model name -> selection method(s).
    selections : mapping
        Selection methods available (``reports/selection/selected.json`` ``methods``).
    full_grid : bool
        Every model on every selection method (models without temperature inputs on ``none``).

    Raises
    ------
    KeyError
        If a model is not registered or a selection method was not run by ``select``; the
        message lists what exists.
    """
    wanted = {
        model: [chosen] if isinstance(chosen, str) else list(chosen)
        for model, chosen in pairs.items()
    }
    for model, chosen in wanted.items():
        if model not in MODELS:
            raise unknown_name_error(
                ("evaluate", "candidates", model), model, sorted(MODELS), "model", "registered"
            )
        unknown = [s for s in chosen if s not in selections]
        if MODELS[model].uses_temperatures and unknown:
            raise KeyError(
                f"params.yaml evaluate.candidates: model '{model}' is fed by selection "
                f"{unknown}, which the select stage did not run; run one of "
                f"{sorted(selections)} or add it to select.methods"
            )
    candidates: list[Candidate] = []
    for model, chosen in wanted.items():
        if not MODELS[model].uses_temperatures:
            candidates.append(Candidate(model, NO_SELECTION))
        elif full_grid:
            candidates.extend(Candidate(model, method) for method in selections)
        else:
            candidates.extend(Candidate(model, method) for method in chosen)
    return list(dict.fromkeys(candidates))


def unit_sensors(
    candidate: Candidate, unit: TrainingUnit, selected: Mapping[str, Mapping[str, Mapping]]
) -> list[str]:
    """Return the inputs chosen on this training unit (none for models without inputs)."""
    if candidate.selection == NO_SELECTION:
        return []
    return list(selected[candidate.selection][unit.name]["inputs"])


def run_all(
    candidates: list[Candidate],
    units: list[TrainingUnit],
    series: list[CampaignSeries],
    selected: Mapping[str, Mapping[str, Mapping]],
    model_params: Mapping[str, Mapping],
    n_jobs: int,
    label: str = "candidates",
) -> list[UnitResult]:
    """Fit every candidate on every training unit and score it on every campaign.

    The (candidate, unit) fits run in parallel in ``n_jobs`` joblib worker processes; each
    sees only the campaigns of its unit for fitting. How far they are is shown under ``label``
    (:mod:`pipeline.progress`); each result counts its fit's warnings.
    """
    jobs = [
        delayed(fit_and_score)(
            candidate,
            unit,
            series,
            make_model(candidate.model, **dict(model_params.get(candidate.model) or {})),
            sensors,
        )
        for candidate in candidates
        for unit in units
        for sensors in [unit_sensors(candidate, unit, selected)]
        if sensors or not MODELS[candidate.model].uses_temperatures
    ]
    LOGGER.info(
        "%d candidates x %d training units = %d fits", len(candidates), len(units), len(jobs)
    )
    # One BLAS thread per process: statsmodels' small Kalman filters and least-squares fits run
    # many times slower with multi-threaded BLAS on a busy machine (joblib workers already
    # limit theirs; this covers n_jobs=1 in the main process).
    with threadpool_limits(limits=1):
        return run_jobs(jobs, n_jobs, label, logger=LOGGER)

"""``params.yaml`` ``discrepancy:``: which effects the baseline twin misses, and how that is found.

Read by the ``discrepancy`` stage (:mod:`pipeline.discrepancy.workflow`): the forward search
(:mod:`pipeline.discrepancy.search`), the localisation of the residuals
(:mod:`pipeline.discrepancy.localise`) and the identifiability of each candidate effect
(:mod:`pipeline.discrepancy.identifiability`). The effect names of ``candidates`` and the sizes
of ``identifiability.plausible`` are those of the library, checked there.
"""

from __future__ import annotations

from pydantic import Field, StrictBool, StrictFloat, StrictInt

from pipeline.settings.base import Settings


class LocaliseSettings(Settings):
    """How the disagreement is split and when a finding is worth reporting.

    Attributes
    ----------
    warmup_min : float, min
        Minutes after a start from rest counted as warm-up.
    transient_min : float, min
        Minutes after a change between two non-zero speeds counted as speed change.
    max_lag_min : float, min
        Largest lag of the ambient trend tried.
    min_correlation : float
        |correlation| of the Z residual with the ambient trend above which it is reported.
    min_floor_ratio : float
        A phase or speed level is reported when its mean residual exceeds this many noise floors.
    """

    warmup_min: StrictFloat = Field(60.0, ge=0)
    transient_min: StrictFloat = Field(30.0, ge=0)
    max_lag_min: StrictFloat = Field(120.0, ge=0)
    min_correlation: StrictFloat = Field(0.5, ge=0, le=1)
    min_floor_ratio: StrictFloat = Field(3.0, ge=0)


class IdentifiabilityParams(Settings):
    """Whether the campaigns can show each candidate at all (``discrepancy.identifiability``).

    Attributes
    ----------
    min_signal_sigma : float
        Smallest visible signal, RMS in noise sigmas, of an identifiable effect.
    max_collinearity_index : float
        Largest collinearity index (Brun, Reichert and Künsch 2001) of an identifiable effect.
    prior_log_sd : float
        How far the baseline may move a positive parameter to absorb an effect: the standard
        deviation of its prior, in its natural log (1: a factor e).
    plausible : dict of str to float
        Size of an effect at which its signal is measured, overriding the library's
        (:data:`pipeline.discrepancy.visibility.PLAUSIBLE`): parameter -> value in its unit.
    """

    min_signal_sigma: StrictFloat = Field(1.5, ge=0)
    max_collinearity_index: StrictFloat = Field(1000.0, gt=0)
    prior_log_sd: StrictFloat = Field(1.0, gt=0)
    plausible: dict[str, StrictFloat] = {}


class DiscrepancySettings(Settings):
    """The ``discrepancy`` section.

    Attributes
    ----------
    candidates : tuple of str
        Effects offered (names of the effect registry); empty: every registered effect.
    min_heldout_reduction : float
        Relative reduction of the held-out Z RMS that qualifies an effect, 0..1.
    min_heldout_temperature_reduction : float
        Relative reduction of the held-out temperature RMS that qualifies an effect (> 1
        disables this route).
    max_delta_bic : float
        Largest change of BIC for an effect to be named (negative: the data prefer it).
    n_folds : int
        Folds across campaigns (leave-one-campaign-out with at most this many campaigns).
    hold_out_validation : bool
        Search on the non-validation campaigns; check the named effects on the validation ones.
    n_jobs : int
        Parallel calibrations (joblib processes); 1: serial. A loop projected to take less than
        :data:`pipeline.progress.SERIAL_UNDER_S` runs in the stage's own process.
    max_effects : int or None
        Stop after naming this many effects; None: as many as there are candidates.
    localise : LocaliseSettings
    identifiability : IdentifiabilityParams
    mlflow : bool
        Log a run to the store of the ``tracking`` section.
    experiment : str
        Its MLflow experiment.
    """

    candidates: tuple[str, ...] = ()
    min_heldout_reduction: StrictFloat = Field(0.2, ge=0)
    min_heldout_temperature_reduction: StrictFloat = Field(0.2, ge=0)
    max_delta_bic: StrictFloat = -10.0
    n_folds: StrictInt = Field(4, ge=2)
    hold_out_validation: StrictBool = True
    n_jobs: StrictInt = 2
    max_effects: StrictInt | None = Field(None, ge=1)
    localise: LocaliseSettings = LocaliseSettings()
    identifiability: IdentifiabilityParams = IdentifiabilityParams()
    mlflow: StrictBool = True
    experiment: str = Field("thermal-discrepancy", min_length=1)

"""The calibrated physical twin as candidate model ``twin`` of the ``evaluate`` stage.

The twin of :mod:`pipeline.discrepancy` is not a scikit-learn estimator on temperature
features: it is driven by the campaign's spindle program (rpm), its ambient reading and its
initial temperatures, and it is calibrated by bounded least squares on the temperatures and Z
drift of the campaigns it is built on (:func:`pipeline.discrepancy.calibrate.calibrate`). So it
is run here, beside the model registry, on the same training units and scored on every campaign
with the same score rows (:func:`pipeline.protocol.cross_season.score_row`) as the registry's
models:

- model ``twin``, selection ``roles`` (it reads every sensor whose contract role is a node of
  its thermal network, plus the ambient sensor; no selection method chooses them), mode
  ``static`` (it runs without the measured error, like the temperature models);
- the *augmented* twin: the baseline network plus the effects the ``discrepancy`` stage named
  (``reports/discrepancy/discrepancy.json`` ``named_effects``); without that report the
  baseline twin, and the report says so;
- calibrated on each training unit's campaigns only (their temperatures and Z), then predicts
  every campaign from that campaign's program, ambient and first readings (never its Z).

The twin predicts the Z drift since the first sample (um, the sign of the probe reading); the
separation stage defines the thermal error as displacement minus its cold value
(:func:`pipeline.separation.features.reference_value`), so the same cold reference is applied to the
prediction, over the samples where the displacement was measured: like for like.

The effect *set* is named by the ``discrepancy`` stage on the training campaigns (it holds the
validation campaigns back, ``discrepancy.hold_out_validation``); the parameters are fitted per
unit. The LOSO and single-campaign units still use an effect set named on all training
campaigns, which includes their own test campaigns of the training split.

The candidate is skipped, with the reason in the comparison report and MLflow
(:func:`skip_reason`), on axes other than Z (the twin models the Z drift), when the
discrepancy stage found the campaigns untestable (no structure role, too few campaigns), and
when campaigns continue one another in a run (the twin starts each campaign from its own first
readings, so it cannot express a warm campaign's drift from its run's reference).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from joblib import delayed
from threadpoolctl import threadpool_limits

from pipeline.discrepancy.calibrate import Calibration, calibrate, predict
from pipeline.discrepancy.data import DISPLACEMENT_COLUMN, MeasuredCampaign
from pipeline.discrepancy.model import ROLE_NODES, TwinModel, build_model, loaded_roles
from pipeline.discrepancy.report import STATUS_UNTESTABLE
from pipeline.errors import InputDataError, ParamsError
from pipeline.progress import run_jobs
from pipeline.protocol.cross_season import STATIC, Candidate, UnitResult, score_row
from pipeline.protocol.units import CampaignSeries, TrainingUnit
from pipeline.separation.features import reference_value
from pipeline.warnings_capture import captured

LOGGER = logging.getLogger(__name__)

TWIN_MODEL = "twin"
"""Name of the candidate in ``evaluate.candidates`` and in every output."""
TWIN_SELECTION = "roles"
"""Its selection: the sensors whose role is a node of the network, and the ambient sensor."""
AMBIENT_ROLE = "ambient"


@dataclass(frozen=True)
class TwinSetup:
    """What the twin candidate needs beyond the campaign series.

    Attributes
    ----------
    campaigns : dict of str to MeasuredCampaign
        Campaign id -> the campaign as the twin sees it (speed, program, temperatures in degC
        with roles, Z drift in um), on exactly the samples of its :class:`CampaignSeries`.
    effects : frozenset of str
        Effects switched on beyond the baseline network.
    effects_source : str
        Where the effects come from, in words (for the log and the report).
    cold_reference : str
        ``separate.cold_reference``: ``first_sample`` or ``mean_first_n``.
    cold_n : int
        ``separate.cold_n``: samples averaged for ``mean_first_n``.
    calibration : dict
        Keyword arguments of :func:`pipeline.discrepancy.calibrate.calibrate` (``n_starts``,
        ``max_nfev``, ``tol``...); default its own.
    """

    campaigns: dict[str, MeasuredCampaign]
    effects: frozenset[str]
    effects_source: str
    cold_reference: str = "first_sample"
    cold_n: int = 1
    calibration: dict = field(default_factory=dict)

    @property
    def roles(self) -> frozenset[str]:
        """Sensor roles of all campaigns: the machine's sensor layout (no measured values)."""
        return frozenset(r for c in self.campaigns.values() for r in c.roles.values())

    @property
    def load_roles(self) -> frozenset[str]:
        """Roles that take an external heat load (``heat_loads:``) in any campaign."""
        return loaded_roles(self.campaigns.values())


@dataclass(frozen=True)
class CalibratedTwin:
    """The twin calibrated on one training unit (``UnitResult.estimator`` of the candidate).

    Attributes
    ----------
    roles : frozenset of str
        Roles the network was built for.
    effects : frozenset of str
    calibration : Calibration
        Parameters (``params``: name -> (value, unit)) and fit diagnostics.
    load_roles : frozenset of str
        Roles that take an external heat load in the campaigns it was built for.
    """

    roles: frozenset[str]
    effects: frozenset[str]
    calibration: Calibration = field(repr=False)
    load_roles: frozenset[str] = frozenset()

    def model(self) -> TwinModel:
        """Build the twin's network (a fresh instance, without cached campaigns)."""
        return build_model(self.roles, self.effects, self.load_roles)

    def predict_z(self, campaign: MeasuredCampaign) -> np.ndarray:
        """Predicted Z drift since the first sample, ndarray of shape (n,), um."""
        return np.asarray(predict(self.model(), self.calibration, campaign).z_um, dtype=float)


def skip_reason(
    axis: str, document: Mapping | None, series: Sequence[CampaignSeries], roles: frozenset[str]
) -> str | None:
    """Why the twin cannot be scored on this axis and these campaigns, or None if it can.

    Parameters
    ----------
    axis : str
        Displacement axis.
    document : mapping or None
        ``reports/discrepancy/discrepancy.json`` (None when absent).
    series : sequence of CampaignSeries
        The axis' campaigns.
    roles : frozenset of str
        Sensor roles of the campaigns.
    """
    if axis != DISPLACEMENT_COLUMN.removeprefix("disp_"):
        return f"the twin models the {DISPLACEMENT_COLUMN.removeprefix('disp_')} drift only"
    if document is not None and document.get("status") == STATUS_UNTESTABLE:
        return f"the twin cannot be compared with these campaigns: {document.get('reason')}"
    if not roles & set(ROLE_NODES):
        return (
            "no sensor has a structure role (campaign.yaml sensors: role), so the twin has "
            "no node to attach to"
        )
    continued = [s.campaign_id for s in series if s.run_id and s.run_id != s.campaign_id]
    if continued:
        return (
            f"campaigns {', '.join(continued)} continue a run and start warm: the twin starts "
            "each campaign from its own first readings and cannot count its drift from the "
            "run's reference"
        )
    return None


def named_effects(document: Mapping | None) -> tuple[frozenset[str], str]:
    """Effects of the augmented twin from ``discrepancy.json``, and where they came from.

    Parameters
    ----------
    document : mapping or None
        The parsed ``reports/discrepancy/discrepancy.json``; ``None`` when it does not exist.

    Returns
    -------
    effects : frozenset of str
        Its ``named_effects`` (empty: the baseline twin).
    source : str
        E.g. ``"augmented twin: baseline + motor_heat (reports/discrepancy/discrepancy.json)"``.

    Raises
    ------
    ValueError
        If the document has no ``named_effects`` list.
    """
    if document is None:
        return frozenset(), "baseline twin: no discrepancy report (run dvc repro discrepancy)"
    effects = document.get("named_effects")
    if not isinstance(effects, list):
        raise InputDataError(
            "reports/discrepancy/discrepancy.json has no 'named_effects' list; rerun the "
            "discrepancy stage (dvc repro discrepancy)"
        )
    if not effects:
        return frozenset(), "baseline twin: the discrepancy stage named no missing effect"
    return frozenset(effects), (
        f"augmented twin: baseline + {', '.join(sorted(effects))} "
        "(named by the discrepancy stage, reports/discrepancy/discrepancy.json)"
    )


def twin_campaigns(
    table: pd.DataFrame, campaigns: pd.DataFrame, series: Sequence[CampaignSeries]
) -> dict[str, MeasuredCampaign]:
    """Campaigns as the twin sees them, on the samples of the separated table.

    Parameters
    ----------
    table : DataFrame
        ``data/separated/spindle_thermal_error.parquet`` (``campaign_id``, ``source_row``,
        ``elapsed_s``, ``rpm``, ``displacement_um``, one column per sensor in degC...).
    campaigns : DataFrame
        ``data/validated/spindle/campaigns.parquet`` (``sensors_json`` with each sensor's role,
        ``spindle_program_json``, ``has_spindle_log``...).
    series : sequence of CampaignSeries
        The campaigns scored; each gets its twin campaign.

    Returns
    -------
    dict of str to MeasuredCampaign
        By campaign id, in the order of ``series``.

    Raises
    ------
    ValueError
        If a campaign is missing from ``campaigns`` or its samples differ from its series'.
    """
    samples = table.rename(columns={"displacement_um": DISPLACEMENT_COLUMN})
    rows = {str(r["campaign_id"]): r for r in campaigns.to_dict("records")}
    out = {}
    for item in series:
        if item.campaign_id not in rows:
            raise ValueError(
                f"campaign {item.campaign_id} is in the separated table but not in "
                "data/validated/spindle/campaigns.parquet; rerun dvc repro separate_spindle"
            )
        campaign = MeasuredCampaign.from_tables(rows[item.campaign_id], samples)
        elapsed = item.features.index.get_level_values("elapsed_s").to_numpy(dtype=float)
        if not np.array_equal(campaign.t_s, elapsed):
            raise ValueError(
                f"campaign {item.campaign_id}: the twin's samples differ from the separated "
                "table's (duplicate elapsed_s?); check data/separated/spindle_thermal_error.parquet"
            )
        out[item.campaign_id] = campaign
    return out


def twin_sensors(campaign: MeasuredCampaign) -> list[str]:
    """Sensors the twin reads: those on a node of its network and the ambient one."""
    return [s for s, role in campaign.roles.items() if role in ROLE_NODES or role == AMBIENT_ROLE]


def as_thermal_error(z_um: np.ndarray, measured: np.ndarray, reference: str, n: int) -> np.ndarray:
    """Express a predicted Z drift as the separation stage expresses the measured one.

    Parameters
    ----------
    z_um : ndarray of shape (n_samples,)
        Predicted drift since the first sample, um.
    measured : ndarray of shape (n_samples,)
        The campaign's thermal error, um; only where it is finite is used (the samples that
        set the measured cold value), never its values.
    reference : {"first_sample", "mean_first_n"}
    n : int

    Returns
    -------
    ndarray of shape (n_samples,)
        ``z_um`` minus its cold value over the measured samples, um.
    """
    z = np.asarray(z_um, dtype=float)
    cold = reference_value(np.where(np.isfinite(measured), z, np.nan), reference, n)
    return z - (0.0 if np.isnan(cold) else cold)


def fit_and_score_twin(
    unit: TrainingUnit, series: Sequence[CampaignSeries], setup: TwinSetup
) -> UnitResult:
    """Calibrate the twin on the unit's campaigns and score it on the unit's test campaigns.

    Parameters
    ----------
    unit : TrainingUnit
    series : sequence of CampaignSeries
        Every campaign scored (targets in um).
    setup : TwinSetup

    Returns
    -------
    UnitResult
        Candidate ``twin/roles``, mode ``static``; ``chosen_params`` holds the effects, the
        calibrated parameters (each name ends with its unit, e.g. ``C_bearing_J_per_K``), the
        training Z RMS (um) and whether the least squares converged; ``estimator`` a
        :class:`CalibratedTwin`; ``warnings`` what the calibration and predictions warned.
    """
    candidate = Candidate(TWIN_MODEL, TWIN_SELECTION)
    training = [setup.campaigns[c] for c in unit.campaigns]
    model = build_model(setup.roles, setup.effects, setup.load_roles)
    with threadpool_limits(limits=1), captured(fit=True) as counts:
        calibration = calibrate(model, training, **setup.calibration)
        fitted = CalibratedTwin(setup.roles, setup.effects, calibration, setup.load_roles)
        rows, predictions = [], {}
        for test in (t for t in series if unit.scores(t.campaign_id)):
            z = predict(model, calibration, setup.campaigns[test.campaign_id]).z_um
            predicted = as_thermal_error(z, test.target, setup.cold_reference, setup.cold_n)
            predictions[(STATIC, test.campaign_id)] = predicted
            row = score_row(candidate, unit, STATIC, test, predicted)
            if row is not None:
                rows.append(row)
    chosen = {
        "effects": sorted(setup.effects),
        **{name: value for name, (value, _) in calibration.params.items()},
        "train_rmse_z_um": calibration.rmse_z_um,
        "converged": calibration.converged,
    }
    sensors = sorted({s for c in training for s in twin_sensors(c)})
    frame = pd.DataFrame(rows)
    return UnitResult(candidate, unit, sensors, chosen, frame, predictions, fitted, counts)


def run_twin(
    units: Sequence[TrainingUnit],
    series: Sequence[CampaignSeries],
    setup: TwinSetup,
    n_jobs: int,
) -> list[UnitResult]:
    """Calibrate and score the twin on every training unit, ``n_jobs`` units in parallel.

    The units with most campaigns (the slowest calibrations) are dispatched first.

    Returns
    -------
    list of UnitResult
        One per unit, in the order of ``units``.
    """
    start = time.perf_counter()
    order = sorted(range(len(units)), key=lambda i: -len(units[i].campaigns))
    jobs = [delayed(fit_and_score_twin)(units[i], list(series), setup) for i in order]
    found = run_jobs(jobs, n_jobs, "twin calibrations", "calibrations", LOGGER)
    done = dict(zip(order, found, strict=True))
    results = [done[i] for i in range(len(units))]
    LOGGER.info(
        "twin candidate (%s): %d calibrations in %.1f s",
        setup.effects_source,
        len(units),
        time.perf_counter() - start,
    )
    return results


def split_twin(pairs: Mapping[str, str]) -> tuple[dict[str, str], bool]:
    """Separate the twin from the registry's candidates in ``evaluate.candidates``.

    Parameters
    ----------
    pairs : mapping of str to str
        Model name -> selection method; the twin's entry is ``twin: roles``.

    Returns
    -------
    registry : dict of str to str
        The other entries.
    with_twin : bool
        Whether the twin is a candidate.

    Raises
    ------
    KeyError
        If the twin is paired with another selection than ``roles``.
    """
    registry = {model: selection for model, selection in pairs.items() if model != TWIN_MODEL}
    if TWIN_MODEL not in pairs:
        return registry, False
    if pairs[TWIN_MODEL] != TWIN_SELECTION:
        raise ParamsError(
            f"params.yaml evaluate.candidates: model '{TWIN_MODEL}' reads the sensors by their "
            f"contract role; write '{TWIN_MODEL}: {TWIN_SELECTION}' (got '{pairs[TWIN_MODEL]}')"
        )
    return registry, True

"""What a lost sensor costs, and how few sensors would do: fallbacks and the sensor budget.

**Fallbacks** (:func:`fallback_fits`). For each temperature sensor the champion uses, the
champion's family (same model, same hyper-parameters) is fitted without that sensor: on all
training campaigns (the estimator the runtime switches to when the sensor fails, with its input
list) and on each held-out unit of the ranking scheme, scored on the campaigns that unit scores
exactly as the champion was (:func:`pipeline.protocol.cross_season.fit_and_score`). Its held-out
RMS (the mean over the held-out campaigns of the per-campaign RMS, the ``Mn_rms_um`` statistic
of :mod:`pipeline.protocol.scoring`) stands next to the champion's and to no compensation on
the same samples. The champion's own score is taken on the same (unit, campaign) pairs.

*Inputs per held-out unit.* With ``selected`` (``reports/selection/selected.json``) each
held-out unit uses its *own* selection (the champion's selection method run on that unit's
training campaigns) minus the lost sensor: nothing about the held-out campaigns enters the
inputs. Without it, each unit uses the champion's *pooled* inputs minus the lost sensor: a small
leak, since the pooled selection saw the held-out campaigns (the selection bias of Ambroise and
McLachlan 2002, "Selection bias in gene extraction on the basis of microarray gene-expression
data", PNAS 99(10)); :attr:`Fallback.inputs_rule` says which was used.

A champion with a single temperature input and no speed response has nothing left when that
sensor fails: no fallback model (:attr:`Fallback.estimator` None; the runtime holds the last
offset and decays it). The champion ``none`` and the models on the error series alone (no
inputs) have no fallback at all (empty list).

**Sensor budget** (:func:`sensor_budget`). For k = 1, 2, ..., K temperature sensors: the best
model of the champion's family with k sensors and its held-out RMS. On each held-out unit, the
k sensors are the minimum-RSS subset of size k of a linear regression of the thermal error on
the sensors' rises, chosen on the unit's *training* campaigns only
(:func:`pipeline.selection.best_subset.best_subset`: exhaustive over all subsets up to
``max_exhaustive`` sensors, then sequential replacement, Miller 2002, "Subset Selection in
Regression", 2nd ed., Chapman & Hall/CRC). The speed responses the champion uses stay in every
regression: the error and the rises are first residualised on them (and an intercept), which
gives exactly the RSS of the regression with the speed columns in (Frisch and Waugh 1933,
"Partial time regressions as compared with individual trends", Econometrica 1(4); Lovell 1963,
"Seasonal adjustment of economic time series and multiple regression analysis", Journal of the
American Statistical Association 58(304)). The champion's family is then fitted on the unit with
those k sensors plus the speed responses, and scored on the unit's held-out campaigns. With
``selected``, a unit's speed responses are those of its own selection, otherwise the
champion's (pooled) ones.

K is the number of sensors offered, capped at the champion's sensor count + :data:`EXTRA_K`
and at :data:`MAX_K` (or at ``max_k``): the curve runs through the champion's size and a little
beyond, where the fits stay cheap. The ``sensors`` column is the subset chosen on all training
campaigns (what a machine builder would fit); ``stability`` the share of held-out units that
chose the same set.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from joblib import delayed
from matplotlib.figure import Figure
from sklearn.base import RegressorMixin
from threadpoolctl import threadpool_limits

from pipeline.models.registry import MODELS, make_model
from pipeline.plots import (
    PANEL_TITLE_FONTSIZE,
    TITLE_FONTSIZE,
    fit_tick_labels,
    new_figure,
    save_figure,
    wrap_text,
)
from pipeline.progress import run_jobs
from pipeline.protocol.cross_season import Candidate, UnitResult, fit_and_score
from pipeline.protocol.scoring import compensation_ratio, summarise
from pipeline.protocol.units import POOLED, POOLED_UNIT, CampaignSeries, TrainingUnit, stack
from pipeline.selection.best_subset import best_subset
from pipeline.separation.features import is_speed_feature, natural_sorted

LOGGER = logging.getLogger(__name__)

MAX_K = 8
"""Most temperature sensors in the budget unless ``max_k`` says otherwise."""
EXTRA_K = 2
"""The budget goes this many sensors beyond the champion's count."""
MAX_EXHAUSTIVE = 20
"""Sensors searched exhaustively per unit (about 1 s each on one core); above: approximate."""
UNIT_SELECTION, POOLED_INPUTS = "unit_selection", "pooled_inputs"
MIN_RSS, CHAMPION = "min_rss", "champion"
BUDGET_COLUMNS = [
    "axis",
    "model",
    "scheme",
    "choice",
    "k",
    "sensors",
    "speed_inputs",
    "heldout_rms_um",
    "none_rms_um",
    "eta",
    "n_campaigns",
    "stability",
]
NO_FALLBACK = (
    "no input is left without this sensor: no fallback model; the runtime holds the last "
    "offset and decays it"
)


@dataclass(frozen=True)
class Fallback:
    """The champion's family without one temperature sensor.

    Attributes
    ----------
    lost : str
        The sensor that failed.
    inputs : tuple of str
        The fallback's inputs on all training campaigns (the champion's minus ``lost``); empty
        when nothing is left.
    estimator : RegressorMixin or None
        Fitted on all training campaigns on ``inputs`` (what the runtime switches to); None
        without a fallback model.
    heldout_rms_um : float, um
        Mean over the held-out campaigns of the per-campaign RMS of its residual (NaN without
        a fallback model or a held-out unit).
    champion_rms_um : float, um
        The same for the champion, on the same (unit, campaign) pairs.
    none_rms_um : float, um
        The same for no compensation (the thermal error itself), on the fallback's samples.
    n_campaigns : int
        Held-out campaigns scored.
    inputs_rule : str
        ``unit_selection`` (each held-out unit's own selection minus ``lost``),
        ``pooled_inputs`` (the champion's pooled inputs minus ``lost``: a small leak) or
        ``mixed``.
    note : str
        What the runtime does with it, in a sentence.
    """

    lost: str
    inputs: tuple[str, ...]
    estimator: RegressorMixin | None = field(repr=False)
    heldout_rms_um: float
    champion_rms_um: float
    none_rms_um: float
    n_campaigns: int
    inputs_rule: str
    note: str


def temperature_inputs(inputs: Sequence[str]) -> list[str]:
    """Return the temperature sensors among model inputs (not the speed responses)."""
    return [name for name in inputs if not is_speed_feature(name)]


def speed_inputs(inputs: Sequence[str]) -> list[str]:
    """Return the speed responses among model inputs (free: computed from the spindle speed)."""
    return [name for name in inputs if is_speed_feature(name)]


def heldout_units(units: Sequence[TrainingUnit], scheme: str | None) -> list[TrainingUnit]:
    """Return the units of the ranking scheme (``loso``, ``loco`` or ``forward``)."""
    return [unit for unit in units if scheme is not None and unit.scheme == scheme]


def pooled_unit(units: Sequence[TrainingUnit], series: Sequence[CampaignSeries]) -> TrainingUnit:
    """Return the ``all_training`` unit (built from the training campaigns when not listed)."""
    found = next((unit for unit in units if unit.scheme == POOLED), None)
    training = tuple(s.campaign_id for s in series if s.split == "train")
    return found or TrainingUnit(POOLED_UNIT, POOLED, training)


def offered_sensors(series: Sequence[CampaignSeries]) -> list[str]:
    """Return every temperature sensor the campaigns carry, in natural order (T2 before T10)."""
    names = {str(c) for item in series for c in item.features.columns}
    return natural_sorted(temperature_inputs(sorted(names)))


def budget_size(n_offered: int, n_champion: int, max_k: int | None = None) -> int:
    """Largest k of the budget: the sensors offered, capped (module docstring)."""
    cap = max_k if max_k is not None else min(MAX_K, n_champion + EXTRA_K)
    return max(0, min(n_offered, cap))


def unit_selections(
    selected: Mapping | None, axis: str, selection: str
) -> Mapping[str, Mapping] | None:
    """Return ``{unit: {"inputs": [...]}}`` of one axis and selection method, if available.

    Parameters
    ----------
    selected : mapping or None
        ``reports/selection/selected.json`` as read, or its ``axes`` entry
        (``selected[axis][selection][unit]["inputs"]``).
    axis, selection : str
    """
    if not selected:
        return None
    axes = selected["axes"] if "axes" in selected and axis not in selected else selected
    return (axes.get(axis) or {}).get(selection) or None


def unit_inputs(
    card: Mapping, unit: TrainingUnit, by_unit: Mapping[str, Mapping] | None
) -> tuple[list[str], str]:
    """Return a unit's inputs (its own selection, else the champion's pooled ones) and the rule."""
    if by_unit is not None and unit.name in by_unit:
        return list(by_unit[unit.name]["inputs"]), UNIT_SELECTION
    return list(card["inputs"]), POOLED_INPUTS


def _rule(rules: set[str]) -> str:
    return rules.pop() if len(rules) == 1 else ("mixed" if rules else POOLED_INPUTS)


def refittable(card: Mapping) -> bool:
    """Whether the champion's family can be refitted on other inputs.

    False for ``none``, for the models on the error series alone and for models outside the
    registry (the physical twin, logged).
    """
    model = card["model"]
    if model not in MODELS:
        LOGGER.warning(
            "axis %s: champion '%s' is not a registered model; no fallback or sensor budget is "
            "fitted for it",
            card.get("axis"),
            model,
        )
        return False
    return MODELS[model].uses_temperatures


def _scored_campaigns(series: Sequence[CampaignSeries], unit: TrainingUnit) -> list:
    """Return the unit's training campaigns and, for a held-out unit, the ones it scores."""
    if unit.scheme == POOLED:
        return [s for s in series if s.campaign_id in unit.campaigns]
    return [
        s
        for s in series
        if s.campaign_id in unit.campaigns or (s.split == "train" and unit.scores(s.campaign_id))
    ]


def _run_fits(
    card: Mapping,
    model_params: Mapping[str, Mapping],
    series: Sequence[CampaignSeries],
    plan: Sequence[tuple[object, TrainingUnit, list[str]]],
    n_jobs: int,
    label: str = "refits",
) -> dict[tuple[object, str], UnitResult]:
    """Fit the champion's family on each (key, unit, inputs) of the plan, in parallel.

    How far they are is shown under ``label`` (:func:`pipeline.progress.run_jobs`).

    Returns
    -------
    dict
        ``(key, unit name)`` -> the fit and its scores (:func:`fit_and_score`).
    """
    model = card["model"]
    candidate = Candidate(model, str(card.get("selection", "")))
    params = dict(model_params.get(model) or {})
    jobs = [
        delayed(fit_and_score)(
            candidate, unit, _scored_campaigns(series, unit), make_model(model, **params), inputs
        )
        for _, unit, inputs in plan
    ]
    # One BLAS thread per process, as pipeline.protocol.candidates.run_all.
    with threadpool_limits(limits=1):
        results = run_jobs(jobs, n_jobs, label, logger=LOGGER)
    return {(key, unit.name): result for (key, unit, _), result in zip(plan, results, strict=True)}


def heldout_score(
    results: Sequence[UnitResult], mode: str, pairs: set[tuple[str, str]] | None = None
) -> dict:
    """Held-out scores of fits: the ``Mn_rms_um`` statistic and no compensation beside it.

    Parameters
    ----------
    results : sequence of UnitResult
        Fits on held-out units.
    mode : str
        Scoring mode of the champion (``static``, ``one_step`` or ``free_run``).
    pairs : set of (unit, campaign), optional
        Keep only these (training unit, test campaign) pairs.

    Returns
    -------
    dict
        ``heldout_rms_um`` (mean over the held-out campaigns of the per-campaign RMS, um),
        ``none_rms_um`` (the same for the error itself on the same samples, um), ``eta``,
        ``n_campaigns`` and ``pairs`` (the scored (unit, campaign) pairs).
    """
    frames = [r.scores for r in results if len(r.scores)]
    rows = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    if len(rows):
        rows = rows[(rows["mode"] == mode) & (rows["role"] == "prediction")]
        rows = rows[rows["rmse_um"].notna()]
    if len(rows) and pairs is not None:
        keep = [
            pair in pairs for pair in zip(rows["train_unit"], rows["test_campaign"], strict=True)
        ]
        rows = rows[np.array(keep, dtype=bool)]
    if not len(rows):
        nan = float("nan")
        return {
            "heldout_rms_um": nan,
            "none_rms_um": nan,
            "eta": nan,
            "n_campaigns": 0,
            "pairs": set(),
        }
    rms = summarise(rows)["Mn_rms_um"]
    none = float(rows["uncompensated_rms_um"].mean())
    return {
        "heldout_rms_um": rms,
        "none_rms_um": none,
        "eta": compensation_ratio(rms, none),
        "n_campaigns": int(rows["test_campaign"].nunique()),
        "pairs": set(zip(rows["train_unit"], rows["test_campaign"], strict=True)),
    }


def _fallback_plan(
    card: Mapping, held: Sequence[TrainingUnit], pooled: TrainingUnit, by_unit
) -> tuple[list[tuple[object, TrainingUnit, list[str]]], str]:
    """Fits of the champion (key None) and of each fallback (key: the lost sensor)."""
    sensors = temperature_inputs(card["inputs"])
    kept = [lost for lost in sensors if [n for n in card["inputs"] if n != lost]]
    plan: list[tuple[object, TrainingUnit, list[str]]] = []
    rules = set()
    for unit in held:
        inputs, rule = unit_inputs(card, unit, by_unit)
        rules.add(rule)
        plan.append((None, unit, inputs))
        for lost in kept:
            reduced = [n for n in inputs if n != lost]
            if reduced:
                plan.append((lost, unit, reduced))
    plan += [(lost, pooled, [n for n in card["inputs"] if n != lost]) for lost in kept]
    return plan, _rule(rules)


def fallback_fits(
    series: Sequence[CampaignSeries],
    units: Sequence[TrainingUnit],
    card: Mapping,
    model_params: Mapping[str, Mapping],
    protocol_scheme: str | None,
    selected: Mapping | None = None,
    *,
    n_jobs: int = 1,
) -> list[Fallback]:
    """Fit and score the champion's family without each of its temperature sensors.

    Parameters
    ----------
    series : sequence of CampaignSeries
        The axis' campaigns (:func:`pipeline.protocol.units.series_by_axis`).
    units : sequence of TrainingUnit
        :func:`pipeline.protocol.units.training_units` of ``series``.
    card : mapping
        The champion's card (``data/models/champion/<axis>/champion.json``): ``model``,
        ``selection``, ``mode``, ``inputs``.
    model_params : mapping
        ``params.yaml`` ``evaluate.model_params`` (the champion's ``model_params.get(model)``).
    protocol_scheme : str or None
        The ranking scheme (card ``protocol``): ``loso``, ``loco`` or ``forward``.
    selected : mapping, optional
        ``reports/selection/selected.json`` (or its ``axes``): each held-out unit then uses its
        own selection minus the lost sensor (preferred); without it the champion's pooled
        inputs minus the lost sensor (a small leak, module docstring).
    n_jobs : int
        joblib worker processes.

    Returns
    -------
    list of Fallback
        One per temperature sensor of the champion, in its input order; empty for ``none``,
        for models on the error series alone and for a champion without temperature input.
    """
    if not refittable(card) or not temperature_inputs(card["inputs"]):
        return []
    axis = str(card.get("axis") or series[0].axis)
    by_unit = unit_selections(selected, axis, str(card["selection"]))
    held = heldout_units(units, protocol_scheme)
    plan, rule = _fallback_plan(card, held, pooled_unit(units, series), by_unit)
    fits = _run_fits(card, model_params, series, plan, n_jobs, f"axis {axis} fallback fits")
    names = {unit.name for unit in held}
    return [
        _fallback_of(lost, card, fits, names, rule) for lost in temperature_inputs(card["inputs"])
    ]


def _fallback_of(lost: str, card: Mapping, fits: Mapping, names: set[str], rule: str) -> Fallback:
    """Assemble one sensor's fallback from the fits of :func:`_fallback_plan`."""
    champion = [r for (key, _), r in fits.items() if key is None]
    pooled = fits.get((lost, POOLED_UNIT))
    if pooled is None:
        theirs = heldout_score(champion, card["mode"])
        return Fallback(
            lost=lost,
            inputs=(),
            estimator=None,
            heldout_rms_um=float("nan"),
            champion_rms_um=theirs["heldout_rms_um"],
            none_rms_um=theirs["none_rms_um"],
            n_campaigns=0,
            inputs_rule=rule,
            note=NO_FALLBACK,
        )
    mine = [r for (key, unit), r in fits.items() if key == lost and unit in names]
    ours = heldout_score(mine, card["mode"])
    theirs = heldout_score(champion, card["mode"], ours["pairs"])
    held_inputs = "each unit's own selection" if rule == UNIT_SELECTION else "pooled inputs"
    return Fallback(
        lost=lost,
        inputs=tuple(pooled.sensors),
        estimator=pooled.estimator,
        heldout_rms_um=ours["heldout_rms_um"],
        champion_rms_um=theirs["heldout_rms_um"],
        none_rms_um=ours["none_rms_um"],
        n_campaigns=ours["n_campaigns"],
        inputs_rule=rule,
        note=(
            f"without {lost} the runtime switches to {card['model']} on "
            f"{', '.join(pooled.sensors)}; held out on {held_inputs} minus {lost}"
        ),
    )


def residualise(
    rises: np.ndarray, error: np.ndarray, speed: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of the rises and the error on an intercept and the speed responses.

    The regression of the residual error on the residual rises has the coefficients and the RSS
    of the regression of the error on the rises, the speed responses and an intercept (Frisch and
    Waugh 1933; Lovell 1963).

    Parameters
    ----------
    rises : ndarray of shape (n, m), K
    error : ndarray of shape (n,), um
    speed : ndarray of shape (n, s), (krpm)^a; s may be 0

    Returns
    -------
    rises, error : ndarray of shape (n, m), K, and ndarray of shape (n,), um
    """
    design = np.column_stack([np.ones(len(error)), speed])
    stacked = np.column_stack([error, rises])
    coefficients, *_ = np.linalg.lstsq(design, stacked, rcond=None)
    residual = stacked - design @ coefficients
    return residual[:, 1:], residual[:, 0]


def unit_subsets(
    series: Sequence[CampaignSeries],
    unit: TrainingUnit,
    sensors: Sequence[str],
    speed: Sequence[str],
    max_k: int,
    max_exhaustive: int = MAX_EXHAUSTIVE,
) -> dict[int, tuple[str, ...]]:
    """Minimum-RSS subset of each size 1..max_k, chosen on the unit's training campaigns only.

    Parameters
    ----------
    series : sequence of CampaignSeries
    unit : TrainingUnit
        Only ``unit.campaigns`` are read.
    sensors : sequence of str
        Sensors offered; a sensor with no finite value in one of the unit's training campaigns,
        or constant on them, is not offered on this unit.
    speed : sequence of str
        Speed responses kept in every regression (partialled out first, :func:`residualise`).
    max_k : int
    max_exhaustive : int
        Above this many sensors the search is approximate
        (:func:`pipeline.selection.best_subset.best_subset`).

    Returns
    -------
    dict of int to tuple of str
        k -> the sensors of the minimum-RSS subset of size k, in natural order.
    """
    training = [s for s in series if s.campaign_id in unit.campaigns]
    usable = [
        name
        for name in sensors
        if all(np.isfinite(s.features[name].to_numpy(dtype=float)).any() for s in training)
    ]
    if not usable or max_k < 1:
        return {}
    X, y = stack(training, [*usable, *speed])
    usable = [name for name in usable if np.ptp(X[name].to_numpy(dtype=float)) > 0]
    if not usable:
        return {}
    rises, error = residualise(X[usable].to_numpy(), y, X[list(speed)].to_numpy())
    positions = [f"x{i}" for i in range(len(usable))]
    found = best_subset(
        pd.DataFrame(rises, columns=positions), error, max_exhaustive=max_exhaustive
    )
    best = found.evidence[found.evidence["status"] == "best of its size"]
    subsets = {}
    for size, joined in zip(best["n_sensors"], best["sensors"], strict=True):
        if int(size) <= max_k:
            chosen = {usable[positions.index(p)] for p in str(joined).split("+")}
            subsets[int(size)] = tuple(name for name in usable if name in chosen)
    return subsets


def _stability(choices: Mapping[str, Mapping], names: Sequence[str], k, reference) -> float:
    """Share of held-out units whose size-k choice is the reference set (NaN without units)."""
    if not names:
        return float("nan")
    return float(np.mean([set(choices[name].get(k, ())) == set(reference) for name in names]))


def _budget_choices(series, units, card, scheme, by_unit, max_k, n_jobs, max_exhaustive):
    """Per unit (all training first, then the held-out ones): speed inputs and subsets."""
    pooled, held = pooled_unit(units, series), heldout_units(units, scheme)
    champion_sensors = temperature_inputs(card["inputs"])
    offered = offered_sensors(series)
    top = budget_size(len(offered), len(champion_sensors), max_k)
    speed = {pooled.name: speed_inputs(card["inputs"])}
    speed |= {unit.name: speed_inputs(unit_inputs(card, unit, by_unit)[0]) for unit in held}
    jobs = [
        delayed(unit_subsets)(series, unit, offered, speed[unit.name], top, max_exhaustive)
        for unit in (pooled, *held)
    ]
    with threadpool_limits(limits=1):
        found = run_jobs(jobs, n_jobs, "sensor budget subsets", "units", LOGGER)
    return held, speed, dict(zip([pooled.name, *(u.name for u in held)], found, strict=True))


def sensor_budget(
    series: Sequence[CampaignSeries],
    units: Sequence[TrainingUnit],
    card: Mapping,
    model_params: Mapping[str, Mapping],
    protocol_scheme: str | None,
    selected: Mapping | None = None,
    *,
    max_k: int | None = None,
    n_jobs: int = 1,
    max_exhaustive: int = MAX_EXHAUSTIVE,
) -> pd.DataFrame:
    """Score held out the best model of the champion's family with k = 1..K sensors.

    Parameters
    ----------
    series, units, card, model_params, protocol_scheme, selected, n_jobs
        As for :func:`fallback_fits`.
    max_k : int, optional
        K; default the sensors offered capped at the champion's count + :data:`EXTRA_K` and
        at :data:`MAX_K`.
    max_exhaustive : int
        Sensors searched exhaustively per unit (:func:`unit_subsets`).

    Returns
    -------
    DataFrame
        Columns :data:`BUDGET_COLUMNS`: ``axis``, ``model``, ``scheme`` (the ranking scheme),
        ``choice`` (``min_rss``: k sensors chosen per unit by minimum RSS; ``champion``: the
        champion's own inputs, per unit as in :func:`fallback_fits`), ``k``, ``sensors``
        (comma-joined; the all-training choice), ``speed_inputs`` (the champion's, comma-joined),
        ``heldout_rms_um`` (mean over the held-out campaigns of the per-campaign RMS, um),
        ``none_rms_um`` (no compensation on the same samples, um), ``eta``, ``n_campaigns``
        and ``stability`` (share of held-out units whose choice equals the all-training one;
        NaN for the champion without per-unit selections). Empty (with its columns) for a
        champion that cannot be refitted on sensors (``none``, error-series models, the twin).
    """
    if not refittable(card):
        return pd.DataFrame(columns=BUDGET_COLUMNS)
    axis = str(card.get("axis") or series[0].axis)
    by_unit = unit_selections(selected, axis, str(card["selection"]))
    held, speed, choices = _budget_choices(
        series, units, card, protocol_scheme, by_unit, max_k, n_jobs, max_exhaustive
    )
    plan: list[tuple[object, TrainingUnit, list[str]]] = [
        (k, unit, [*subset, *speed[unit.name]])
        for unit in held
        for k, subset in choices[unit.name].items()
    ]
    plan += [(CHAMPION, unit, unit_inputs(card, unit, by_unit)[0]) for unit in held]
    fits = _run_fits(card, model_params, series, plan, n_jobs, f"axis {axis} sensor budget fits")
    return _budget_rows(axis, card, protocol_scheme, held, speed, choices, fits, by_unit)


def _budget_rows(axis, card, scheme, held, speed, choices, fits, by_unit) -> pd.DataFrame:
    """One row per k of the all-training and held-out choices, then the champion's row."""
    names = [unit.name for unit in held]
    own = {}
    for unit in held:
        sensors = temperature_inputs(unit_inputs(card, unit, by_unit)[0])
        own[unit.name] = {len(sensors): sensors}
    champion = temperature_inputs(card["inputs"])
    sizes = sorted({k for found in choices.values() for k in found})
    rows = []
    for key in [*sizes, CHAMPION]:
        if key == CHAMPION:
            sensors, k = champion, len(champion)
            stable = _stability(own, names, k, champion) if by_unit else float("nan")
        else:
            sensors, k = list(choices[POOLED_UNIT].get(key, ())), key
            stable = _stability(choices, names, key, sensors)
        score = heldout_score([r for (fit, _), r in fits.items() if fit == key], card["mode"])
        rows.append(
            {
                "axis": axis,
                "model": card["model"],
                "scheme": scheme,
                "choice": CHAMPION if key == CHAMPION else MIN_RSS,
                "k": k,
                "sensors": ",".join(sensors),
                "speed_inputs": ",".join(speed_inputs(card["inputs"])),
                "heldout_rms_um": score["heldout_rms_um"],
                "none_rms_um": score["none_rms_um"],
                "eta": compensation_ratio(score["heldout_rms_um"], score["none_rms_um"]),
                "n_campaigns": score["n_campaigns"],
                "stability": stable,
            }
        )
    return pd.DataFrame(rows, columns=BUDGET_COLUMNS)


def _tick_label(row: pd.Series) -> str:
    """``k``, then its sensors three to a line, then the stability."""
    sensors = str(row["sensors"]).split(",") if row["sensors"] else []
    lines = [",".join(sensors[i : i + 3]) for i in range(0, len(sensors), 3)]
    stable = row["stability"]
    share = f"{stable:.0%} of units" if np.isfinite(stable) else ""
    return "\n".join([f"k={int(row['k'])}", *lines, share]).strip()


def _draw_axis(fig: Figure, ax, table: pd.DataFrame) -> None:
    """One axis' budget curve, its no-compensation line and the champion's point."""
    budget = table[table["choice"] == MIN_RSS].sort_values("k")
    champion = table[table["choice"] == CHAMPION]
    ax.plot(
        budget["k"],
        budget["heldout_rms_um"],
        "o-",
        color="C0",
        label="best k sensors (min RSS on each unit's training campaigns)",
    )
    ax.plot(
        budget["k"],
        budget["none_rms_um"],
        "--",
        color="0.4",
        label="no compensation (same samples)",
    )
    if len(champion):
        row = champion.iloc[0]
        ax.plot(
            [row["k"]],
            [row["heldout_rms_um"]],
            "*",
            ms=15,
            color="C3",
            label=f"champion {row['model']} on {row['sensors'] or 'no sensor'}",
        )
    ax.set_xticks(budget["k"].to_numpy(), [_tick_label(r) for _, r in budget.iterrows()])
    ax.tick_params(axis="x", labelsize=7.5)
    ax.set_xlabel(
        "temperature sensors k (chosen on all training campaigns; share of held-out "
        "units choosing the same)"
    )
    ax.set_ylabel("held-out RMS of the residual (um)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    first = table.iloc[0]
    speed = f" + speed responses {first['speed_inputs']}" if first["speed_inputs"] else ""
    machine = f"machine {first['machine']}, " if "machine" in table else ""
    text = f"{machine}axis {first['axis']}: {first['model']}{speed}, held out by {first['scheme']}"
    width = ax.get_position().width * fig.get_figwidth()
    ax.set_title(
        wrap_text(fig, text, PANEL_TITLE_FONTSIZE, 0.9 * width), fontsize=PANEL_TITLE_FONTSIZE
    )


def _panel_names(table: pd.DataFrame) -> pd.Series:
    """Return each row's panel: its axis, after its machine when the table has one."""
    if not len(table):
        return pd.Series(dtype=object)
    if "machine" not in table:
        return table["axis"].astype(str)
    return table["machine"].astype(str) + " " + table["axis"].astype(str)


def budget_figure(table: pd.DataFrame, path: Path | str) -> Figure:
    """Draw the held-out RMS against k (one panel per machine and axis) and write it as a PNG.

    Parameters
    ----------
    table : DataFrame
        :func:`sensor_budget` (one or several axes, concatenated; with a ``machine`` column,
        of several machines).
    path : Path or str
        PNG written (parent folders created).

    Returns
    -------
    Figure
    """
    names = _panel_names(table)
    axes_names = list(dict.fromkeys(names)) if len(table) else []
    fig = new_figure(9.0, 1.0 + 4.6 * max(len(axes_names), 1))
    panels = fig.subplots(max(len(axes_names), 1), 1, squeeze=False)[:, 0]
    for ax, axis in zip(panels, axes_names, strict=False):
        _draw_axis(fig, ax, table[names == axis])
    if not axes_names:
        panels[0].set_axis_off()
        panels[0].text(0.5, 0.5, "no sensor budget: the champion uses no sensor", ha="center")
    title = "Sensor budget: held-out RMS of the champion's family with k temperature sensors"
    fig.suptitle(wrap_text(fig, title, TITLE_FONTSIZE), fontsize=TITLE_FONTSIZE)
    fig.canvas.draw()
    for ax, axis in zip(panels, axes_names, strict=False):
        n = max(int((names == axis).sum()) - 1, 1)
        fit_tick_labels(fig, ax.xaxis, ax.bbox.width / n)
    save_figure(fig, Path(path))
    return fig

"""What the MLflow UI must show for one pipeline execution, read from the store and the record.

:func:`read_store` copies what the store holds about the execution named in
``reports/mlflow_run.json`` (experiment, parent run, child runs with tags, metrics and
artifacts, each champion's registered version) into plain data;
:func:`make_plan` (pure) checks the tracking layout and decides, per axis, which runs the pages
must show and in which order:

- each child run has tags ``axis``, ``model``, ``selection``, ``mode`` (its name is
  ``<axis>/<model>/<selection>/<mode>``), ``eligible`` (``true``/``false``, with
  ``ineligible_reason`` when false), ``rank`` (``1``..``n`` among the eligible runs of its axis)
  and ``champion``; artifacts ``cross_season_rms.png`` and ``scores.json``;
- the parent run's tag ``ranked_by.<axis>`` names the metric the candidates are ranked by
  (ascending, e.g. ``loso_Mn_rms_um``, the mean held-out RMS in um), which every eligible child
  has;
- the experiment has a description (tag ``mlflow.note.content``); each axis' champion is
  registered with a description and the alias ``champion``.

Where a store lacks the layout (one written by an older ``track`` stage) the plan falls back to
what there is (all children of an axis, ordered by a held-out RMS metric) so that the pages can
still be looked at, and the missing items are problems.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pipeline.errors import InputDataError
from pipeline.paths import TRACKING_RECORD
from pipeline.tracking import records, views

DESCRIPTION_TAG = "mlflow.note.content"
PARENT_TAG = "mlflow.parentRunId"
RANKED_BY_TAG = "ranked_by."
KEY_TAGS = ("axis", "model", "selection", "mode")
LAYOUT_TAGS = (*KEY_TAGS, "eligible", "champion")
HEAT_MAP = records.HEATMAP
SCORES_TABLE = records.SCORES_TABLE
EVIDENCE = (HEAT_MAP, SCORES_TABLE)
# For the pages only, when the parent has no ranked_by.<axis> tag; the check still fails.
FALLBACK_METRICS = (
    "loso_Mn_rms_um",
    "forward_Mn_rms_um",
    "loco_Mn_rms_um",
    "loso.Mn_rms_um",
    "loco.Mn_rms_um",
)


@dataclass(frozen=True)
class Child:
    """One child run of the pipeline execution: id, name, tags, metrics (um), artifacts."""

    run_id: str
    name: str
    tags: Mapping[str, str]
    metrics: Mapping[str, float]
    artifacts: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Version:
    """A registered model version: name, version, description, aliases, source run id."""

    name: str
    version: str
    description: str
    aliases: tuple[str, ...]
    run_id: str | None


@dataclass(frozen=True)
class StoreView:
    """What the store holds about one pipeline execution (plain data, no MLflow objects)."""

    experiment_id: str
    experiment_name: str
    experiment_tags: Mapping[str, str]
    parent_run_id: str
    parent_tags: Mapping[str, str]
    children: tuple[Child, ...]
    versions: Mapping[str, Version | None]


@dataclass(frozen=True)
class AxisPlan:
    """What the pages of one axis must show.

    Attributes
    ----------
    axis : str
        Probe axis, e.g. ``"Z"``.
    metric : str or None
        The metric the candidates are ranked by, ascending (None when no child has one).
    listed : tuple of Child
        The runs of the run list: the axis' eligible children (all of its children in a store
        without ``eligible`` tags).
    ranked : tuple of Child
        The eligible children in rank order (by the metric in a store without ``rank`` tags).
    champion : Child or None
        The child tagged ``champion: true`` (else the one the record names).
    version : Version or None
        The champion's registered model version.
    search_filter : str
        The run list's filter (MLflow search syntax).
    has_rank : bool
        Whether the children carry ``rank`` tags.
    shared_view : str or None
        Share key of the axis' ranked view (:mod:`pipeline.tracking.views`), None if the
        experiment has none.
    """

    axis: str
    metric: str | None
    listed: tuple[Child, ...]
    ranked: tuple[Child, ...]
    champion: Child | None
    version: Version | None
    search_filter: str
    has_rank: bool
    shared_view: str | None = None


@dataclass(frozen=True)
class Plan:
    """The experiment and, per axis, what its pages must show."""

    experiment_id: str
    experiment_name: str
    description: str
    axes: tuple[AxisPlan, ...]


def _children(client: Any, experiment_id: str, parent_id: str) -> list[Child]:
    children, token = [], None
    while True:
        page = client.search_runs(
            [experiment_id],
            filter_string=f"tags.`{PARENT_TAG}` = '{parent_id}'",
            max_results=1000,
            page_token=token,
        )
        for run in page:
            evidence = client.list_artifacts(run.info.run_id)
            children.append(
                Child(
                    run.info.run_id,
                    run.info.run_name or "",
                    dict(run.data.tags),
                    dict(run.data.metrics),
                    frozenset(item.path for item in evidence),
                )
            )
        token = page.token
        if not token:
            return children


def _version(client: Any, card: Mapping[str, Any]) -> Version | None:
    from mlflow.exceptions import MlflowException

    if not (card.get("registered_model") and card.get("version")):
        return None
    try:
        found = client.get_model_version(card["registered_model"], str(card["version"]))
    except MlflowException:
        return None
    aliases = tuple(found.aliases or ())
    return Version(found.name, str(found.version), found.description or "", aliases, found.run_id)


def read_store(client: Any, record: Mapping[str, Any]) -> StoreView:
    """Read the pipeline execution named in ``record`` from the store.

    Parameters
    ----------
    client : mlflow.MlflowClient
        Client of the store (tracking and registry).
    record : mapping
        ``reports/mlflow_run.json``: ``experiment_id``, ``parent_run_id``, ``champions``.

    Returns
    -------
    StoreView
        The experiment, the parent's tags, every child run with its tags, metrics and
        artifacts, and each champion's registered version (None if absent).

    Raises
    ------
    InputDataError
        If the store has no such experiment or parent run.
    """
    from mlflow.exceptions import MlflowException

    experiment_id, parent_id = str(record["experiment_id"]), str(record["parent_run_id"])
    try:
        experiment = client.get_experiment(experiment_id)
        parent = client.get_run(parent_id)
    except MlflowException as error:
        raise InputDataError(
            f"the store has no experiment {experiment_id} or run {parent_id} named in "
            f"{TRACKING_RECORD} ({error.message}); the record and the store disagree: check "
            "MLFLOW_TRACKING_URI or rerun the track stage"
        ) from None
    children = sorted(_children(client, experiment_id, parent_id), key=lambda child: child.name)
    cards = record.get("champions") or {}
    return StoreView(
        experiment_id,
        experiment.name,
        dict(experiment.tags),
        parent_id,
        dict(parent.data.tags),
        tuple(children),
        {axis: _version(client, card) for axis, card in cards.items()},
    )


def _count(problem: str, runs: Sequence[Child], total: int) -> str:
    example = ", ".join(child.name for child in runs[:2])
    return f"{problem}: {len(runs)} of {total} child runs (e.g. {example})"


def rank_of(child: Child) -> int | None:
    """Return the child's ``rank`` tag as an integer, None when absent, empty or not a number."""
    value = child.tags.get("rank", "")
    return int(value) if value.isdigit() else None


def layout_problems(view: StoreView) -> list[str]:
    """Return the problems of the layout common to every axis (pure).

    The experiment's description; the child runs' tags, names and evidence artifacts.
    """
    problems = []
    if not view.experiment_tags.get(DESCRIPTION_TAG, "").strip():
        problems.append(
            f"store: experiment '{view.experiment_name}' has no description (tag {DESCRIPTION_TAG})"
        )
    children = view.children
    if not children:
        return [*problems, f"store: parent run {view.parent_run_id} has no child runs"]
    total = len(children)
    for tag in LAYOUT_TAGS:
        lacking = [child for child in children if not child.tags.get(tag)]
        if lacking:
            problems.append(_count(f"store: tag '{tag}' missing", lacking, total))
    if not any("rank" in child.tags for child in children):
        problems.append(_count("store: tag 'rank' missing", children, total))
    misnamed = [
        child
        for child in children
        if all(child.tags.get(tag) for tag in KEY_TAGS)
        and child.name != "/".join(child.tags[tag] for tag in KEY_TAGS)
    ]
    if misnamed:
        problems.append(
            _count("store: run name is not <axis>/<model>/<selection>/<mode>", misnamed, total)
        )
    no_reason = [
        child
        for child in children
        if child.tags.get("eligible") == "false" and not child.tags.get("ineligible_reason")
    ]
    if no_reason:
        problems.append(_count("store: tag 'ineligible_reason' missing", no_reason, total))
    for artifact in EVIDENCE:
        lacking = [child for child in children if artifact not in child.artifacts]
        if lacking:
            problems.append(_count(f"store: artifact {artifact} missing", lacking, total))
    return problems


def _ranking(
    axis: str, listed: Sequence[Child], metric: str | None
) -> tuple[list[Child], list[str]]:
    """Order the eligible runs by their rank (else by the metric); check ranks and values."""
    problems = []
    if metric:
        lacking = [child for child in listed if metric not in child.metrics]
        if lacking:
            problems.append(
                _count(f"store: metric {metric} missing (axis {axis})", lacking, len(listed))
            )
    if any(rank_of(child) is not None for child in listed):
        ranked = sorted((c for c in listed if rank_of(c) is not None), key=lambda c: rank_of(c))
        ranks = [rank_of(child) for child in ranked]
        if ranks != list(range(1, len(listed) + 1)):
            problems.append(
                f"store: the ranks of the {len(listed)} eligible runs of axis {axis} are "
                f"{ranks}, not 1..{len(listed)}"
            )
    elif metric:
        ranked = sorted((c for c in listed if metric in c.metrics), key=lambda c: c.metrics[metric])
    else:
        ranked = []
    pairs = [(child, child.metrics.get(metric)) for child in ranked] if metric else []
    for (better, value), (worse, next_value) in zip(pairs, pairs[1:], strict=False):
        if value is not None and next_value is not None and value > next_value:
            problems.append(
                f"store: axis {axis}: {better.name} ranks before {worse.name} but its {metric} "
                f"{value:g} is larger than {next_value:g}"
            )
    return ranked, problems


def _champion(
    axis: str, children: Sequence[Child], card: Mapping[str, Any], parent_id: str
) -> tuple[Child | None, list[str]]:
    """Return the champion's child run; problems if its tags and the record disagree."""
    problems = []
    tagged = [child for child in children if child.tags.get("champion") == "true"]
    expected = f"{axis}/{card['model']}" if card.get("model") else None
    if len(tagged) != 1:
        problems.append(
            f"store: axis {axis} has {len(tagged)} child runs tagged champion=true, expected one"
        )
    champion = tagged[0] if len(tagged) == 1 else None
    if not card:
        problems.append(f"record: no champion of axis {axis} in {TRACKING_RECORD}")
    elif expected not in {child.name for child in children}:
        problems.append(
            f"record: the champion {expected} of axis {axis} in {TRACKING_RECORD} is not a "
            f"child run of parent {parent_id}"
        )
    elif champion is not None and champion.name != expected:
        problems.append(
            f"record: the champion of axis {axis} is {expected} in {TRACKING_RECORD} but "
            f"{champion.name} in the store"
        )
    if champion is None and expected:
        champion = next((child for child in children if child.name == expected), None)
    return champion, problems


def _version_problems(
    axis: str, version: Version | None, card: Mapping[str, Any], champion: Child | None
) -> list[str]:
    if not card:
        return []
    if version is None:
        return [
            f"store: no registered model version {card.get('registered_model')} "
            f"v{card.get('version')} (the champion of axis {axis} in {TRACKING_RECORD})"
        ]
    problems = []
    label = f"store: {version.name} v{version.version}"
    if "champion" not in version.aliases:
        problems.append(f"{label} lacks the alias 'champion'")
    if not version.description.strip():
        problems.append(f"{label} has no description")
    if champion is not None and version.run_id != champion.run_id:
        problems.append(
            f"{label} comes from run {version.run_id}, not from the champion's child run "
            f"{champion.name} ({champion.run_id})"
        )
    return problems


def axis_plan(axis: str, view: StoreView, record: Mapping[str, Any]) -> tuple[AxisPlan, list[str]]:
    """Decide what the pages of ``axis`` must show; list its problems (pure).

    Parameters
    ----------
    axis : str
        Probe axis.
    view : StoreView
        What the store holds.
    record : mapping
        ``reports/mlflow_run.json``.

    Returns
    -------
    AxisPlan
        The axis' runs, ranking, champion and version, with fallbacks for an older layout.
    list of str
        One line per problem.
    """
    problems: list[str] = []
    children = [child for child in view.children if child.tags.get("axis") == axis] or [
        child for child in view.children if child.name.split("/", 1)[0] == axis
    ]
    metric = view.parent_tags.get(f"{RANKED_BY_TAG}{axis}")
    if not metric:
        problems.append(
            f"store: parent run {view.parent_run_id} has no tag {RANKED_BY_TAG}{axis} (the "
            f"metric the candidates of axis {axis} are ranked by)"
        )
        metric = next((m for m in FALLBACK_METRICS if any(m in c.metrics for c in children)), None)
    has_eligible = any("eligible" in child.tags for child in children)
    listed = [c for c in children if c.tags.get("eligible") == "true"] if has_eligible else children
    if has_eligible and not listed:
        problems.append(f"store: no child run of axis {axis} is tagged eligible=true")
    ranked, ranking_problems = _ranking(axis, listed, metric)
    card = (record.get("champions") or {}).get(axis) or {}
    champion, champion_problems = _champion(axis, children, card, view.parent_run_id)
    version = view.versions.get(axis)
    problems += ranking_problems + champion_problems
    problems += _version_problems(axis, version, card, champion)
    search = f"tags.`{PARENT_TAG}` = '{view.parent_run_id}' and tags.axis = '{axis}'"
    if has_eligible:
        search += " and tags.eligible = 'true'"
    has_rank = any(rank_of(child) is not None for child in listed)
    key = views.view_key("ranked", record.get("machine", ""), axis)
    shared = key if f"{views.SHARED_VIEW_TAG}{key}" in view.experiment_tags else None
    if shared is None:
        problems.append(
            f"store: experiment has no shared view {key} (tag {views.SHARED_VIEW_TAG}{key}): "
            "the run list cannot open with the scores as columns"
        )
    plan = AxisPlan(
        axis, metric, tuple(listed), tuple(ranked), champion, version, search, has_rank, shared
    )
    return plan, problems


def make_plan(view: StoreView, record: Mapping[str, Any]) -> tuple[Plan, list[str]]:
    """Decide what each page must show; list the store's and the record's problems (pure).

    Parameters
    ----------
    view : StoreView
        What the store holds.
    record : mapping
        ``reports/mlflow_run.json``.

    Returns
    -------
    Plan
        The pages' expectations, with fallbacks where the store lacks the layout.
    list of str
        One line per problem, prefixed ``store:`` or ``record:``.
    """
    problems = layout_problems(view)
    if record.get("experiment") and record["experiment"] != view.experiment_name:
        problems.append(
            f"record: experiment '{record['experiment']}' in {TRACKING_RECORD} but "
            f"'{view.experiment_name}' in the store"
        )
    axes = sorted(
        set(record.get("champions") or {})
        | {child.tags["axis"] for child in view.children if child.tags.get("axis")}
    )
    if not axes:
        problems.append(f"record: no champion in {TRACKING_RECORD} and no axis tag in the store")
    plans = []
    for axis in axes:
        plan, axis_problems = axis_plan(axis, view, record)
        plans.append(plan)
        problems += axis_problems
    description = view.experiment_tags.get(DESCRIPTION_TAG, "")
    return Plan(view.experiment_id, view.experiment_name, description, tuple(plans)), problems

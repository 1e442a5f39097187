"""An axis' champion as an MLflow pyfunc model, logged from its child run and registered.

The registered version is the *challenger*: the promotion gate (:mod:`pipeline.tracking.promotion`)
decides whether it takes the alias ``champion``.

``mlflow.pyfunc.load_model("models:/thermal-error-spindle-<axis>@champion").predict(table)``
takes a table as the machine logs it -- one column per input sensor in degC, rows in time order,
``rpm`` and ``elapsed_s`` when the model uses speed responses (``elapsed_s`` also lets a fast
logger's rows be averaged into the training windows), optional ``campaign_id`` for several runs
(each group is a run from its own first row) -- and returns the predicted thermal error (um) per
row, NaN where an input is missing. The inputs are prepared by :mod:`pipeline.protocol.serving`
from the card's ``input_spec``, the same code that prepared them in training: rises from each run's
first row (or the mean of its first rows), the speed responses from rest at each run's start. The
signature says which columns are required (``rpm`` and ``elapsed_s`` only when the model needs
the speed log). The estimator is the candidate's fit on all training campaigns; models on the
error's own history predict in free run; the champion ``none`` predicts zero (do not
compensate). The model carries the package modules its loading imports
(:mod:`pipeline.tracking.model_code`), so it loads where the repository is not installed.
"""

from __future__ import annotations

import json
import logging
import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import joblib
import mlflow
import pandas as pd
from mlflow.models import ModelSignature
from mlflow.tracking import MlflowClient
from mlflow.types.schema import ColSpec, Schema

from pipeline import paths
from pipeline.errors import MissingInputError
from pipeline.machines import machine_key
from pipeline.protocol.serving import predict_table
from pipeline.separation.features import InputSpec
from pipeline.tracking.model_code import write_model_code

logger = logging.getLogger(__name__)

MODEL_NAME = "model"
BUNDLE_ARTIFACTS = "compensation/bundle"
"""Artifacts of the champion's run: the compensation runtime's bundle of the axis."""
REPORT_ARTIFACTS = "compensation/report"
"""Artifacts of the champion's run: controller exports, the replay proof and its figures."""
TRACKING_URI_ENV = "MLFLOW_TRACKING_URI"
REQUIREMENTS = (
    "numpy==2.4.6",
    "pandas==3.1.1",
    "scikit-learn==1.9.1",
    "scipy==1.17.1",
    "statsmodels==0.15.0",
    "joblib==1.6.0",
)


@contextmanager
def import_path_kept() -> Iterator[None]:
    """Restore ``sys.path`` after MLflow loaded or logged a model in this process.

    Loading a pyfunc model (logging one with an input example loads it too) puts the model's
    ``code`` folder first on ``sys.path``. This process has the package already; worker
    processes it starts later must import the package from where it is installed, not the
    modules a model carries.
    """
    import_path = list(sys.path)
    try:
        yield
    finally:
        sys.path[:] = import_path


class ChampionModel(mlflow.pyfunc.PythonModel):
    """Predict the thermal error (um) from a table of the machine's inputs."""

    def load_context(self, context) -> None:
        """Load the fitted estimator and its card from the model's artifacts."""
        self.estimator = joblib.load(context.artifacts["estimator"])
        self.card = json.loads(Path(context.artifacts["card"]).read_text(encoding="utf-8"))

    def predict(self, context, model_input: pd.DataFrame, params=None) -> pd.Series:
        """Thermal error, um, one value per row of ``model_input`` (NaN: an input is missing)."""
        spec = InputSpec.from_dict(self.card["input_spec"])
        predicted = predict_table(self.estimator, pd.DataFrame(model_input), spec)
        return pd.Series(predicted, index=model_input.index, name="thermal_error_um")


def signature(spec: InputSpec) -> ModelSignature:
    """Input and output schema: the sensors (degC), ``rpm`` and ``elapsed_s`` when needed."""
    columns = [ColSpec("double", name) for name in spec.sensors]
    columns += [
        ColSpec("double", "rpm", required=spec.needs_speed),
        ColSpec("double", "elapsed_s", required=spec.needs_speed),
        ColSpec("string", "campaign_id", required=False),
    ]
    return ModelSignature(Schema(columns), Schema([ColSpec("double", "thermal_error_um")]))


def description(card: dict) -> str:
    """Model-version description: inputs, decision, protocol and scores, in words."""
    spec = InputSpec.from_dict(card["input_spec"])
    scores = card.get("scores") or {}
    protocol = card.get("protocol")
    held_out = scores.get(f"{protocol}_Mn_rms_um") if protocol else None
    lines = [
        f"Axis {card['axis']}: {card['model']}/{card['selection']}/{card['mode']}, fitted on "
        f"{len(card['trained_on'])} training campaign(s).",
        "Compensate: "
        + ("yes. " if card["compensate"] else "NO (predicts zero). ")
        + str(card["reason"])
        + ".",
        f"Inputs: {', '.join(spec.inputs) or 'none'}"
        + ("; needs the table's rpm and elapsed_s (speed log)." if spec.needs_speed else "."),
        f"Reference: {spec.reference} of each run ({spec.features}).",
        f"Chosen on {card.get('protocol_name')}: held-out RMS {held_out} um "
        f"(`{card.get('chosen_on')}`) against {card.get('none_score_um')} um without "
        f"compensation (eta {scores.get(f'{protocol}_eta') if protocol else None}).",
        f"Validation RMS (all-training fit): {scores.get('pooled_Mn_val_rms_um')} um "
        f"(`pooled_Mn_val_rms_um`, eta {scores.get('pooled_eta_val')}).",
        f"Trained on: {', '.join(card.get('trained_on') or [])}.",
    ]
    return "\n".join(lines)


def model_description(card: dict) -> str:
    """Registered-model description: what the model is and which version to use."""
    return (
        f"Thermal error of the spindle along {card['axis']} (um), predicted from the machine's "
        "own temperature sensors (degC) and spindle speed. Each `dvc repro` registers the "
        "champion of its candidates as a new version, logged from that candidate's child run "
        "in the `thermal-error` experiment. The alias `champion` points at the one the machine "
        "runs, moved only by the promotion gate when a new version proves better on campaigns "
        "the champion never saw (`previous`: the one before; `challenger`: the latest kept "
        "out; tags `gate` and `gate_reason` say why): "
        f"`mlflow.pyfunc.load_model('models:/<this model>@champion')`. Read a version's "
        "description for its inputs, protocol and held-out scores."
    )


def log_and_register(tracking_uri: str, run_id: str, registered_name: str, folder: Path) -> str:
    """Log an axis' champion to its child run ``run_id`` and register it (no alias: the gate's).

    Parameters
    ----------
    tracking_uri : str
    run_id : str
        The champion candidate's child run (still running).
    registered_name : str
        E.g. ``thermal-error-spindle-Z``.
    folder : Path
        ``data/models/champion/<axis>/`` (estimator, card, input example).

    Returns
    -------
    str
        The registered model version.
    """
    card_path = folder / paths.CHAMPION_CARD_FILE
    card = json.loads(card_path.read_text(encoding="utf-8"))
    spec = InputSpec.from_dict(card["input_spec"])
    example_path = folder / paths.CHAMPION_EXAMPLE_FILE
    example = pd.read_csv(example_path) if example_path.is_file() else None
    previous_uri = os.environ.get(TRACKING_URI_ENV)
    mlflow.set_tracking_uri(tracking_uri)
    # Not ``with start_run``: leaving the block would mark the child run FINISHED before its
    # metrics are logged; the run is handed back still RUNNING.
    mlflow.start_run(run_id=run_id)
    try:
        estimator = joblib.load(folder / paths.CHAMPION_ESTIMATOR_FILE)
        with tempfile.TemporaryDirectory() as scratch, import_path_kept():
            info = mlflow.pyfunc.log_model(
                name=MODEL_NAME,
                python_model=ChampionModel(),
                artifacts={
                    "estimator": str(folder / paths.CHAMPION_ESTIMATOR_FILE),
                    "card": str(card_path),
                },
                code_paths=[str(write_model_code(estimator, Path(scratch)))],
                pip_requirements=list(REQUIREMENTS),
                signature=signature(spec),
                input_example=example,
                registered_model_name=registered_name,
            )
        log_compensation(card["machine"], card["axis"])
    finally:
        mlflow.end_run(status="RUNNING")
        # set_tracking_uri also sets the environment variable: restore the caller's.
        mlflow.set_tracking_uri(previous_uri)
    version = str(info.registered_model_version)
    client = MlflowClient(tracking_uri=tracking_uri)
    client.update_model_version(registered_name, version, description=description(card))
    client.update_registered_model(registered_name, description=model_description(card))
    tags = {
        "machine": card["machine"],
        "axis": card["axis"],
        "model": card["model"],
        "selection": card["selection"],
        "mode": card["mode"],
        "compensate": str(card["compensate"]).lower(),
        "protocol": str(card.get("protocol")),
        "needs_speed_log": str(spec.needs_speed).lower(),
        "inputs": ",".join(spec.inputs) or "-",
        "ranked_by": str(card.get("chosen_on")),
        "trained_on": ",".join(card.get("trained_on") or []) or "-",
    }
    for key, value in tags.items():
        client.set_model_version_tag(registered_name, version, key, value)
    for key in ("machine", "axis"):
        client.set_registered_model_tag(registered_name, key, card[key])
    logger.info("registered %s version %s", registered_name, version)
    return version


def log_compensation(machine: str, axis: str) -> None:
    """Log the machine's axis' compensation bundle, exports and replay proof to the active run.

    The bundle (``data/models/compensation/<machine>/<axis>/``) goes to ``compensation/bundle``
    (what ``thermal compensate --registry`` loads), the reports
    (``reports/compensation/<machine>/<axis>/``) to ``compensation/report``, and the replay's
    means as metrics ``replay.<name>`` (um; ``ratio`` is the replayed over the offline held-out
    RMS). Nothing is logged for a part not written.
    """
    bundle = paths.COMPENSATION_BUNDLES / machine_key(machine) / axis
    if bundle.is_dir():
        mlflow.log_artifacts(str(bundle), BUNDLE_ARTIFACTS)
    report = paths.COMPENSATION_REPORTS / machine_key(machine) / axis
    if report.is_dir():
        mlflow.log_artifacts(str(report), REPORT_ARTIFACTS)
    if paths.COMPENSATION_SUMMARY.is_file():
        document = json.loads(paths.COMPENSATION_SUMMARY.read_text(encoding="utf-8"))
        entry = (document.get("machines") or {}).get(machine) or {}
        proof = (entry.get("axes", {}).get(axis) or {}).get("proof") or {}
        metrics = {
            f"replay.{name}": float(value)
            for name, value in proof.items()
            if isinstance(value, int | float) and value == value
        }
        if metrics:
            mlflow.log_metrics(metrics)


def registered_targets(tracking_uri: str, prefix: str) -> list[tuple[str, str, str]]:
    """Every machine and axis with a registered model ``<prefix>-<machine>-<axis>``, sorted.

    Returns
    -------
    list of (str, str, str)
        ``(machine, axis, registered name)``, from the registered model's tags ``machine`` and
        ``axis``.
    """
    client = MlflowClient(tracking_uri=tracking_uri)
    models = client.search_registered_models(filter_string=f"name LIKE '{prefix}-%'")
    return sorted(
        (m.tags["machine"], m.tags["axis"], m.name)
        for m in models
        if "machine" in m.tags and "axis" in m.tags
    )


def download_bundle(tracking_uri: str, registered_name: str, alias: str, dest: Path) -> Path:
    """Download the compensation bundle of the version ``registered_name@alias``.

    Returns
    -------
    Path
        The local folder of the bundle (``bundle.json`` and the estimators).

    Raises
    ------
    MissingInputError
        When the registry has no such alias, or its run logged no bundle.
    """
    client = MlflowClient(tracking_uri=tracking_uri)
    try:
        version = client.get_model_version_by_alias(registered_name, alias)
    except mlflow.exceptions.MlflowException as error:
        raise MissingInputError(
            f"{tracking_uri}: no version of {registered_name} with alias '{alias}' ({error}); "
            "run `dvc repro` (track registers it) or check MLFLOW_TRACKING_URI"
        ) from None
    try:
        folder = mlflow.artifacts.download_artifacts(
            run_id=version.run_id,
            artifact_path=BUNDLE_ARTIFACTS,
            dst_path=str(dest),
            tracking_uri=tracking_uri,
        )
    except (OSError, mlflow.exceptions.MlflowException) as error:
        raise MissingInputError(
            f"{registered_name} version {version.version} (run {version.run_id}) has no "
            f"{BUNDLE_ARTIFACTS} artifacts ({error}); it was registered before the compensation "
            "stage existed: give --bundle DIR, or --alias challenger (the latest version has one)"
        ) from None
    return Path(folder)

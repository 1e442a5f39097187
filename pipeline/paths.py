"""Where each stage reads and writes, relative to the repository root.

``dvc.yaml`` declares the same paths as stage ``deps``/``outs``; ``tests/test_dvc_paths.py``
fails when one side names an output the other does not.
"""

from pathlib import Path

RAW = Path("data/raw")

INGESTED = Path("data/ingested")
INGESTED_CAMPAIGNS = INGESTED / "campaigns.parquet"
INGESTED_SAMPLES = INGESTED / "samples.parquet"
INGESTED_LASER = INGESTED / "laser.parquet"
INGESTED_PROBLEMS = INGESTED / "problems.parquet"

VALIDATED = Path("data/validated")
VALIDATED_SPINDLE = VALIDATED / "spindle"
VALIDATED_AXIS = VALIDATED / "axis"
CAMPAIGNS_FILE = "campaigns.parquet"
SAMPLES_FILE = "samples.parquet"
LASER_FILE = "laser.parquet"

SEPARATED = Path("data/separated")
SPINDLE_THERMAL_ERROR = SEPARATED / "spindle_thermal_error.parquet"
SPINDLE_RUNS = SEPARATED / "spindle_runs.json"
AXIS_GEOMETRIC = SEPARATED / "axis_geometric.parquet"
AXIS_THERMAL_ERROR = SEPARATED / "axis_thermal_error.parquet"
AXIS_SLOPES = SEPARATED / "axis_slopes.parquet"

MODELS = Path("data/models")
CHAMPION = MODELS / "champion"
"""One folder per machine and displacement axis: ``<machine>/<axis>/estimator.joblib``,
``champion.json``, ``input_example.csv``, ``heldout.parquet``."""
CHAMPION_ESTIMATOR_FILE = "estimator.joblib"
CHAMPION_CARD_FILE = "champion.json"
CHAMPION_EXAMPLE_FILE = "input_example.csv"
CHAMPION_HELDOUT_FILE = "heldout.parquet"
"""The champion's prediction of each campaign by a fit that did not see it (the promotion gate)."""

REPORTS = Path("reports")
VALIDATION_REPORT = REPORTS / "validation.json"
SEPARATION_PLOTS = REPORTS / "separation"
SELECTION = REPORTS / "selection"
SELECTED = SELECTION / "selected.json"
SELECTION_STABILITY = SELECTION / "stability.csv"
SCORES_LONG = REPORTS / "cross_season_scores.csv"
CANDIDATE_SCORES = REPORTS / "model_scores.csv"
GROUP_SCORES = REPORTS / "heldout_scores.csv"
"""Scores per held-out season (or campaign) and validation season (``scoring.group_scores``)."""
MATRIX_CSV = REPORTS / "cross_season_matrix.csv"
MATRICES = REPORTS / "matrices"
MODEL_COMPARISON = REPORTS / "model_comparison.md"
COMPARISON_FIGURES = REPORTS / "comparison"
PLOTS = REPORTS / "plots"
PLOT_MODEL_SCORES = PLOTS / "model_scores.csv"
PLOT_PREDICTIONS = PLOTS / "predicted_vs_measured.csv"
TRACKING_RECORD = REPORTS / "mlflow_run.json"
PROMOTION = REPORTS / "promotion"
"""The promotion gate's decision of the last ``track``: ``promotion.json`` and ``promotion.md``."""
PROMOTION_DECISION = PROMOTION / "promotion.json"
PROMOTION_REPORT = PROMOTION / "promotion.md"
DISCREPANCY = REPORTS / "discrepancy"
"""One folder per machine (``<machine>/``, the machine as ``pipeline.machines.machine_key``
writes it): ``discrepancy.json``, ``discrepancy.md``, the figures."""
DISCREPANCY_FILE = "discrepancy.json"
DISCREPANCY_RECORD = REPORTS / "discrepancy_run.json"
"""The discrepancy stage's MLflow run id of each machine (not cached by DVC: it changes every
execution)."""
DISCREPANCY_HISTORY = REPORTS / "discrepancy_history.json"
"""What the discrepancy stage's next run needs of this one, per machine (kept by DVC between
runs)."""


def discrepancy_document(machine_key: str) -> Path:
    """Return ``reports/discrepancy/<machine>/discrepancy.json``."""
    return DISCREPANCY / machine_key / DISCREPANCY_FILE


FIT_CACHE = Path(".thermal_cache")
"""Each machine's results of a stage, by the hash of their inputs (``pipeline.fit_cache``; not a
DVC output, git-ignored)."""

METRICS = Path("metrics")
CROSS_SEASON_METRICS = METRICS / "cross_season.json"
FITTED_MODELS = REPORTS / "fitted_models.json"

AXIS_MODEL_REPORT = REPORTS / "axis_model.json"
AXIS_MODEL_PLOTS = REPORTS / "axis_model"
"""One figure per machine: ``<machine>.png``."""
AXIS_MODEL_METRICS = METRICS / "axis_model.json"

COMPENSATION_BUNDLES = MODELS / "compensation"
"""One folder per axis: what ``thermal compensate`` loads (estimator, fallbacks, ranges)."""
HELDOUT_FITS_FILE = "heldout_fits.joblib"
"""In ``CHAMPION/<axis>/``: the champion's fits that left campaigns out, for the replay proof."""
COMPENSATION_REPORTS = REPORTS / "compensation"
"""Per axis: ``coefficients.json``, ``controller.json``, the replay proof and its figures."""
COMPENSATION_SUMMARY = COMPENSATION_REPORTS / "compensation.json"
COMPENSATION_REPORT = COMPENSATION_REPORTS / "compensation.md"
SENSOR_BUDGET = REPORTS / "sensor_budget.csv"
SENSOR_BUDGET_PLOT = REPORTS / "sensor_budget.png"
COMPENSATION_METRICS = METRICS / "compensation.json"

"""Where each stage reads and writes, relative to the repository root.

``dvc.yaml`` declares the same paths as stage ``deps``/``outs``; keep the two in step.
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
AXIS_GEOMETRIC = SEPARATED / "axis_geometric.parquet"
AXIS_THERMAL_ERROR = SEPARATED / "axis_thermal_error.parquet"
AXIS_SLOPES = SEPARATED / "axis_slopes.parquet"

REPORTS = Path("reports")
VALIDATION_REPORT = REPORTS / "validation.json"
SEPARATION_PLOTS = REPORTS / "separation"
SCORES_LONG = REPORTS / "cross_season_scores.csv"
MATRIX_CSV = REPORTS / "cross_season_matrix.csv"
MATRIX_PNG = REPORTS / "cross_season_matrix.png"
PLOTS = REPORTS / "plots"
PLOT_SCORES_BY_TRAIN = PLOTS / "scores_by_train_campaign.csv"
PLOT_PREDICTIONS = PLOTS / "predicted_vs_measured.csv"
TRACKING_RECORD = REPORTS / "mlflow_run.json"

METRICS = Path("metrics")
CROSS_SEASON_METRICS = METRICS / "cross_season.json"
FITTED_MODELS = REPORTS / "fitted_models.json"

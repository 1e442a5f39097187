"""Load a logged champion in a Python that cannot import the repository's ``pipeline``.

The test environment installs the package in editable mode (a finder on ``sys.meta_path``) and
runs from the repository (its root on ``sys.path``). The script below removes both before MLflow
loads the model, so the only ``pipeline`` it can import is the one the model carries in its
``code`` folder: what a machine that never cloned the repository gets.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import json, sys
root = sys.argv[1]
sys.path = [p for p in sys.path if p.rstrip("/") != root]
sys.meta_path = [f for f in sys.meta_path if not f.__module__.startswith("__editable__")]
sys.path_hooks = [h for h in sys.path_hooks if "__editable__" not in str(h)]
sys.path_importer_cache.clear()
import mlflow, pandas as pd
model = mlflow.pyfunc.load_model(sys.argv[2])
import pipeline
predicted = model.predict(pd.read_csv(sys.argv[3]))
print(json.dumps({"pipeline": pipeline.__file__, "predicted": [float(v) for v in predicted]}))
"""


def predict_without_repository(
    model_uri: str, table_csv: Path, cwd: Path, tracking_uri: str | None = None
) -> tuple[Path, list[float]]:
    """Load ``model_uri`` where the repository is not importable and predict a table.

    Parameters
    ----------
    model_uri : str
        ``models:/<name>@<alias>`` (with ``tracking_uri``) or a local model folder.
    table_csv : Path
        The input table, as the machine logs it.
    cwd : Path
        A folder outside the repository to run in.
    tracking_uri : str, optional
        The MLflow server or store the model is registered in.

    Returns
    -------
    Path
        The ``pipeline/__init__.py`` the loaded model imported.
    list of float
        The predictions, um.
    """
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    if tracking_uri is not None:
        env["MLFLOW_TRACKING_URI"] = tracking_uri
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(ROOT), model_uri, str(table_csv)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    answer = json.loads(done.stdout.strip().splitlines()[-1])
    return Path(answer["pipeline"]), answer["predicted"]

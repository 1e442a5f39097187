"""Read one section of ``params.yaml``.

Each stage reads only its own section (DVC's ``params`` dependency is per section), so a change
to another stage's parameters does not rerun it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

DEFAULT_PARAMS = Path("params.yaml")


def load_section(section: str, params_path: Path | str = DEFAULT_PARAMS) -> dict[str, Any]:
    """Return the mapping stored under ``section`` in the params file.

    Parameters
    ----------
    section : str
        Top-level key, e.g. ``"separate"``.
    params_path : Path or str
        The YAML file, ``params.yaml`` in the working directory by default.

    Returns
    -------
    dict
        A copy of the section; the caller may modify it freely.

    Raises
    ------
    KeyError
        If the section is missing, with the file name and the sections it does have.
    """
    path = Path(params_path)
    with path.open(encoding="utf-8") as handle:
        params = yaml.safe_load(handle) or {}
    if section not in params:
        raise KeyError(
            f"{path}: no section '{section}' (sections present: {sorted(params)}); "
            f"add a '{section}:' block to {path}"
        )
    return dict(params[section] or {})

"""Read one section of ``params.yaml``.

Each stage reads only its own section (DVC's ``params`` dependency is per section), so a change
to another stage's parameters does not rerun it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from pipeline.errors import ParamsError

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
    ParamsError
        (a ``KeyError``) If the file is missing or not a YAML mapping, or the section is
        missing, with the file name and what to do.
    """
    path = Path(params_path)
    if not path.is_file():
        raise ParamsError(
            f"{path} not found; run the command in the project folder (where params.yaml is)"
        )
    try:
        params = yaml.safe_load(path.read_text(encoding="utf-8-sig")) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise ParamsError(f"{path} cannot be read as YAML: {error}; fix its syntax") from None
    if not isinstance(params, dict):
        raise ParamsError(f"{path} is not a mapping of sections (ingest:, validate:, ...)")
    if section not in params:
        raise ParamsError(
            f"{path}: no section '{section}' (sections present: {sorted(params)}); "
            f"add a '{section}:' block to {path}"
        )
    return dict(params[section] or {})

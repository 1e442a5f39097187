"""``dvc.yaml`` and ``pipeline.paths`` name the same stage outputs: they cannot drift apart.

Every ``Path`` in :mod:`pipeline.paths` is a declared output (out, metric or plot) of a stage in
``dvc.yaml``, lies inside one, is a folder holding some, or is the raw data folder or the fit
cache (each machine's results by the hash of their inputs: a cache DVC does not track); and every
declared output is one of those paths or lies inside one. A path renamed on one side only fails
here.
"""

from __future__ import annotations

from pathlib import Path, PurePosixPath

import yaml

from pipeline import paths

ROOT = Path(__file__).resolve().parents[1]


def _entries(items) -> list[str]:
    """Paths of a ``dvc.yaml`` list: plain strings or ``{path: options}`` mappings."""
    found = []
    for item in items or []:
        found += list(item) if isinstance(item, dict) else [item]
    return found


def declared_outputs() -> dict[PurePosixPath, str]:
    """Every stage output of ``dvc.yaml`` (outs, metrics, plots) -> the stage writing it."""
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    return {
        PurePosixPath(path): name
        for name, stage in stages.items()
        for key in ("outs", "metrics", "plots")
        for path in _entries(stage.get(key))
    }


def library_paths() -> dict[str, PurePosixPath]:
    """Every ``Path`` constant of :mod:`pipeline.paths`, by name."""
    return {
        name: PurePosixPath(value.as_posix())
        for name, value in vars(paths).items()
        if name.isupper() and isinstance(value, Path)
    }


def _covers(outer: PurePosixPath, inner: PurePosixPath) -> bool:
    return inner == outer or outer in inner.parents


def test_every_library_path_is_a_declared_output_or_holds_or_lies_in_one():
    outputs = declared_outputs()
    stray = {
        name: path.as_posix()
        for name, path in library_paths().items()
        if path not in {PurePosixPath(p.as_posix()) for p in (paths.RAW, paths.FIT_CACHE)}
        and not any(_covers(out, path) or _covers(path, out) for out in outputs)
    }
    assert stray == {}, f"pipeline/paths.py names paths no dvc.yaml stage declares: {stray}"


def test_every_declared_output_is_named_in_the_library():
    named = list(library_paths().values())
    unnamed = {
        out.as_posix(): stage
        for out, stage in declared_outputs().items()
        if not any(_covers(out, path) for path in named)
    }
    assert unnamed == {}, f"dvc.yaml outputs pipeline/paths.py does not name: {unnamed}"


def test_the_check_sees_a_rename_on_one_side():
    outputs = declared_outputs()
    renamed = PurePosixPath("reports/heldout_scores_v2.csv")
    assert not any(_covers(out, renamed) or _covers(renamed, out) for out in outputs)
    assert PurePosixPath(paths.GROUP_SCORES.as_posix()) in outputs

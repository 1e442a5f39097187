"""The house plan of ARCHITECTURE.md, enforced: which package may import which, and dvc.yaml.

Every ``import`` of the ``pipeline`` package (module level and inside functions) is read from
the source. The packages form layers (:data:`ALLOWED`): a package imports only the ones listed
for it, so imports go one way, from the stages down to the foundation; library code never
imports a stage; models never import tracking. Each ``dvc.yaml`` stage runs its own module
``pipeline/stages/<stage>.py`` and lists as dependencies exactly the code that module imports,
directly or not: a new import without its dependency (the stage would not rerun when that code
changes) or a stale dependency fails here.
"""

from __future__ import annotations

import ast
from pathlib import Path, PurePosixPath

import pytest
import yaml

from pipeline import cli
from pipeline.tracking.model_code import import_closure, imported_modules
from pipeline.tracking.model_code import module_name as dotted_name

ROOT = Path(__file__).resolve().parents[1]
OWN_PACKAGES = frozenset({"pipeline", "schemas", "benchmarks", "tests"})
"""Top-level packages of the repository, whose imports the checks follow."""
FOUNDATION = {
    "errors",
    "paths",
    "config",
    "plots",
    "schemas",
    "fit_statistics",
    "warnings_capture",
    "progress",
    "cluster",
    "settings",
    "machines",
    "fit_cache",
}
"""Modules every package may import: errors, paths, params, the figure toolkit, the schemas,
the shared statistics (RMS, information criteria), the warnings' counts, the progress display,
where the parallel jobs run, the typed params.yaml sections, machines as partitions and each
machine's cached results."""

ALLOWED = {
    "schemas": set(),
    "errors": set(),
    "paths": set(),
    "config": {"errors"},
    "plots": set(),
    "fit_statistics": set(),
    "warnings_capture": set(),
    "progress": set(),
    "cluster": set(),
    "settings": set(),
    "machines": {"errors"},
    "fit_cache": {"paths"},
    "validation": set(),
    "io": {"validation", "thermal"},  # the heat-load parser (pipeline/thermal/loads.py)
    "importers": {"io", "cli"},  # `thermal import <source>` reuses the command dispatcher
    "separation": set(),
    "selection": set(),
    "thermal": set(),
    "twin": {"thermal"},
    "models": {"selection"},
    "discrepancy": {"thermal", "io", "validation"},
    "protocol": {"separation", "selection", "models", "discrepancy", "thermal"},
    "reporting": {"protocol", "separation"},
    "tracking": {"protocol", "separation", "discrepancy"},
    "retraining": {"tracking"},
    # the runtime loads the registry's champion through tracking (download_bundle)
    "compensation": {"protocol", "separation", "selection", "models", "tracking"},
    "stages": {
        "io",
        "validation",
        "separation",
        "selection",
        "models",
        "protocol",
        "discrepancy",
        "reporting",
        "tracking",
        "compensation",
    },
    "cli": set(),
    "__main__": {"cli"},
    "pipeline": set(),
}
"""Package -> the packages it may import besides :data:`FOUNDATION` (ARCHITECTURE.md)."""


def module_name(path: Path) -> str:
    """Dotted module name of a source file of the repository."""
    return dotted_name(path, ROOT)


def unit(module: str) -> str:
    """The package (or top-level module) of ``pipeline`` a module belongs to."""
    parts = module.split(".")
    if parts[0] != "pipeline":
        return parts[0]
    return parts[1] if len(parts) > 1 else "pipeline"


def imports(path: Path) -> frozenset[str]:
    """Every ``pipeline``/``schemas``/``benchmarks``/``tests`` module a file imports, anywhere."""
    return imported_modules(path, ROOT, OWN_PACKAGES)


def violations(path: Path, own: str) -> list[str]:
    """The imports of ``path`` (a module of package ``own``) that break the layers."""
    return sorted(
        imported
        for imported in imports(path)
        if unit(imported) not in {own, "pipeline"} | FOUNDATION | ALLOWED[own]
    )


def library_files() -> list[Path]:
    return sorted((ROOT / "pipeline").rglob("*.py"))


def test_every_package_imports_only_the_layers_below_it():
    wrong = {}
    for path in library_files():
        own = unit(module_name(path))
        assert own in ALLOWED, f"{path}: package {own} is not in ARCHITECTURE.md's plan"
        if violations(path, own):
            wrong[path.relative_to(ROOT).as_posix()] = violations(path, own)
    assert wrong == {}


def test_the_layer_check_sees_an_import_inside_a_function(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text(
        "from pipeline.selection import registry\n\n\ndef f():\n"
        "    from pipeline.tracking import store\n    import pipeline.stages.track\n",
        encoding="utf-8",
    )
    assert violations(probe, "models") == ["pipeline.stages.track", "pipeline.tracking.store"]


def test_library_never_imports_a_stage_and_models_never_import_tracking():
    stage_importers = [
        path.relative_to(ROOT).as_posix()
        for path in library_files()
        if unit(module_name(path)) != "stages" and any(unit(m) == "stages" for m in imports(path))
    ]
    tracked_models = [
        path.relative_to(ROOT).as_posix()
        for path in (ROOT / "pipeline" / "models").rglob("*.py")
        if any(unit(m) == "tracking" or m.startswith("mlflow") for m in imports(path))
    ]
    assert stage_importers == [] and tracked_models == []


def test_the_package_never_imports_benchmarks_or_tests():
    outside = [
        path.relative_to(ROOT).as_posix()
        for path in library_files()
        if any(m.split(".")[0] in {"benchmarks", "tests"} for m in imports(path))
    ]
    assert outside == []


def closure(module: str) -> set[Path]:
    """Source files of ``module`` and of everything it imports, transitively."""
    return import_closure([module], ROOT, OWN_PACKAGES)


def _docstring_only(path: Path) -> bool:
    """True for a package ``__init__`` that holds no code (its docstring, a version string)."""
    body = ast.parse(path.read_text(encoding="utf-8")).body
    return path.name == "__init__.py" and all(
        isinstance(node, ast.Expr | ast.Assign) and not isinstance(node.value, ast.Call)
        for node in body
    )


def stages() -> dict[str, dict]:
    return yaml.safe_load((ROOT / "dvc.yaml").read_text(encoding="utf-8"))["stages"]


def stage_module(name: str, stage: dict) -> str:
    """The module ``thermal`` runs for a stage's ``cmd`` (``bin/thermal <command> ...``)."""
    command = stage["cmd"].split()[1]
    return cli.COMMANDS[command][0]


@pytest.mark.parametrize("name", sorted(stages()))
def test_each_stage_runs_its_own_module(name):
    assert stage_module(name, stages()[name]) == f"pipeline.stages.{name}"


@pytest.mark.parametrize("name", sorted(stages()))
def test_each_stage_depends_on_exactly_the_code_it_imports(name):
    stage = stages()[name]
    code = {
        PurePosixPath(p.relative_to(ROOT).as_posix())
        for p in closure(stage_module(name, stage))
        if not _docstring_only(p)
    }
    deps = [
        PurePosixPath(d)
        for d in stage.get("deps") or []
        if d.split("/")[0] in {"pipeline", "schemas"}
    ]

    def covered(path: PurePosixPath) -> bool:
        return any(path == d or d in path.parents for d in deps)

    uncovered = sorted(p.as_posix() for p in code if not covered(p))
    stale = sorted(d.as_posix() for d in deps if not any(p == d or d in p.parents for p in code))
    assert (uncovered, stale) == ([], []), f"dvc.yaml stage {name}: missing deps, stale deps"


MAX_FUNCTION_LINES = 80
"""ARCHITECTURE.md: a function longer than this is split along its sections."""


def test_no_function_is_longer_than_the_limit():
    long = [
        f"{path.relative_to(ROOT)}::{node.name} ({node.end_lineno - node.lineno + 1} lines)"
        for folder in ("pipeline", "benchmarks", "schemas", "tests")
        for path in sorted((ROOT / folder).rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    ]
    assert long == []

"""The source files a logged champion needs: the package modules its loading imports.

A registered champion is an MLflow pyfunc model whose ``python_model`` is
:class:`pipeline.tracking.champion_model.ChampionModel` and whose estimator is a pickled model of
:mod:`pipeline.models`; loading it imports those modules, so they travel with the model
(``code_paths``). Only the modules reached from the loader and the estimator's classes are
shipped, not the whole package: the import statements of each source file are read (``ast``,
imports inside functions included, parent packages added), and the estimator's classes are the
ones its pickle names.
"""

from __future__ import annotations

import ast
import functools
import pickle
import shutil
from collections.abc import Iterable
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
"""The ``pipeline`` package folder."""
LOADER = "pipeline.tracking.champion_model"
"""The module whose class MLflow unpickles as the model's ``python_model``."""


def module_source(module: str, root: Path) -> Path | None:
    """Source file of a dotted module name under ``root``, or None when there is none there.

    Parameters
    ----------
    module : str
        E.g. ``pipeline.models.base`` (file) or ``pipeline.models`` (package ``__init__``).
    root : Path
        The folder that holds the top-level packages.

    Returns
    -------
    Path or None
    """
    path = root.joinpath(*module.split("."))
    for candidate in (path.with_suffix(".py"), path / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def module_name(path: Path, root: Path) -> str:
    """Dotted module name of a source file under ``root`` (of an ``__init__``: its package)."""
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def imported_modules(path: Path, root: Path, packages: frozenset[str]) -> frozenset[str]:
    """Every module of ``packages`` a source file imports, at its top or inside a function.

    ``from a.b import c`` counts as ``a.b.c`` when that is a module under ``root``, else as
    ``a.b``.

    Parameters
    ----------
    path : Path
        A Python source file.
    root : Path
        The folder that holds ``packages``.
    packages : frozenset of str
        Top-level package names whose modules are kept (e.g. ``{"pipeline"}``).

    Returns
    -------
    frozenset of str
        Dotted module names.
    """
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            for alias in node.names:
                candidate = f"{node.module}.{alias.name}"
                found.add(candidate if module_source(candidate, root) else node.module)
    return frozenset(m for m in found if m.split(".")[0] in packages)


def import_closure(modules: Iterable[str], root: Path, packages: frozenset[str]) -> set[Path]:
    """Source files of ``modules`` and of everything they import, transitively.

    A module's parent packages count as imported (Python runs their ``__init__`` first).

    Parameters
    ----------
    modules : iterable of str
        Dotted names to start from; names without a source file under ``root`` are skipped.
    root : Path
        The folder that holds ``packages``.
    packages : frozenset of str
        Top-level package names followed.

    Returns
    -------
    set of Path
    """
    seen: set[Path] = set()
    todo = list(modules)
    while todo:
        path = module_source(todo.pop(), root)
        if path is None or path in seen:
            continue
        seen.add(path)
        todo += sorted(imported_modules(path, root, packages))
        parts = module_name(path, root).split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts))]
    return seen


class _Discard:
    """A file that forgets what is written to it (the pickle is only walked)."""

    def write(self, data: bytes) -> int:
        return len(data)


def referenced_modules(obj: object) -> set[str]:
    """Modules of the classes and functions that pickling ``obj`` refers to by name.

    Parameters
    ----------
    obj : object
        A picklable object, e.g. a fitted estimator.

    Returns
    -------
    set of str
    """
    found: set[str] = set()

    class Recorder(pickle.Pickler):
        def reducer_override(self, value: object) -> object:
            named = isinstance(value, type) or callable(value) and hasattr(value, "__qualname__")
            module = getattr(value, "__module__", None) if named else type(value).__module__
            if isinstance(module, str):
                found.add(module)
            return NotImplemented

    Recorder(_Discard(), protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return found


def write_model_code(estimator: object, destination: Path) -> Path:
    """Copy the package modules that loading a champion with ``estimator`` imports.

    Parameters
    ----------
    estimator : object
        The fitted estimator the model's artifacts hold.
    destination : Path
        An empty folder; ``destination/pipeline/...`` is written, in the package's layout.

    Returns
    -------
    Path
        ``destination/pipeline``, for MLflow's ``code_paths``.
    """
    root = PACKAGE.parent
    own = {m for m in referenced_modules(estimator) if m.split(".")[0] == PACKAGE.name}
    for source in import_closure({LOADER, *own}, root, frozenset({PACKAGE.name})):
        target = destination / source.relative_to(root)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, target)
    return destination / PACKAGE.name

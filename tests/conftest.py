"""Test-suite order: the longest modules first, so that two workers finish together.

``make test`` hands whole modules to its two workers (``--dist loadscope``), so a module's
shared fixture (one pipeline run for all its tests) is built once. Starting with the modules
that run the whole pipeline, the longest jobs, then the other slow ones, and filling in with the
fast ones is the longest-processing-time-first rule, which keeps one worker from finishing long
after the other.
"""

from __future__ import annotations

import sys

import pytest

PIPELINE_MODULES = (
    "tests.test_end_to_end",
    "tests.test_retrain_weeks",
    "tests.test_readme_commands",
    "tests.test_workshop_end_to_end",
    "tests.test_dvc_remote",
)
"""Modules whose tests run ``dvc repro`` on a copy of the repository, longest first."""


def _rank(item: pytest.Item, slow_modules: set[str]) -> tuple[int, int]:
    module = item.module.__name__
    if module in PIPELINE_MODULES:
        return 0, PIPELINE_MODULES.index(module)
    return (1 if module in slow_modules else 2), 0


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Pipeline modules first, then the other modules with ``slow`` tests, then the rest."""
    slow_modules = {item.module.__name__ for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: _rank(item, slow_modules))


@pytest.fixture(autouse=True)
def import_path_restored(monkeypatch: pytest.MonkeyPatch) -> None:
    """Give each test its own ``sys.path``, the session's again after it.

    Loading a pyfunc model in the test process puts the model's ``code`` folder first on
    ``sys.path``; joblib worker processes started later by another test would import ``pipeline``
    from there (the modules the model needs, not the package).
    """
    monkeypatch.setattr(sys, "path", list(sys.path))

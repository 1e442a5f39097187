"""Test-suite order: the slow modules first, so that two workers finish together.

``make test`` hands whole modules to its two workers (``--dist loadscope``), so a module's
shared fixture (one pipeline run for all its tests) is built once. Starting with the modules
that run the pipeline end to end, the longest jobs, and filling in with the fast ones is the
longest-processing-time-first rule, which keeps one worker from finishing long after the other.
"""

from __future__ import annotations

import pytest


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Put the modules holding ``slow`` tests first, keeping each module's tests together."""
    slow_modules = {item.module.__name__ for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.module.__name__ not in slow_modules)

"""Sensitive-point selection: which temperature sensors a thermal-error model should use.

Each method is ``f(temperatures, error, **params) -> Selection`` and is registered by name in
:mod:`pipeline.selection.registry`:

- ``all``: every sensor with data;
- ``fc_grd``: fuzzy clustering by correlation + grey relational degree (the PCDL paper);
- ``gra_top_k``: the k sensors with the largest grey relational degree (the PCDL paper);
- ``best_subset``: exact best subset by adjusted R^2 and AICc (the patent);
- ``correlation_grouping``: one sensor per group of mutually correlated sensors (Lo, Yuan and
  Ni 1999).
"""

from pipeline.selection.best_subset import best_subset, best_subset_naive
from pipeline.selection.correlation_grouping import correlation_grouping
from pipeline.selection.fuzzy import fc_grd
from pipeline.selection.gra_top_k import gra_top_k
from pipeline.selection.registry import SELECTORS, make_selector, select_all
from pipeline.selection.result import Selection

__all__ = [
    "SELECTORS",
    "Selection",
    "best_subset",
    "best_subset_naive",
    "correlation_grouping",
    "fc_grd",
    "gra_top_k",
    "make_selector",
    "select_all",
]

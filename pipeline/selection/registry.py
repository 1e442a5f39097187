"""Registry of sensitive-point selection methods: name in ``params.yaml`` -> selector.

Every entry is ``f(temperatures, error, **params) -> Selection`` (:mod:`pipeline.selection.result`).
:func:`make_selector` binds the params once, checking the name and every param name, so a typo in
``params.yaml`` fails before any campaign is processed.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from functools import partial

import numpy as np
import pandas as pd

from pipeline.selection.best_subset import best_subset
from pipeline.selection.correlation_grouping import correlation_grouping
from pipeline.selection.fuzzy import fc_grd
from pipeline.selection.gra_top_k import gra_top_k
from pipeline.selection.result import STATUS_ALL_NAN, STATUS_USED, Selection, check_frame

Selector = Callable[[pd.DataFrame, np.ndarray], Selection]


def select_all(temperatures: pd.DataFrame, error: np.ndarray) -> Selection:
    """Every sensor with at least one finite value, in column order (no selection).

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (:mod:`pipeline.selection.result`); only the error's shape is checked.

    Returns
    -------
    Selection
        ``evidence``: one row per sensor with ``sensor``, ``n_finite`` (finite readings),
        ``chosen``, ``status``. ``details``: ``n_sensors_used``, ``n_sensors_ignored``.

    Raises
    ------
    ValueError
        If the inputs are malformed or no sensor has a finite value.
    """
    check_frame(temperatures, error)
    names = [str(c) for c in temperatures.columns]
    n_finite = np.isfinite(temperatures.to_numpy(dtype=float)).sum(axis=0)
    chosen = n_finite > 0
    if not chosen.any():
        raise ValueError(f"no sensor has any finite value (all of {names} are NaN)")
    evidence = pd.DataFrame(
        {
            "sensor": names,
            "n_finite": n_finite,
            "chosen": chosen,
            "status": np.where(chosen, STATUS_USED, STATUS_ALL_NAN),
        }
    )
    sensors = [name for name, keep in zip(names, chosen, strict=True) if keep]
    details: dict[str, int | float | str] = {
        "n_sensors_used": len(sensors),
        "n_sensors_ignored": len(names) - len(sensors),
    }
    return Selection("all", sensors, evidence, details)


SELECTORS: dict[str, Callable[..., Selection]] = {
    "all": select_all,
    "fc_grd": fc_grd,
    "gra_top_k": gra_top_k,
    "best_subset": best_subset,
    "correlation_grouping": correlation_grouping,
}


def make_selector(name: str, **params: object) -> Selector:
    """Look up a selection method and bind its parameters.

    Parameters
    ----------
    name : str
        A key of :data:`SELECTORS`.
    **params
        Keyword parameters of that method (see its docstring); omitted ones keep their defaults.

    Returns
    -------
    callable
        ``selector(temperatures, error) -> Selection``.

    Raises
    ------
    KeyError
        If ``name`` is not registered (the message lists the registered names).
    TypeError
        If a parameter is not one the method accepts (the message names it and the accepted
        ones).
    """
    if name not in SELECTORS:
        raise KeyError(
            f"unknown selection method {name!r}; registered methods: {sorted(SELECTORS)}"
        )
    accepted = parameters(name)
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise TypeError(
            f"selection method {name!r} got unknown parameter(s) {unknown}; "
            f"it accepts {accepted or 'no parameters'}"
        )
    return partial(SELECTORS[name], **params)


def parameters(name: str) -> list[str]:
    """Return the parameters the registered selection method ``name`` accepts, in order."""
    return [
        p.name
        for p in inspect.signature(SELECTORS[name]).parameters.values()
        if p.kind is inspect.Parameter.KEYWORD_ONLY
    ]

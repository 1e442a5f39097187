"""GRA top-k: rank every sensor by grey relational degree to the error, keep the first k.

The PCDL paper (Miao et al. 2016, section 4.1, tables 4-5) picks the inputs of its PCDL model by
the "main factor" and "fewest points" strategies only -- PCDL suppresses collinearity itself, so
mutually correlated sensors may all be kept: the sensors with the largest grey relational degree
to the thermal deformation (:mod:`pipeline.selection.grey`, rho = 0.5). The paper does not say
how many; ``k`` (default 4) is a parameter.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from pipeline.selection.grey import RESOLUTION_COEFFICIENT, grey_relational_degree
from pipeline.selection.result import STATUS_USED, Selection, clean_inputs

logger = logging.getLogger(__name__)


def gra_top_k(
    temperatures: pd.DataFrame,
    error: np.ndarray,
    *,
    k: int = 4,
    rho: float = RESOLUTION_COEFFICIENT,
) -> Selection:
    """Keep the k sensors with the largest grey relational degree to the thermal error.

    Parameters
    ----------
    temperatures, error : DataFrame of shape (n, m), array-like of shape (n,)
        The selector inputs (:mod:`pipeline.selection.result`); campaigns' rows are pooled.
    k : int, default 4
        Number of sensors to keep, between 1 and the number of usable sensors.
    rho : float, default 0.5
        Resolution coefficient of the grey relational degree.

    Returns
    -------
    Selection
        ``sensors``: the top k, best first (ties keep column order). ``evidence``: one row per
        sensor with ``sensor``, ``grd``, ``rank`` (1 = largest degree), ``chosen``, ``status``
        (ignored sensors have NaN grd and rank). ``details``: ``k``, ``rho``, ``n_rows``,
        ``n_rows_dropped``, ``n_sensors_used``, ``n_sensors_ignored``.

    Raises
    ------
    ValueError
        If the inputs are unusable or ``k`` is not between 1 and the number of usable sensors.
    """
    inputs = clean_inputs(temperatures, error)
    used = list(inputs.temperatures.columns)
    if not (isinstance(k, int | np.integer) and 1 <= k <= len(used)):
        raise ValueError(
            f"k={k!r} must be an integer between 1 and the {len(used)} usable sensors {used}; "
            f"lower k or supply more sensors"
        )
    degrees = grey_relational_degree(inputs.error, inputs.temperatures.to_numpy(), rho)
    order = np.argsort(-degrees, kind="stable")
    rank = np.empty(len(used), dtype=int)
    rank[order] = np.arange(1, len(used) + 1)
    evidence = pd.DataFrame(
        {"sensor": used, "grd": degrees, "rank": rank, "chosen": rank <= k, "status": STATUS_USED}
    ).sort_values("rank", kind="stable")
    evidence = inputs.with_ignored(evidence, "rank")
    sensors = [used[i] for i in order[:k]]
    details: dict[str, int | float | str] = {
        "k": int(k),
        "rho": float(rho),
        **inputs.counts(),
    }
    logger.debug("gra_top_k: top %d of %d -> %s", k, len(used), sensors)
    return Selection("gra_top_k", sensors, evidence, details)

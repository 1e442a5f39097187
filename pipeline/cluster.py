"""Where the parallel jobs run: this machine's processes, or a Dask cluster a team names.

By default :func:`pipeline.progress.run_jobs` runs its jobs in joblib's local worker processes.
Where the environment variable :data:`SCHEDULER_VARIABLE` names a Dask scheduler (e.g.
``tcp://10.0.0.5:8786``), they run on that cluster's workers instead, through joblib's Dask
backend (``distributed``): every job is the same function call with the same arguments, so the
scores are the local run's. The cluster is an environment setting, not a ``params.yaml`` one:
where a fit runs does not change what it computes, and a parameter would make DVC rerun every
stage that reads it when the cluster's address changes.

The workers import the jobs' functions: they run the same version of this package (the same
commit's ``.venv``, e.g. ``.venv/bin/dask worker tcp://...`` from a clone of it).
"""

from __future__ import annotations

import logging
import os
from contextlib import AbstractContextManager, nullcontext

from joblib import parallel_config

from pipeline.errors import ClusterUnreachableError

LOGGER = logging.getLogger(__name__)

SCHEDULER_VARIABLE = "THERMAL_DASK_SCHEDULER"
"""Environment variable naming the Dask scheduler (``tcp://host:port``); unset or empty: local
processes."""

CONNECT_TIMEOUT_S = 20.0
"""How long the stage waits for the scheduler to answer before it stops with an error."""

_CLIENTS: dict[str, object] = {}
"""One ``distributed.Client`` per scheduler address, kept for the life of the stage's process."""


def scheduler_address() -> str | None:
    """Return the Dask scheduler :data:`SCHEDULER_VARIABLE` names, or None (local processes)."""
    address = os.environ.get(SCHEDULER_VARIABLE, "").strip()
    return address or None


def backend() -> AbstractContextManager:
    """Return the context in which joblib's ``Parallel`` runs: the Dask cluster, or as it is.

    Raises
    ------
    ClusterUnreachableError
        If the named scheduler does not answer within :data:`CONNECT_TIMEOUT_S`.
    """
    address = scheduler_address()
    if address is None:
        return nullcontext()
    _client(address)
    return parallel_config(backend="dask")


def _client(address: str) -> object:
    """Connect to the scheduler once per process (the client joblib's Dask backend uses)."""
    if address not in _CLIENTS:
        from distributed import Client  # imported only where a cluster is named

        try:
            client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=True)
        except OSError as error:
            raise ClusterUnreachableError(
                f"{SCHEDULER_VARIABLE}={address}: no Dask scheduler answered within "
                f"{CONNECT_TIMEOUT_S:.0f} s ({error}). Start it (`dask scheduler`) and its "
                f"workers (`dask worker {address}`), or unset {SCHEDULER_VARIABLE} to run the "
                "jobs in local processes."
            ) from error
        workers = client.scheduler_info().get("workers", {})
        LOGGER.info("parallel jobs run on the Dask cluster %s (%d workers)", address, len(workers))
        _CLIENTS[address] = client
    return _CLIENTS[address]

"""Exact discretisation of a linear system for inputs linear within each step (first-order hold).

Over a step of length h with ``u`` linear from ``u(t)`` to ``u(t+h)``, ``dx/dt = A x + B u``
integrates exactly to ``x(t+h) = Phi x(t) + G0 u(t) + G1 (u(t+h) - u(t))``. The three matrices
are blocks of the exponential (``scipy.linalg.expm``) of the augmented matrix
``[[A h, B h, 0], [0, 0, I], [0, 0, 0]]``. A heat step at a step boundary is represented
exactly (one-sided limits), and so is an ambient that is linear between grid instants.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm


def foh_matrices(
    A: np.ndarray, B: np.ndarray, hs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order-hold matrices of P systems over each of n_h step lengths.

    ``scipy.linalg.expm`` exponentiates each (P, n_h) slice on its own, so a batch gives the
    same matrices, bit for bit, as one system and one step length at a time.

    Parameters
    ----------
    A : ndarray of shape (P, ns, ns), 1/s
    B : ndarray of shape (P, ns, ni)
    hs : ndarray of shape (n_h,), s
        Step lengths.

    Returns
    -------
    phi, g0, g1 : ndarray of shape (P, n_h, ns, ns), (P, n_h, ns, ni), (P, n_h, ns, ni)
        ``x[k+1] = phi x[k] + g0 u[k] + g1 (u[k+1] - u[k])``.
    """
    n_p, ns, ni = B.shape
    M = np.zeros((n_p, hs.size, ns + 2 * ni, ns + 2 * ni))
    M[:, :, :ns, :ns] = A[:, None] * hs[None, :, None, None]
    M[:, :, :ns, ns : ns + ni] = B[:, None] * hs[None, :, None, None]
    M[:, :, ns : ns + ni, ns + ni :] = np.eye(ni)
    E = expm(M)
    return E[..., :ns, :ns], E[..., :ns, ns : ns + ni], E[..., :ns, ns + ni :]

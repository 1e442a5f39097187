"""Stepping a discretised thermal network through time: one state, or a batch in its modes.

:func:`time_grid` puts the output instants and the program's breakpoints on one grid, so the
inputs are linear within every step (heat constant, ambient linear). :func:`integrate_foh`
steps one state with the first-order-hold matrices of :mod:`pipeline.thermal.discretise`
(the generator, :mod:`pipeline.twin.simulate`); :func:`propagate` steps P parameter vectors and
several campaigns at once, in the modes of the network when its eigenbasis is well conditioned
(the calibrated twin, :mod:`pipeline.discrepancy.model`). :func:`integrate_ivp` integrates with
``scipy.integrate.solve_ivp`` (stiff ``Radau``/``BDF``/``LSODA``) as a cross-check.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from pipeline.thermal.discretise import foh_matrices
from pipeline.thermal.network import LinearSystem

logger = logging.getLogger(__name__)

MAX_MODAL_CONDITION = 1e6
"""Largest condition number of the eigenvector matrix for which :func:`propagate` steps in
modal coordinates; above it (near-coincident time constants) it steps the full state."""


def time_grid(
    times_s: np.ndarray,
    breaks_s: np.ndarray,
    start_s: float = 0.0,
    max_step_s: float = np.inf,
) -> np.ndarray:
    """Return the integration grid: start, output instants and the breakpoints between them.

    Parameters
    ----------
    times_s : ndarray of shape (n_t,), s
        Output instants, increasing; the grid ends at the last one.
    breaks_s : ndarray of shape (k,), s
        Instants where an input may jump (program breakpoints); only those strictly between
        ``start_s`` and the last output instant are kept.
    start_s : float
        Instant of the initial state, s.
    max_step_s : float
        Longest step, s; longer gaps are cut into equal steps (default: no limit).

    Returns
    -------
    ndarray of shape (L,), s
        Sorted unique instants.
    """
    t_end = times_s[-1]
    pts = np.concatenate([[start_s], times_s, breaks_s[(breaks_s > start_s) & (breaks_s < t_end)]])
    grid = np.unique(pts)
    gaps = np.diff(grid)
    extra = [
        np.linspace(a, b, int(np.ceil(h / max_step_s)) + 1)[1:-1]
        for a, b, h in zip(grid[:-1], grid[1:], gaps, strict=True)
        if h > max_step_s
    ]
    return np.unique(np.concatenate([grid, *extra])) if extra else grid


def integrate_foh(
    system: LinearSystem,
    x0: np.ndarray,
    grid_s: np.ndarray,
    u_left: np.ndarray,
    u_right: np.ndarray,
) -> np.ndarray:
    """Integrate one state exactly for inputs that are linear on each grid interval.

    Parameters
    ----------
    system : LinearSystem
    x0 : ndarray of shape (n_states,)
        State at ``grid_s[0]``.
    grid_s : ndarray of shape (k,), s
        Strictly increasing instants; step lengths are rounded to 1e-6 s and discretised once
        each.
    u_left, u_right : ndarray of shape (k - 1, n_inputs)
        Inputs at the start and at the end of each interval (one-sided limits, so a heat step
        at a grid instant is represented exactly).

    Returns
    -------
    ndarray of shape (k, n_states)
        The state at every grid instant.
    """
    grid = np.asarray(grid_s, dtype=float)
    if np.any(np.diff(grid) <= 0):
        raise ValueError("integrate_foh: grid instants must be strictly increasing")
    steps = [round(float(h), 6) for h in np.diff(grid)]
    hs = np.array(sorted(set(steps)))
    which = np.searchsorted(hs, steps)
    phi, g0, g1 = (m[0] for m in foh_matrices(system.A[None], system.B[None], hs))
    x = np.empty((grid.size, x0.size))
    x[0] = x0
    for k, j in enumerate(which):
        x[k + 1] = phi[j] @ x[k] + g0[j] @ u_left[k] + g1[j] @ (u_right[k] - u_left[k])
    logger.debug("integrate_foh: %d steps, %d distinct step lengths", grid.size - 1, hs.size)
    return x


def _linear_rhs(
    t: float,
    y: np.ndarray,
    system: LinearSystem,
    inputs: Callable[[float, int], np.ndarray],
    k: int,
) -> np.ndarray:
    """Right-hand side ``A y + B u(t)`` on interval ``k``, K/s."""
    return system.A @ y + system.B @ inputs(t, k)


def integrate_ivp(
    system: LinearSystem,
    x0: np.ndarray,
    grid_s: np.ndarray,
    inputs: Callable[[float, int], np.ndarray],
    method: str = "Radau",
) -> np.ndarray:
    """Integrate with ``scipy.integrate.solve_ivp`` interval by interval (cross-check).

    Parameters
    ----------
    system : LinearSystem
    x0 : ndarray of shape (n_states,)
    grid_s : ndarray of shape (k,), s
        Instants; heat steps may only occur at these instants.
    inputs : callable ``(t_s, interval_index) -> ndarray of shape (n_inputs,)``
        Inputs at time t inside the given interval.
    method : str
        A stiff-capable ``solve_ivp`` method: ``"Radau"``, ``"BDF"`` or ``"LSODA"``.

    Returns
    -------
    ndarray of shape (k, n_states)
    """
    grid = np.asarray(grid_s, dtype=float)
    x = np.empty((grid.size, x0.size))
    x[0] = x0
    for k in range(grid.size - 1):
        sol = solve_ivp(
            _linear_rhs,
            (grid[k], grid[k + 1]),
            x[k],
            method=method,
            jac=system.A,
            rtol=1e-9,
            atol=1e-9,
            args=(system, inputs, k),
        )
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed on [{grid[k]}, {grid[k + 1]}] s: {sol.message}")
        x[k + 1] = sol.y[:, -1]
    return x


def _stepping_basis(A: np.ndarray) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray]:
    """Eigenbasis of each ``A`` if all of them are real and well conditioned.

    Returns
    -------
    modal : bool
        True when :func:`propagate` may step in modal coordinates.
    mu : ndarray of shape (P, ns), 1/s
        Eigenvalues.
    V : ndarray of shape (P, ns, ns)
        Real eigenvectors (columns).
    basis_t : ndarray of shape (P, ns, ns) or (1, ns, ns)
        Transposed change to the stepping basis (``V^-1`` transposed, or the identity).
    """
    ns = A.shape[1]
    mu, V = np.linalg.eig(A)
    modal = bool(np.all(np.abs(mu.imag) <= 1e-12 * np.abs(mu).max())) and bool(
        np.all(np.linalg.cond(V) < MAX_MODAL_CONDITION)
    )
    V = V.real
    basis_t = np.swapaxes(np.linalg.inv(V), 1, 2) if modal else np.eye(ns)[None]
    return modal, mu, V, basis_t


def _input_terms(
    g0: np.ndarray,
    g1: np.ndarray,
    basis_t: np.ndarray,
    U: np.ndarray,
    dU: np.ndarray,
    H: np.ndarray,
    hs: np.ndarray,
) -> np.ndarray:
    """Each step's input contribution ``g0 u + g1 du`` in the stepping basis, (P, L-1, n_c, ns)."""
    n_p, n_steps, n_c, ni = U.shape
    ns = basis_t.shape[-1]
    m0 = np.swapaxes(g0, 2, 3) @ basis_t[:, None]  # (P, n_h, ni, ns)
    m1 = np.swapaxes(g1, 2, 3) @ basis_t[:, None]
    if hs.size == 1:
        w = U.reshape(n_p, -1, ni) @ m0[:, 0] + dU.reshape(-1, ni) @ m1[:, 0]
        return w.reshape(n_p, n_steps, n_c, ns)
    w = np.empty((n_p, n_steps, n_c, ns))
    for i in range(hs.size):
        k_idx, c_idx = np.nonzero(H.T == i)
        w[:, k_idx, c_idx] = U[:, k_idx, c_idx] @ m0[:, i] + dU[k_idx, c_idx] @ m1[:, i]
    return w


def propagate(
    A: np.ndarray,
    phi: np.ndarray,
    g0: np.ndarray,
    g1: np.ndarray,
    U: np.ndarray,
    dU: np.ndarray,
    X0: np.ndarray,
    H: np.ndarray,
    hs: np.ndarray,
) -> np.ndarray:
    """Step ``x[k+1] = phi[h_k] x[k] + g0[h_k] u[k] + g1[h_k] du[k]`` for all P and campaigns.

    ``A`` is similar to a symmetric matrix on the nodes (``-C^-1 K``) with the sensor-lag states
    below it, so it has real eigenvalues and, unless a lag equals a node time constant, a
    well-conditioned eigenbasis ``A = V diag(mu) V^-1``. Then ``phi[h] = V diag(exp(mu h))
    V^-1`` and the recurrence decouples into one scalar recurrence per mode, stepped as an
    element-wise product (no small matrix product per step). Where the eigenbasis is
    ill-conditioned or complex (:data:`MAX_MODAL_CONDITION`), the full state is stepped with
    ``phi``.

    Parameters
    ----------
    A : ndarray of shape (P, ns, ns), 1/s
    phi : ndarray of shape (P, n_h, ns, ns)
        Transition matrices for the step lengths ``hs``.
    g0, g1 : ndarray of shape (P, n_h, ns, ni)
        Input matrices of the first-order hold for the step lengths ``hs``.
    U : ndarray of shape (P, L - 1, n_c, ni)
        Inputs at the start of each step.
    dU : ndarray of shape (L - 1, n_c, ni)
        Change of the inputs over each step.
    X0 : ndarray of shape (n_c, ns), degC
    H : ndarray of shape (n_c, L - 1), int
        Index in ``hs`` of each step's length.
    hs : ndarray of shape (n_h,), s

    Returns
    -------
    ndarray of shape (P, L, n_c, ns), degC
    """
    n_p, n_steps, n_c, _ = U.shape
    ns = A.shape[1]
    modal, mu, V, basis_t = _stepping_basis(A)
    w = _input_terms(g0, g1, basis_t, U, dU, H, hs)
    Y = np.empty((n_p, n_steps + 1, n_c, ns))
    Y[:, 0] = X0 @ basis_t
    if modal:
        decay = np.exp(mu.real[:, None, :] * hs[None, :, None])  # (P, n_h, ns)
        for k in range(n_steps):
            d = decay[:, :1] if hs.size == 1 else decay[:, H[:, k]]
            Y[:, k + 1] = d * Y[:, k] + w[:, k]
        X = (Y.reshape(n_p, -1, ns) @ np.swapaxes(V, 1, 2)).reshape(Y.shape)
        X[:, 0] = X0  # exactly, not through the round trip of the basis change
        return X
    phi_t = np.swapaxes(phi, 2, 3)
    for k in range(n_steps):
        Y[:, k + 1] = np.einsum("pcj,pcji->pci", Y[:, k], phi_t[:, H[:, k]]) + w[:, k]
    return Y

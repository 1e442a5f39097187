"""Collinearity of sensitivity vectors: Brun et al.'s index and the part a set cannot absorb.

A sensitivity matrix ``S`` (n_observations, n_parameters) holds in column ``j`` the change of
the (noise-weighted) model outputs per unit change of parameter ``j``. Brun, Reichert and
Künsch (2001, *Practical identifiability analysis of large environmental simulation models*,
Water Resources Research 37(4), 1015-1030) scale each column to unit length,
``s_j / ||s_j||``, and define the *collinearity index* of a parameter subset

    gamma = 1 / sqrt(min eigenvalue of S_n^T S_n),        S_n: the unit-length columns,

so that ``1 / gamma`` is the smallest change of the outputs (relative to the columns' lengths)
any unit-norm combination of the parameter changes can produce: gamma = 1 for orthogonal
columns, infinite for linearly dependent ones. They call subsets with gamma above about 10-15
poorly identifiable (a parameter change can be compensated to 1/10-1/15 by the others).

:func:`absorbed` and :func:`project_out` split a response into the part a set of sensitivity
vectors can reproduce by least squares and the orthogonal rest, through an orthonormal basis of
their column space (:func:`orthonormal_basis`, SVD with a relative rank cut).
"""

from __future__ import annotations

import numpy as np

RANK_RCOND = 1e-10
"""Singular values below this fraction of the largest are dropped from a column space (they are
round-off of linearly dependent or zero columns)."""


def unit_columns(sensitivities: np.ndarray) -> np.ndarray:
    """Return the columns scaled to unit Euclidean length; a zero column stays zero.

    Parameters
    ----------
    sensitivities : ndarray of shape (n, p)

    Returns
    -------
    ndarray of shape (n, p)
    """
    s = np.asarray(sensitivities, dtype=float)
    norms = np.linalg.norm(s, axis=0)
    return s / np.where(norms > 0.0, norms, 1.0)


def collinearity_index(sensitivities: np.ndarray) -> float:
    """Return Brun et al.'s (2001) collinearity index of the columns' parameters.

    Parameters
    ----------
    sensitivities : ndarray of shape (n, p)
        One column per parameter, in any scale (the columns are normalised here).

    Returns
    -------
    float
        ``1 / sqrt(lambda_min)`` of the normalised ``S^T S``, >= 1; ``inf`` when the columns
        are linearly dependent or one is zero (no output change at all); NaN without any
        column.
    """
    s = np.asarray(sensitivities, dtype=float)
    if s.shape[1] == 0:
        return float("nan")
    if np.any(np.linalg.norm(s, axis=0) == 0.0):
        return float("inf")
    # singular values of S_n: lambda_min(S_n^T S_n) = sigma_min^2, without squaring round-off
    sigma_min = np.linalg.svd(unit_columns(s), compute_uv=False)[-1]
    return float(1.0 / sigma_min) if sigma_min > 0.0 else float("inf")


def orthonormal_basis(sensitivities: np.ndarray, rcond: float = RANK_RCOND) -> np.ndarray:
    """Return an orthonormal basis of the column space of the unit-length columns.

    Parameters
    ----------
    sensitivities : ndarray of shape (n, p)
    rcond : float
        Relative cut on the singular values (:data:`RANK_RCOND`).

    Returns
    -------
    ndarray of shape (n, r)
        ``r`` <= p orthonormal columns (r = 0 for an empty or all-zero matrix).
    """
    s = unit_columns(sensitivities)
    if s.size == 0:
        return np.zeros((s.shape[0], 0))
    u, sv, _ = np.linalg.svd(s, full_matrices=False)
    if sv.size == 0 or sv[0] == 0.0:
        return np.zeros((s.shape[0], 0))
    return u[:, sv > rcond * sv[0]]


def with_prior(sensitivities: np.ndarray) -> np.ndarray:
    """Return the sensitivities with one prior row per parameter appended (the identity).

    With the columns scaled by each parameter's prior standard deviation (Brun et al.'s
    ``Delta theta``), the least-squares fit of a response ``[r; 0]`` by these columns is the
    Tikhonov (ridge) fit ``min ||r - S b||^2 + ||b||^2``: the posterior mean of the parameter
    changes under a unit Gaussian prior. A parameter whose outputs barely move (a link at a
    bound, a node tied to its neighbour) can then absorb only what a plausible change of it
    gives, not what an unbounded one would.

    Parameters
    ----------
    sensitivities : ndarray of shape (n, p)

    Returns
    -------
    ndarray of shape (n + p, p)
    """
    s = np.asarray(sensitivities, dtype=float)
    return np.vstack([s, np.eye(s.shape[1])])


def absorbed(response: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Return the least-squares reproduction of ``response`` by the columns of ``basis``.

    Parameters
    ----------
    response : ndarray of shape (n,) or (n, k)
    basis : ndarray of shape (n, r)
        Orthonormal columns (:func:`orthonormal_basis`).

    Returns
    -------
    ndarray, the shape of ``response``
        ``basis basis^T response``.
    """
    return basis @ (basis.T @ np.asarray(response, dtype=float))


def project_out(response: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Return the part of ``response`` orthogonal to the columns of ``basis`` (what they miss).

    Parameters
    ----------
    response : ndarray of shape (n,) or (n, k)
    basis : ndarray of shape (n, r)
        Orthonormal columns (:func:`orthonormal_basis`).

    Returns
    -------
    ndarray, the shape of ``response``
        The least-squares residual ``response - basis basis^T response``.
    """
    response = np.asarray(response, dtype=float)
    return response - absorbed(response, basis)


def effect_collinearity_index(baseline_basis: np.ndarray, effect: np.ndarray) -> float:
    """Return the collinearity index of an effect's parameters against the baseline's.

    Brun et al.'s index of the columns ``[baseline_basis, unit(effect)]``: the baseline is
    re-parameterised by an orthonormal basis of its sensitivities (the combinations of its
    parameters the data can move), so that its own collinearity (parameters that only act
    together, such as a node's heat capacity and cooling) does not count against the effect.
    For one effect column at angle ``phi`` to the baseline's column space it equals
    ``1 / sqrt(1 - cos phi)``.

    Parameters
    ----------
    baseline_basis : ndarray of shape (n, r)
        Orthonormal columns (:func:`orthonormal_basis` of the baseline's sensitivities).
    effect : ndarray of shape (n, k)
        The effect's sensitivity columns, any scale.

    Returns
    -------
    float
        >= 1; ``inf`` when an effect column is zero or lies in the baseline's column space.
    """
    return collinearity_index(np.hstack([baseline_basis, np.asarray(effect, dtype=float)]))

"""Lumped-parameter thermal network and its state-space form with sensor-lag states.

A machine is a set of lumped nodes i with heat capacity C_i (J/K), linked by conductances
G_ij (W/K) and losing heat to the ambient air through a convection conductance h_i (W/K)::

    C_i dT_i/dt = q_i(t) - sum_j G_ij (T_i - T_j) - h_i (T_i - T_amb(t))

i.e. ``C dT/dt = -K T + h T_amb + q`` with ``K`` the conductance (Laplacian + convection)
matrix. :func:`build_system` writes it as ``dx/dt = A x + B u`` and appends one first-order
state per lagged sensor; :mod:`pipeline.thermal.discretise` and :mod:`pipeline.thermal.stepping`
integrate it exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class ThermalNetwork:
    """Nodes, heat capacities and conductances of a lumped thermal model.

    Attributes
    ----------
    nodes : tuple of str
        Node names, e.g. ``("front_bearing", "headstock", ...)``.
    capacity_j_per_k : tuple of float
        Heat capacity C_i of each node, J/K (mass times specific heat; steel ~460, cast iron
        ~500 J/(kg K)).
    convection_w_per_k : tuple of float
        Convection conductance h_i = h A to the ambient air of each node, W/K.
    links : tuple of (str, str, float)
        Conduction links ``(node_a, node_b, G_ab)``, G in W/K.
    """

    nodes: tuple[str, ...]
    capacity_j_per_k: tuple[float, ...]
    convection_w_per_k: tuple[float, ...]
    links: tuple[tuple[str, str, float], ...]

    def __post_init__(self) -> None:
        """Check sizes, positivity and link node names."""
        n = len(self.nodes)
        if len(set(self.nodes)) != n:
            raise ValueError(f"ThermalNetwork: duplicate node names in {self.nodes}")
        if len(self.capacity_j_per_k) != n or len(self.convection_w_per_k) != n:
            raise ValueError(
                f"ThermalNetwork: {n} nodes but {len(self.capacity_j_per_k)} capacities and "
                f"{len(self.convection_w_per_k)} convection conductances; give one per node"
            )
        if min(self.capacity_j_per_k) <= 0:
            raise ValueError("ThermalNetwork: every heat capacity must be > 0 J/K")
        for a, b, g in self.links:
            for name in (a, b):
                if name not in self.nodes:
                    raise ValueError(
                        f"ThermalNetwork: link ({a}, {b}) names unknown node '{name}'; "
                        f"nodes are {self.nodes}"
                    )
            if g < 0:
                raise ValueError(f"ThermalNetwork: link ({a}, {b}) has negative conductance {g}")

    def index(self, node: str) -> int:
        """Return the position of ``node`` in :attr:`nodes`."""
        try:
            return self.nodes.index(node)
        except ValueError:
            raise KeyError(f"unknown node '{node}'; nodes are {self.nodes}") from None

    @property
    def capacities(self) -> np.ndarray:
        """Heat capacities, ndarray of shape (n,), J/K."""
        return np.asarray(self.capacity_j_per_k, dtype=float)

    @property
    def convection(self) -> np.ndarray:
        """Convection conductances to ambient, ndarray of shape (n,), W/K."""
        return np.asarray(self.convection_w_per_k, dtype=float)

    def conductance_matrix(self) -> np.ndarray:
        """Return K, ndarray of shape (n, n), W/K: link Laplacian plus diag(convection)."""
        n = len(self.nodes)
        K = np.diag(self.convection.copy())
        for a, b, g in self.links:
            i, j = self.index(a), self.index(b)
            K[i, i] += g
            K[j, j] += g
            K[i, j] -= g
            K[j, i] -= g
        return K.reshape(n, n)

    def steady_state(self, heat_W: np.ndarray, ambient_degC: float) -> np.ndarray:
        """Solve ``K T = q + h T_amb`` (constant heat and ambient), degC, shape (n,)."""
        q = np.asarray(heat_W, dtype=float)
        return np.linalg.solve(self.conductance_matrix(), q + self.convection * ambient_degC)

    def with_capacity(self, node: str, value_J_per_K: float) -> ThermalNetwork:
        """Return a copy with the heat capacity of ``node`` set to ``value_J_per_K``."""
        caps = list(self.capacity_j_per_k)
        caps[self.index(node)] = float(value_J_per_K)
        return replace(self, capacity_j_per_k=tuple(caps))

    def with_convection(self, node: str, value_W_per_K: float) -> ThermalNetwork:
        """Return a copy with the convection conductance of ``node`` set, W/K."""
        conv = list(self.convection_w_per_k)
        conv[self.index(node)] = float(value_W_per_K)
        return replace(self, convection_w_per_k=tuple(conv))

    def with_link(self, node_a: str, node_b: str, value_W_per_K: float) -> ThermalNetwork:
        """Return a copy with the conductance between two nodes set (added if absent), W/K."""
        self.index(node_a), self.index(node_b)
        pair = {node_a, node_b}
        links = [lk for lk in self.links if {lk[0], lk[1]} != pair]
        links.append((node_a, node_b, float(value_W_per_K)))
        return replace(self, links=tuple(links))


@dataclass(frozen=True)
class LinearSystem:
    """State-space form ``dx/dt = A x + B u`` of a network plus optional sensor-lag states.

    Attributes
    ----------
    A : ndarray of shape (n_states, n_states), 1/s
    B : ndarray of shape (n_states, n_inputs)
        Inputs are ``u = [T_amb (degC), q_1 .. q_{n_q}]`` (node heats in W unless
        :func:`build_system` was given another ``heat_input``).
    """

    A: np.ndarray
    B: np.ndarray


def build_system(
    network: ThermalNetwork,
    sensor_nodes: tuple[int, ...] = (),
    sensor_tau_s: tuple[float, ...] = (),
    heat_input: np.ndarray | None = None,
) -> LinearSystem:
    """Assemble the state-space matrices of the network and of first-order sensor lags.

    Parameters
    ----------
    network : ThermalNetwork
        The n-node network.
    sensor_nodes : tuple of int
        For each lagged sensor, the node it reads (0..n-1) or -1 for the ambient air.
    sensor_tau_s : tuple of float
        Time constant of each lagged sensor, s (> 0): ``tau dS/dt = T_node - S``.
    heat_input : ndarray of shape (n, n_q), optional
        Rate of temperature rise of each node per unit of each heat input, K/s per unit
        (column j: the share of input j each node receives, in W per unit, divided by the
        node's heat capacity). None = ``diag(1 / C)``: the heat inputs are the node heats, W.

    Returns
    -------
    LinearSystem
        States ``[T_1..T_n, S_1..S_m]``, inputs ``[T_amb, q_1..q_{n_q}]``.
    """
    n = len(network.nodes)
    m = len(sensor_nodes)
    if len(sensor_tau_s) != m:
        raise ValueError("build_system: give one time constant per lagged sensor")
    cinv = 1.0 / network.capacities
    heat = np.diag(cinv) if heat_input is None else np.asarray(heat_input, dtype=float)
    if heat.ndim != 2 or heat.shape[0] != n:
        raise ValueError(
            f"build_system: heat_input has shape {heat.shape}; give one row per node ({n})"
        )
    A = np.zeros((n + m, n + m))
    B = np.zeros((n + m, 1 + heat.shape[1]))
    A[:n, :n] = -cinv[:, None] * network.conductance_matrix()
    B[:n, 0] = cinv * network.convection
    B[:n, 1:] = heat
    for k, (node, tau) in enumerate(zip(sensor_nodes, sensor_tau_s, strict=True)):
        if tau <= 0:
            raise ValueError(f"build_system: sensor time constant must be > 0 s, got {tau}")
        A[n + k, n + k] = -1.0 / tau
        if node < 0:
            B[n + k, 0] = 1.0 / tau
        else:
            A[n + k, node] = 1.0 / tau
    return LinearSystem(A=A, B=B)

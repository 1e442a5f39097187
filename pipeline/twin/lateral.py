"""X and Y thermal drift of the spindle nose (workshop preset only).

The demo twin computes the Z drift only (:mod:`pipeline.twin.effects`). A three-probe drift test
also sees the spindle nose move sideways; this module adds the lateral terms a machine-tool
engineer expects on a vertical machining centre whose spindle motor sits on one side of the
headstock. Coordinates and signs follow ISO 841 for the tool relative to the workpiece: +X to
the right seen from the operator (the motor side), +Y towards the column, +Z up, away from the
table. Every term is computed from the node temperature rises since the start of the run,
``rise_K`` of shape (n_t, n_nodes), and returns micrometres.

Y terms
-------
``headstock_expansion``
    The headstock is clamped to the Z carriage on the column guideways and carries the spindle
    ``d`` = ``SpindleParams.spindle_overhang_mm`` (300 mm) in front of them; its free growth
    pushes the spindle axis towards the operator: ``y = -1e3 alpha_ci d dT_head``, about
    -3.2 um/K.
``column_bending``
    A column whose front face (heated by the headstock) is warmer than its rear bends like a
    bimetal: curvature ``k = alpha_ci (dT_cf - dT_cr) / W`` (``W`` the front-rear distance of
    the sensor planes, ``column_depth_mm``). At the head's height ``h`` the column has moved
    back by ``k h^2 / 2`` and tilted back by ``k h``; the nose, ``l`` below the head's
    carriage centre, swings forward by ``k h l``: ``y = 1e3 k h (h / 2 - l)``, about +4 um/K of
    front-rear difference with h = 700 mm (``column_height_mm``), l = 120 mm. The same bending
    gives the demo's Z term ``thermal_bending``; it is switched with that effect.

X terms
-------
``motor_side_bending``
    The motor flange heats the headstock wall on the motor side: that wall runs warmer than the
    opposite one by a share ``s`` of the motor's excess over the headstock, ``dT_lr = s (dT_motor
    - dT_head)``. The headstock (width ``B`` across X) bends with its hot side convex, so its
    lower end, ``L`` below the motor, moves away from the motor: ``x = -1e3 alpha_ci dT_lr L^2 /
    (2 B)``, about -3.3 um/K of wall difference with L = 450 mm, B = 320 mm.
``spindle_offset``
    The spindle axis sits ``e`` off the X datum of the headstock (the key on the Z carriage at
    the centre of the guideways); the headstock's growth moves it by ``x = 1e3 alpha_ci e
    dT_head``; ``e = -50 mm`` (the spindle sits on the side away from the motor, balancing its
    mass) gives about -0.5 um/K.

All lengths and the share ``s`` are engineering estimates for a 450-500 mm travel vertical
machining centre (Leaderway V450 size, the machine of Miao et al. 2016, the PCDL paper), not values
from a drawing or a measurement; the mechanisms are the textbook ones (thermal bending of the
column, asymmetric heat sources, offset of the spindle axis from the thermal datum). With the
twin's temperatures they give X within about 10 um and Y within about 25 um over a two-day run,
smaller than Z (tens of um), as usual on a vertical machining centre.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from pipeline.twin.params import ALPHA_CAST_IRON_PER_K, SpindleParams


@dataclass(frozen=True)
class LateralParams:
    """Geometry of the lateral (X, Y) drift terms; lengths in mm.

    Attributes
    ----------
    alpha_cast_iron_per_k : float
        Expansion coefficient of the headstock and column, 1/K.
    nose_below_head_mm : float
        Vertical distance from the head's carriage centre on the column to the spindle nose,
        mm (``column_bending``).
    motor_wall_share : float
        Share ``s`` of the motor's temperature excess over the headstock carried by the
        motor-side wall, 0..1 (``motor_side_bending``).
    headstock_width_mm : float
        Width ``B`` of the headstock across X, mm.
    headstock_bend_length_mm : float
        Length ``L`` from the motor flange down to the spindle nose, mm.
    spindle_offset_x_mm : float
        Signed X position ``e`` of the spindle axis relative to the headstock's X datum, mm
        (negative = away from the motor side).
    """

    alpha_cast_iron_per_k: float = ALPHA_CAST_IRON_PER_K
    nose_below_head_mm: float = 120.0
    motor_wall_share: float = 0.35
    headstock_width_mm: float = 320.0
    headstock_bend_length_mm: float = 450.0
    spindle_offset_x_mm: float = -50.0


LateralFunc = Callable[[SpindleParams, LateralParams, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class LateralTerm:
    """One lateral drift term.

    Attributes
    ----------
    name : str
        Identifier; names the ``<axis>_<name>_um`` column of the output.
    axis : str
        ``"X"`` or ``"Y"``.
    description : str
        What it is, in a machine-tool engineer's words.
    func : callable ``(params, lateral, rise_K) -> ndarray of shape (n_t,)``, um
    effect : str or None
        Effect of :data:`pipeline.thermal.effects.EFFECTS` that switches it (None = always on).
    """

    name: str
    axis: str
    description: str
    func: LateralFunc
    effect: str | None = None


def _rise(params: SpindleParams, rise_K: np.ndarray, node: str) -> np.ndarray:
    return rise_K[:, params.network.index(node)]


def headstock_y_expansion(
    params: SpindleParams, lateral: LateralParams, rise_K: np.ndarray
) -> np.ndarray:
    """Headstock growth between the guideways and the spindle axis, um (towards the operator).

    ``y = -1e3 alpha_ci d dT_head``, d = ``params.spindle_overhang_mm``.
    """
    d = params.spindle_overhang_mm
    return -1e3 * lateral.alpha_cast_iron_per_k * d * _rise(params, rise_K, "headstock")


def column_bending_y(
    params: SpindleParams, lateral: LateralParams, rise_K: np.ndarray
) -> np.ndarray:
    """Column bending from its front-rear difference, seen at the nose in Y, um.

    ``y = 1e3 alpha_ci (dT_cf - dT_cr) / W * h (h / 2 - l)`` with W = ``column_depth_mm``,
    h = ``column_height_mm``, l = ``lateral.nose_below_head_mm``.
    """
    diff = _rise(params, rise_K, "column_front") - _rise(params, rise_K, "column_rear")
    curvature = lateral.alpha_cast_iron_per_k * diff / params.column_depth_mm  # 1/mm
    h = params.column_height_mm
    return 1e3 * curvature * h * (0.5 * h - lateral.nose_below_head_mm)


def motor_side_bending_x(
    params: SpindleParams, lateral: LateralParams, rise_K: np.ndarray
) -> np.ndarray:
    """Headstock bending away from the motor-side wall, um.

    ``x = -1e3 alpha_ci s (dT_motor - dT_head) L^2 / (2 B)``.
    """
    wall = lateral.motor_wall_share * (
        _rise(params, rise_K, "motor") - _rise(params, rise_K, "headstock")
    )
    length = lateral.headstock_bend_length_mm
    return (
        -1e3 * lateral.alpha_cast_iron_per_k * wall * length**2 / (2.0 * lateral.headstock_width_mm)
    )


def spindle_offset_x(
    params: SpindleParams, lateral: LateralParams, rise_K: np.ndarray
) -> np.ndarray:
    """Headstock growth between its X datum and the off-centre spindle axis, um.

    ``x = 1e3 alpha_ci e dT_head``, e = ``lateral.spindle_offset_x_mm``.
    """
    e = lateral.spindle_offset_x_mm
    return 1e3 * lateral.alpha_cast_iron_per_k * e * _rise(params, rise_K, "headstock")


LATERAL_TERMS = (
    LateralTerm(
        "headstock_expansion",
        "Y",
        "headstock growth pushes the spindle axis away from the column",
        headstock_y_expansion,
    ),
    LateralTerm(
        "column_bending",
        "Y",
        "column bent by its front-rear difference moves and tilts the head",
        column_bending_y,
        effect="thermal_bending",
    ),
    LateralTerm(
        "motor_side_bending",
        "X",
        "headstock bent by the warm motor-side wall",
        motor_side_bending_x,
    ),
    LateralTerm(
        "spindle_offset",
        "X",
        "headstock growth moves the off-centre spindle axis sideways",
        spindle_offset_x,
    ),
)
"""The lateral terms, in output order."""


def lateral_drift(
    params: SpindleParams,
    lateral: LateralParams,
    rise_K: np.ndarray,
    effects: Iterable[str],
) -> dict[str, np.ndarray]:
    """Evaluate the lateral terms switched on by ``effects``.

    Parameters
    ----------
    params : SpindleParams
        Network and the geometry shared with the Z terms.
    lateral : LateralParams
    rise_K : ndarray of shape (n_t, n_nodes), K
        Node temperatures minus their values at the start of the run.
    effects : iterable of str
        Effects on; a term with an ``effect`` is left out unless it is listed.

    Returns
    -------
    dict of str to ndarray of shape (n_t,), um
        ``x_<term>_um`` and ``y_<term>_um`` per term on, and their sums ``x_um``, ``y_um``.
    """
    names = frozenset(effects)
    n_t = rise_K.shape[0]
    parts: dict[str, np.ndarray] = {}
    totals = {"X": np.zeros(n_t), "Y": np.zeros(n_t)}
    for term in LATERAL_TERMS:
        if term.effect is not None and term.effect not in names:
            continue
        value = np.asarray(term.func(params, lateral, rise_K), dtype=float)
        parts[f"{term.axis.lower()}_{term.name}_um"] = value
        totals[term.axis] = totals[term.axis] + value
    return {**parts, "x_um": totals["X"], "y_um": totals["Y"]}

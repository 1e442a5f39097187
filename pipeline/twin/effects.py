"""The generator's physical terms: the fixed demo machine's law for each term of the registry.

The registry of effects, the slots and the baseline of each machine are the kernel's
(:mod:`pipeline.thermal.effects`); this module implements every term it names for the
generator's parameters (:class:`~pipeline.twin.params.SpindleParams`,
:class:`~pipeline.twin.params.AxisParams`). The signature of ``func`` in each slot:

``heat``
    ``func(params, drive) -> ndarray (k, n_nodes)``, W, for each value of the drive (spindle
    rpm or axis feed mm/s).
``ambient``
    ``func(ambient, t_s) -> ndarray (k,)``, degC.
``displacement``
    ``func(params, rise_K, drive) -> ndarray (n_t,)``, um, from the node temperature rises
    ``rise_K`` (n_t, n_nodes) since the start.
``sensor``
    ``func(params) -> float or tuple of float``, s: one time constant for all sensors or one
    per sensor of ``params.sensors``; 0 = reads its node directly.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from pipeline.thermal.effects import Term, term_names

# --------------------------------------------------------------------------- heat terms


def _rate(drive: np.ndarray, reference: float) -> np.ndarray:
    return np.abs(np.asarray(drive, dtype=float)) / reference


def _bearing_heat(params: Any, rpm: np.ndarray, exponent: float) -> np.ndarray:
    net = params.network
    r = _rate(rpm, params.reference_rpm) ** exponent
    total = (params.front_bearing_heat_w + params.rear_bearing_heat_w) * r
    housing = 1.0 - params.bearing_heat_to_shaft
    q = np.zeros((r.size, len(net.nodes)))
    q[:, net.index("front_bearing")] = housing * params.front_bearing_heat_w * r
    q[:, net.index("rear_bearing")] = housing * params.rear_bearing_heat_w * r
    q[:, net.index("spindle_shaft")] = params.bearing_heat_to_shaft * total
    return q


def bearing_friction_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Front/rear bearing friction ``q = Q_ref * rpm / rpm_ref``, W, shape (k, n_nodes).

    A fraction ``bearing_heat_to_shaft`` enters the shaft through the inner rings, the rest
    the bearing housings.
    """
    return _bearing_heat(params, rpm, 1.0)


def nonlinear_bearing_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Bearing friction ``q = Q_ref * (rpm / rpm_ref)^a`` (Palmgren a = 5/3), W."""
    return _bearing_heat(params, rpm, params.bearing_heat_exponent)


def motor_heat(params: Any, rpm: np.ndarray) -> np.ndarray:
    """Spindle-motor loss ``q = Q_motor * rpm / rpm_ref`` into the motor node, W."""
    net = params.network
    q = np.zeros((np.size(rpm), len(net.nodes)))
    q[:, net.index("motor")] = params.motor_heat_w * _rate(rpm, params.reference_rpm)
    return q


def axis_friction_heat(params: Any, feed: np.ndarray) -> np.ndarray:
    """Nut, fixed-bearing, servo-motor and guideway losses proportional to feed, W."""
    net = params.network
    r = _rate(feed, params.reference_feed_mm_s)
    q = np.zeros((r.size, len(net.nodes)))
    q[:, net.index("nut")] = params.nut_heat_w * r
    q[:, net.index("screw_bearing")] = params.bearing_heat_w * r
    q[:, net.index("motor")] = params.motor_heat_w * r
    q[:, net.index("carriage")] = params.guideway_heat_w * r
    return q


# ------------------------------------------------------------------------ ambient terms


def constant_ambient(ambient: Any, t_s: np.ndarray) -> np.ndarray:
    """Air held at its value at the campaign start, degC."""
    return np.full(np.shape(t_s), float(ambient.at(0.0)))


def varying_ambient(ambient: Any, t_s: np.ndarray) -> np.ndarray:
    """Air following its season mean and daily cycle (or the given series), degC."""
    return np.asarray(ambient.at(t_s), dtype=float)


# ------------------------------------------------------------------- displacement terms


def uniform_expansion(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Free expansion of spindle shaft, headstock, Z screw (down) and column (up), um.

    ``z = 1e3 [alpha_ci H (dT_cf + dT_cr)/2 - alpha_s L_sp dT_shaft - alpha_ci L_hs dT_head
    - alpha_s L_zs dT_zscrew]`` with lengths in mm.
    """
    net = params.network
    col = 0.5 * (rise_K[:, net.index("column_front")] + rise_K[:, net.index("column_rear")])
    up = params.alpha_cast_iron_per_k * params.column_height_mm * col
    down = (
        params.alpha_steel_per_k * params.spindle_length_mm * rise_K[:, net.index("spindle_shaft")]
        + params.alpha_cast_iron_per_k
        * params.headstock_length_mm
        * rise_K[:, net.index("headstock")]
        + params.alpha_steel_per_k * params.z_screw_length_mm * rise_K[:, net.index("z_screw")]
    )
    return 1e3 * (up - down)


def thermal_bending(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Column bending from its front-rear temperature difference, seen at the nose, um.

    A front face warmer than the rear tilts the column top backwards by ``alpha H dT / W``
    rad; the nose, ``d`` in front of the column, rises: ``z = 1e3 alpha H d / W (dT_cf -
    dT_cr)`` (rises since the start, so the initial gradient gives no drift).
    """
    net = params.network
    diff = rise_K[:, net.index("column_front")] - rise_K[:, net.index("column_rear")]
    gain = (
        params.alpha_cast_iron_per_k
        * params.column_height_mm
        * params.spindle_overhang_mm
        / params.column_depth_mm
    )
    return 1e3 * gain * diff


def centrifugal_growth(params: Any, rise_K: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Instantaneous nose shift ``z = z_ref (rpm / rpm_ref)^2``, um (no thermal lag)."""
    return params.centrifugal_um * (np.asarray(rpm, dtype=float) / params.reference_rpm) ** 2


# ------------------------------------------------------------------------- sensor terms


def direct_sensors(params: Any) -> float:
    """Sensors read their node's temperature directly (time constant 0)."""
    return 0.0


def lagged_sensors(params: Any) -> tuple[float, ...]:
    """Each sensor reads its node through a first-order lag, s, one value per sensor.

    ``tau dS/dt = T_node - S``: a sensor glued, screwed or magnet-mounted on a surface reads
    the local skin of the part through the contact resistance and its own housing, and the
    skin follows the bulk of the lumped node with a delay. The time constant is the sensor's
    ``tau_s`` (set by its mounting) or, when that is None, the machine's ``sensor_tau_s``.
    """
    return tuple(float(params.sensor_tau_s if s.tau_s is None else s.tau_s) for s in params.sensors)


# -------------------------------------------------------------------------------- terms

TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        Term(
            "bearing_friction_heat",
            "heat",
            "friction heat in the front and rear spindle bearings, proportional to speed",
            bearing_friction_heat,
        ),
        Term(
            "nonlinear_bearing_heat",
            "heat",
            "bearing friction heat ~ rpm^a",
            nonlinear_bearing_heat,
        ),
        Term("motor_heat", "heat", "spindle-motor loss", motor_heat),
        Term(
            "axis_friction_heat",
            "heat",
            "nut, fixed-bearing, servo-motor and guideway losses, proportional to feed",
            axis_friction_heat,
        ),
        Term(
            "constant_ambient",
            "ambient",
            "workshop air constant at its value at the start",
            constant_ambient,
        ),
        Term("varying_ambient", "ambient", "time-varying workshop air", varying_ambient),
        Term(
            "uniform_expansion",
            "displacement",
            "uniform thermal expansion of spindle, headstock, Z screw and column",
            uniform_expansion,
        ),
        Term("thermal_bending", "displacement", "column thermal bending", thermal_bending),
        Term("centrifugal_growth", "displacement", "centrifugal growth", centrifugal_growth),
        Term("direct_sensors", "sensor", "sensors read the structure directly", direct_sensors),
        Term("lagged_sensors", "sensor", "first-order sensor lag", lagged_sensors),
    )
}
"""The generator's implementation of every term the registry names."""

DEMO_EFFECTS = frozenset(
    {"ambient_variation", "motor_heat", "nonlinear_bearing_heat", "sensor_lag", "thermal_bending"}
)
"""Effects switched on in the demo campaigns (never written to the campaign files)."""


def model_terms(machine: str, effects: Iterable[str]) -> tuple[Term, ...]:
    """Assemble the generator's terms of ``machine`` with the given effects switched on.

    Parameters
    ----------
    machine : str
        ``"spindle"`` or ``"axis"``.
    effects : iterable of str
        Effect names from :data:`pipeline.thermal.effects.EFFECTS`.

    Returns
    -------
    tuple of Term
        In the order of :func:`pipeline.thermal.effects.term_names`.
    """
    return tuple(TERMS[name] for name in term_names(machine, effects))

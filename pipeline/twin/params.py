"""All parameters of the physical twin, in one place, as frozen dataclasses.

Change a value with :func:`dataclasses.replace` (and :meth:`ThermalNetwork.with_link` etc. for
the network); nothing here is mutated by the simulation. Magnitudes are chosen so that the demo
campaigns look like the sources:

* the PCDL paper (Miao Enming, Liu Yi, Dong Yunfei and Chen Weikang, 2016, "Improvement of
  forecasting robustness of time series model for thermal error on CNC machine tool", Optics
  and Precision Engineering 24(10), 2480-2489): Leaderway V450 vertical machining centre,
  spindle Z drift at 2000/4000/6000 rpm, 3-min sampling for more than 4 h, DS18B20 sensors
  (+-0.2 degC, 0.0625 degC resolution), eddy-current probe (+-0.5 um), 12 seasonal batches plus
  6 validation batches (October, December);
* the linear-axis patent (Chinese invention patent "Optimal selection method for the thermal
  temperature-sensitive points of a machine tool's linear axis based on independent-variable
  selection criteria", published 2022): Y axis, 280 mm stroke measured every 10 mm in both
  directions by a laser interferometer at 0/20/50/110/190/340/390 min of warm-up (20 mm/s,
  10 mm/s^2), 7 PT100 sensors every 10 min, a 4th-order geometric polynomial and a thermal
  slope k(T) in um/mm.

Typical values reached: 2-15 K temperature rise, 10-60 um Z drift in 4 h, axis slopes up to
~0.08 um/mm (screw rise x 0.0115 um/(mm K)).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pipeline.thermal.network import ThermalNetwork

ALPHA_STEEL_PER_K = 11.5e-6
"""Linear expansion coefficient of steel (spindle, ball screws), 1/K."""
ALPHA_CAST_IRON_PER_K = 10.5e-6
"""Linear expansion coefficient of grey cast iron (headstock, column, bed), 1/K."""


@dataclass(frozen=True)
class SensorSpec:
    """One temperature sensor as mounted on the machine.

    Attributes
    ----------
    name : str
        Column name in temperature.csv (``"T1"``...).
    role : str
        Contract role (closed vocabulary, e.g. ``"spindle_front_bearing"``, ``"ambient"``).
    location : str
        Where it is glued, in words.
    node : str
        Network node it reads, or ``"ambient"`` for the air.
    type : str
        Sensor model written to campaign.yaml (``"DS18B20"``, ``"PT100"``).
    offset_degc : float
        Fixed calibration offset of this sensor, degC (within its accuracy class).
    tau_s : float or None
        First-order time constant through which this sensor reads its node when
        ``sensor_lag`` is on, s (set by how it is mounted); None = the machine's
        ``sensor_tau_s``.
    """

    name: str
    role: str
    location: str
    node: str
    type: str
    offset_degc: float = 0.0
    tau_s: float | None = None


@dataclass(frozen=True)
class SensorNoise:
    """Reading chain of a temperature sensor type.

    Attributes
    ----------
    resolution_degc : float
        Quantisation step, degC (DS18B20 at 12 bit: 0.0625).
    noise_sd_degc : float
        Standard deviation of the white reading noise, degC.
    """

    resolution_degc: float
    noise_sd_degc: float


DS18B20 = SensorNoise(resolution_degc=0.0625, noise_sd_degc=0.03)
"""DS18B20 digital sensor (PCDL paper: accuracy +-0.2 degC, resolution 0.0625 degC); the
+-0.2 degC accuracy is the per-sensor ``offset_degc``."""
PT100_CLASS_A = SensorNoise(resolution_degc=0.01, noise_sd_degc=0.02)
"""PT100 class A with a 0.01 degC recorder (the patent's sensors); accuracy +-0.15 degC is the
per-sensor ``offset_degc``."""


def _spindle_network() -> ThermalNetwork:
    nodes = (
        "front_bearing",  # front angular-contact bearing set and its housing, ~9 kg steel
        "rear_bearing",  # rear bearing and housing, ~5 kg
        "spindle_shaft",  # rotating shaft, ~13 kg: no sensor can be glued on it
        "spindle_sleeve",  # cartridge sleeve around the shaft, between the bearings, ~22 kg
        "motor",  # spindle motor on top of the headstock, ~45 kg
        "headstock",  # cast-iron headstock / Z slide, ~180 kg
        "column_front",  # front half of the column (guideway side), ~500 kg
        "column_rear",  # rear half of the column, ~500 kg
        "bed",  # bed / base, ~2000 kg
        "z_screw",  # Z ball screw, nut and support bearings, ~12 kg
    )
    capacity = (4.0e3, 2.5e3, 6.0e3, 1.0e4, 2.0e4, 9.0e4, 2.5e5, 2.5e5, 1.0e6, 6.0e3)
    convection = (0.8, 0.4, 1.5, 0.8, 4.0, 5.0, 8.0, 8.0, 20.0, 1.0)
    links = (
        ("front_bearing", "spindle_shaft", 3.0),
        ("rear_bearing", "spindle_shaft", 2.0),
        ("spindle_shaft", "spindle_sleeve", 1.0),
        ("front_bearing", "spindle_sleeve", 6.0),
        ("rear_bearing", "spindle_sleeve", 4.0),
        ("front_bearing", "headstock", 8.0),
        ("rear_bearing", "headstock", 5.0),
        ("spindle_sleeve", "headstock", 6.0),
        ("motor", "headstock", 3.0),
        ("headstock", "column_front", 10.0),
        ("headstock", "z_screw", 1.5),
        ("z_screw", "column_front", 2.0),
        ("column_front", "column_rear", 15.0),
        ("column_front", "bed", 10.0),
        ("column_rear", "bed", 10.0),
    )
    return ThermalNetwork(nodes, capacity, convection, links)


def _spindle_sensors() -> tuple[SensorSpec, ...]:
    # last column: first-order time constant of the mounting, s (``sensor_lag``): a sensor
    # screwed into a housing reads within minutes, one on an adhesive pad on a thick cast
    # wall reads the bulk of the part ~15-20 min late, the air probe sits in a steel sheath
    rows = (
        ("T1", "spindle_front_bearing", "front bearing housing", "front_bearing", 0.12, 240.0),
        ("T2", "spindle_rear_bearing", "rear bearing housing", "rear_bearing", -0.08, 300.0),
        ("T3", "spindle_motor", "spindle motor casing", "motor", 0.15, 480.0),
        ("T4", "headstock", "headstock side wall", "headstock", -0.17, 720.0),
        (
            "T5",
            "column_front",
            "column front face, below the Z guideways",
            "column_front",
            0.05,
            900.0,
        ),
        ("T6", "column_rear", "column rear face", "column_rear", 0.19, 900.0),
        ("T7", "bed", "bed, under the column", "bed", -0.11, 1200.0),
        ("T8", "ball_screw", "Z ball-screw nut housing", "z_screw", 0.03, 360.0),
        ("T9", "other", "spindle cartridge sleeve, near the nose", "spindle_sleeve", -0.14, 300.0),
        ("T10", "ambient", "workshop air, 1 m from the machine", "ambient", 0.07, 480.0),
    )
    return tuple(
        SensorSpec(n, r, loc, node, "DS18B20", off, tau) for n, r, loc, node, off, tau in rows
    )


@dataclass(frozen=True)
class SpindleParams:
    """Physical twin of the spindle Z drift of a vertical machining centre.

    Modelled on the PCDL paper's Leaderway V450 (Miao et al. 2016): spindle at 2000-6000 rpm,
    10 DS18B20 sensors, eddy-current probe at the spindle nose. Sign of ``z``: positive = tool
    moves away from the table (the raw contract).

    Attributes
    ----------
    network : ThermalNetwork
        Nodes ``front_bearing, rear_bearing, spindle_shaft, spindle_sleeve, motor, headstock,
        column_front, column_rear, bed, z_screw``; capacities J/K, conductances W/K. The
        rotating shaft carries no sensor: the spindle growth is not measured directly.
    reference_rpm : float
        Speed at which the heat and centrifugal magnitudes below are given, rpm.
    front_bearing_heat_w, rear_bearing_heat_w : float
        Bearing friction power at ``reference_rpm``, W. Baseline law: proportional to speed.
        Chosen with ``nonlinear_bearing_heat`` on (the demo) so that the drift stays within
        10-60 um at 2000-6000 rpm.
    bearing_heat_to_shaft : float
        Fraction of the bearing friction heat that enters the shaft through the inner rings
        (the rest heats the bearing housings), 0..1.
    bearing_heat_exponent : float
        Exponent a of ``q ~ rpm^a`` when ``nonlinear_bearing_heat`` is on (Palmgren: friction
        torque ~ (nu n)^(2/3), power ~ n^(5/3)); equal heat at ``reference_rpm``.
    motor_heat_w : float
        Spindle-motor loss at ``reference_rpm``, W, proportional to speed (``motor_heat``).
    spindle_length_mm : float
        Effective length of the spindle shaft between its axial fix and the nose, mm; its
        expansion (shaft temperature) moves the tool towards the table (negative z).
    headstock_length_mm : float
        Headstock length between the Z nut bracket and the front bearing, mm (negative z).
    column_height_mm : float
        Column height carrying the Z screw's fixed bearing, mm; its growth lifts the head
        (positive z).
    z_screw_length_mm : float
        Z ball-screw length between its fixed (top) bearing and the nut, mm (negative z;
        semi-closed loop).
    column_depth_mm : float
        Distance between the column front and rear sensor planes, mm (``thermal_bending``).
    spindle_overhang_mm : float
        Horizontal distance from the column front face to the spindle axis, mm.
    centrifugal_um : float
        Instantaneous Z shift of the nose at ``reference_rpm`` from centrifugal and bearing
        contact-angle effects, um (``centrifugal_growth``; scales with rpm^2).
    sensor_tau_s : float
        First-order time constant of a glued sensor without its own ``tau_s``, s
        (``sensor_lag``).
    sensors : tuple of SensorSpec
        T1..T10, each with its contract role, the node it reads and the time constant of its
        mounting (4 min screwed into a bearing housing ... 20 min on an adhesive pad on the
        bed).
    probe_noise_um : float
        Standard deviation of the eddy-current probe noise, um (PCDL paper: +-0.5 um).
    heat_scatter_rel : float
        Relative standard deviation of the bearing/motor heat from one campaign to the next,
        applied by the campaign generator (not by the simulation) to a plan without a state
        scatter; the demo plans draw a full machine state instead
        (:mod:`pipeline.twin.conditions`).
    """

    network: ThermalNetwork = field(default_factory=_spindle_network)
    reference_rpm: float = 4000.0
    front_bearing_heat_w: float = 37.0
    rear_bearing_heat_w: float = 18.5
    bearing_heat_to_shaft: float = 0.4
    bearing_heat_exponent: float = 5.0 / 3.0
    motor_heat_w: float = 35.0
    alpha_steel_per_k: float = ALPHA_STEEL_PER_K
    alpha_cast_iron_per_k: float = ALPHA_CAST_IRON_PER_K
    spindle_length_mm: float = 240.0
    headstock_length_mm: float = 200.0
    column_height_mm: float = 700.0
    z_screw_length_mm: float = 400.0
    column_depth_mm: float = 400.0
    spindle_overhang_mm: float = 300.0
    centrifugal_um: float = -1.5
    sensor_tau_s: float = 240.0
    sensors: tuple[SensorSpec, ...] = field(default_factory=_spindle_sensors)
    probe_noise_um: float = 0.2
    heat_scatter_rel: float = 0.05


def _axis_network() -> ThermalNetwork:
    nodes = (
        "screw",  # Y ball screw shaft, d 32 mm x 500 mm, ~3.2 kg
        "nut",  # ball nut and its bracket, ~3 kg
        "screw_bearing",  # fixed-end support bearing block at the motor end, ~3 kg
        "motor",  # Y servo motor, ~8 kg
        "carriage",  # saddle / table running on the Y guideways, ~80 kg
        "bed",  # bed carrying rails and bearing blocks, ~600 kg
    )
    capacity = (1.5e3, 1.5e3, 1.5e3, 4.0e3, 4.0e4, 3.0e5)
    convection = (0.5, 0.3, 0.4, 1.5, 2.0, 10.0)
    links = (
        ("nut", "screw", 3.0),
        ("nut", "carriage", 3.0),
        ("screw", "screw_bearing", 1.0),
        ("screw_bearing", "bed", 2.0),
        ("motor", "screw_bearing", 1.0),
        ("motor", "bed", 1.0),
        ("carriage", "bed", 1.0),
    )
    return ThermalNetwork(nodes, capacity, convection, links)


def _axis_sensors() -> tuple[SensorSpec, ...]:
    rows = (
        ("T1", "ball_screw", "Y ball screw, near the fixed end", "screw", 0.06),
        ("T2", "nut", "ball-nut bracket", "nut", -0.09),
        ("T3", "other", "fixed-end bearing block", "screw_bearing", 0.11),
        ("T4", "other", "Y servo motor casing", "motor", -0.04),
        ("T5", "bed", "bed, between the Y rails", "bed", 0.08),
        ("T6", "other", "saddle, above the nut", "carriage", -0.12),
        ("T7", "ambient", "workshop air beside the machine", "ambient", 0.02),
    )
    return tuple(SensorSpec(n, r, loc, node, "PT100", off) for n, r, loc, node, off in rows)


@dataclass(frozen=True)
class AxisParams:
    """Physical twin of a linear axis (Y) positioning error, after the linear-axis patent.

    Positioning deviation at target x (mm) of pass p, direction d = +-1::

        e = poly(x) + P sin(2 pi x / lambda + phi) + d B / 2 + k(t_p) x + b(t_p) + noise
        k = alpha_steel * (T_screw(t) - T_screw(0))            # um/mm, ~0.0115 um/(mm K)
        b = alpha_steel * L_b * (T_bearing(t) - T_bearing(0))  # um

    The screw is fixed at the motor end (x = 0) and the loop is semi-closed (rotary encoder), so
    the screw's expansion appears in full as a slope.

    Attributes
    ----------
    network : ThermalNetwork
        Nodes ``screw, nut, screw_bearing, motor, carriage, bed``.
    reference_feed_mm_s : float
        Feed at which the heat values are given (the patent's 20 mm/s warm-up), mm/s.
    nut_heat_w, bearing_heat_w, motor_heat_w, guideway_heat_w : float
        Friction/loss power at ``reference_feed_mm_s`` into nut, fixed-end bearing, servo motor
        and carriage (rails), W; proportional to feed.
    alpha_steel_per_k : float
        Expansion coefficient of the screw, 1/K (slope per kelvin = 1e-3 alpha um/(mm K)).
    bearing_offset_length_mm : float
        Length of the bearing block between the bed datum and the screw's fixed point, mm.
    geometric_coeffs_um : tuple of 5 float
        4th-order geometric polynomial c0..c4 (ascending powers, x in mm, result in um), the
        cold machine's pitch error (the patent's eq. (1) has this form).
    periodic_amplitude_um : float
        Amplitude P of the ball-screw periodic (lead) error, um.
    periodic_period_mm : float
        Its period lambda, mm (the screw lead, 16 mm; sampled every 10 mm it aliases).
    periodic_phase_rad : float
        Its phase phi, rad.
    reversal_um : float
        Reversal (backlash) B between + and - runs, um.
    laser_noise_um : float
        Standard deviation of one interferometer reading, um (repeatability + air).
    stroke_mm, step_mm : float
        Measured stroke and target spacing, mm (patent: 280 and 10).
    sensor_tau_s : float
        First-order time constant of a PT100 probe, s (``sensor_lag``).
    sensors : tuple of SensorSpec
        T1..T7 (PT100), roles ball_screw, nut, other, other, bed, other, ambient.
    """

    network: ThermalNetwork = field(default_factory=_axis_network)
    reference_feed_mm_s: float = 20.0
    nut_heat_w: float = 14.0
    bearing_heat_w: float = 3.0
    motor_heat_w: float = 8.0
    guideway_heat_w: float = 6.0
    alpha_steel_per_k: float = ALPHA_STEEL_PER_K
    bearing_offset_length_mm: float = 40.0
    geometric_coeffs_um: tuple[float, ...] = (1.5, -0.0714, 1.786e-4, 1.2755e-6, -2.928e-9)
    periodic_amplitude_um: float = 0.8
    periodic_period_mm: float = 16.0
    periodic_phase_rad: float = 0.6
    reversal_um: float = 2.5
    laser_noise_um: float = 0.25
    stroke_mm: float = 280.0
    step_mm: float = 10.0
    sensor_tau_s: float = 120.0
    sensors: tuple[SensorSpec, ...] = field(default_factory=_axis_sensors)
    heat_scatter_rel: float = 0.05

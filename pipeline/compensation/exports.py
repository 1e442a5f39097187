"""What machine controllers take: the champion as coefficients, a TEMPCOMP formula, SINUMERIK data.

A fitted candidate that is linear in its inputs is written as a table (:func:`linear_form`):

    e(t) = a0 + sum_i c_i x_i(t - l_i w)

e the predicted thermal error (um), a0 the intercept (um), x_i an input (temperature rise, K;
absolute temperature, degC; speed response, (krpm)^a), l_i its lag in samples of the window w
(``spec.resample_s``, s) and c_i its coefficient (um per unit of the input). From the table:

- ``coefficients.json`` (:func:`coefficients_document`): every number and the definition of
  every input, so a controller or PLC programmer can rebuild the prediction without this code;
- a Heidenhain TNC ``TEMPCOMP`` formula (:func:`tempcomp_formula`) when the model fits its limits;
- the SINUMERIK 840D sl temperature-compensation data of the linear-axis model
  (:func:`sinumerik_mapping`) and of a spindle axis' runtime offset (:func:`spindle_k0_mapping`).

Sign: the prediction is the thermal error itself (spindle drift: positive = tool away from the
table / workpiece, ``docs/data-contract.md``; linear axis: the laser's deviation as its software
reports it). The offset that cancels it is its negative (``params.yaml`` ``compensation.
offset_sign`` -1). The SINUMERIK and TNC entries describe the *error* (see below).

Sources (public copies of the manuals, cited by their printed titles):

- [K3] SINUMERIK 840D sl / 828D, Extended Functions, Function Manual 03/2013 (6FC5397-1BP40-3BA1),
  "K3: Compensations", 4.2 Temperature compensation (also edition 09/2009, 6FC5397-1BP20-0BA0):
  dK_x = K0(T) + tan beta(T) * (P_x - P0); MD32750 $MA_TEMP_COMP_TYPE bit 0 position-independent
  (SD43900), bit 1 position-dependent (SD43910, SD43920), bit 2 in tool direction (MD20390
  $MC_TOOL_TEMP_COMP_ON); MD32760 caps the compensation per IPO cycle and the gradient tan beta;
  worked example: P0 = 320 mm -> SD43920 = 320, MD32750 = 2, tan beta(T) = (T - T0) TK_max 1e-6 /
  (T_max - T0) with TK in um/1000 mm, giving SD43910 = 0.000132: tan beta is dimensionless (mm per
  mm); the error curves are the measured actual-value offsets, so the entries describe the error
  line; "the PLC can acquire and preprocess the temperature profile in a minutes cycle".
- [808D] SINUMERIK 808D ADVANCED, Parameter Manual 08/2013 (6FC5397-8EP40-0BA0): MD32750 is a
  BYTE taking effect at power on, bits 0-2 as above; MD32760 $MA_COMP_ADD_VELO_FACTOR, DOUBLE,
  default 0.01, range 0 to 0.10, a factor of MD32000 $MA_MAX_AX_VELO; a larger change is traversed
  over several IPO cycles without alarm; tan beta_max equals the factor (0.01 -> 0.57 deg).
- [840C] SINUMERIK 840C Installation Instructions 09.95 (6FC5197-.AA50), 12.19.4 Temperature
  compensation TC: "Error K_TC = Machine position - Setpoint, i.e. when K_TC is positive, the
  axis traverses in a negative direction"; K_TCabs and P0 in units of the measuring system.
- [828D P4] SINUMERIK 828D, Basic Functions, Function Manual 09/2011 (6FC5397-0BP40-2BA0), P4: the
  PLC writes TEMP_COMP_REF_POSITION (SD43920) and TOOL_TEMP_COMP (SD42960) as REAL variables.
- [TNC] HEIDENHAIN Technical Manual TNC 426, TNC 430 (December 2001), 6.5.3 Temperature
  compensation with tilting axes: a formula in the TEMPCOMP column of the description table;
  at most 31 characters, at most 16 variables, operations lower case, variables upper case
  (PLC operands, e.g. W486 = a Pt100 temperature); "the variables are monitored every second";
  example ``TEMPCOMP = 300 + 3.45e-3 * (W486 - 20)`` (mm; e-notation accepted); "the algebraic
  sign of the compensation must match that of the axis error compensation in Words W576 to W584".
  Same manual, 6-45: PLC Module 9231 "Compensation of thermal expansion": axis 0-8, value
  -30 000 to +30 000 in 0.1 um. The iTNC 530 HSCI Technical Manual (07/2013), 6.5.3 still names
  the TEMPCOMP column.

Not confirmed in those sources, so stated as assumptions where used: the unit of SD43900 (mm is
assumed, as the example gives SD43920 in mm; the 840C gives "units of the measuring system");
the 840D sl's own statement of the sign (only the 840C's is quoted above: check on the machine
with a small value first); whether SD43900-SD43920 act at once when written; OPC UA node names
of the setting data (not looked up, not given); whether TEMPCOMP holds the whole transformation
value (the example adds the nominal 300 mm) or only its change, and whether the TNC 640 / TNC7
keep the 31-character / 16-variable limits.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from decimal import Decimal

import numpy as np
from sklearn.linear_model import LinearRegression
from sklearn.utils.validation import check_is_fitted

from pipeline.models.ar_reduced import ReducedOrderAR
from pipeline.models.ardl import AutoregressiveDistributedLag
from pipeline.models.arma import ARMAErrorModel
from pipeline.models.distributed_lag import LaggedLinearModel
from pipeline.models.neural import BackPropagationRegressor
from pipeline.models.reference import NoCompensation
from pipeline.models.svr import EmbeddedSVR
from pipeline.models.ts_bp import TimeSeriesBPHybrid
from pipeline.models.tv_ar import TimeVaryingAR
from pipeline.separation.features import InputSpec, is_speed_feature

RISE, ABSOLUTE, SPEED = "temperature_rise", "absolute", "speed_response"
"""Kinds of input: rise since the run's reference (K), reading (degC), speed response."""

TEMPCOMP_MAX_CHARS = 31
TEMPCOMP_MAX_VARIABLES = 16
TEMPCOMP_MIN_DIGITS = 2
"""Fewest significant digits a coefficient keeps (relative rounding error <= 5 %)."""
TEMPCOMP_MAX_DIGITS = 6

UM_PER_MM = 1000.0

SIGN_NOTE = (
    "the value is the predicted thermal error (um): spindle drift positive = tool away from the "
    "table / workpiece (docs/data-contract.md); the offset to apply is its negative, "
    "offset_um = -(intercept_um + sum of coefficient x input)"
)


@dataclass(frozen=True)
class Term:
    """One term of a linear model: ``coefficient * input(t - lag)``.

    Attributes
    ----------
    input : str
        Input name as in ``InputSpec.inputs``: a sensor (its rise or reading) or a speed
        response (``speed_lag_30min``).
    lag : int
        Lag in samples of the model's window (``InputSpec.resample_s``).
    coefficient : float
        um per unit of the input: um/K (rise), um/degC (absolute), um/(krpm)^a (speed).
    kind : str
        ``temperature_rise``, ``absolute`` or ``speed_response``.
    unit : str
        Unit of the input: ``K``, ``degC`` or ``(krpm)^a``.
    """

    input: str
    lag: int
    coefficient: float
    kind: str
    unit: str


@dataclass(frozen=True)
class LinearForm:
    """A fitted model written as ``intercept_um + sum(term.coefficient * input(t - lag))``.

    Attributes
    ----------
    intercept_um : float, um
    terms : tuple of Term
        Sensor-major, lags ascending; zero coefficients are kept (complete table).
    window_s : float or None, s
        Length of one sample (lag unit); None: the training data's own interval.
    """

    intercept_um: float
    terms: tuple[Term, ...]
    window_s: float | None

    @property
    def max_lag(self) -> int:
        """Largest lag (samples), 0 for a static model."""
        return max((t.lag for t in self.terms), default=0)


NOT_LINEAR: tuple[tuple[type, str], ...] = (
    (
        TimeSeriesBPHybrid,
        "TS-BP hybrid: a weighted sum of a BP neural network (sigmoid hidden layer) and an ARMA "
        "model of the error's own history; neither part is a linear function of the inputs",
    ),
    (
        BackPropagationRegressor,
        "BP neural network: sigmoid hidden neurons make the error a non-linear function of the "
        "temperatures; its weights are no coefficients per input",
    ),
    (
        AutoregressiveDistributedLag,
        "ARDL: the prediction feeds back the error's own past values (AR terms), so it depends "
        "on the whole input history through the recursion, not on a finite table of lags",
    ),
    (ARMAErrorModel, "ARMA: a model of the error's own history; it uses no input"),
    (ReducedOrderAR, "reduced-order AR: a model of the error's own history; it uses no input"),
    (
        TimeVaryingAR,
        "time-varying AR: the error's own history with parameters tracked on line; no input, "
        "no fixed coefficients",
    ),
    (
        EmbeddedSVR,
        "SVR: an RBF-kernel support vector regression on the error's own past differences; "
        "non-linear and uses no input",
    ),
)
"""Models without a coefficient table, and why (class -> reason)."""


_SPEED_NAME = re.compile(r"^speed(?P<a>[0-9.]+)?_lag_(?P<tau>[0-9.]+)min$")


def _speed_parameters(name: str) -> tuple[float, float]:
    """(exponent a, time constant tau in min) of a speed-response input name."""
    match = _SPEED_NAME.match(name)
    if match is None:
        raise ValueError(f"'{name}' is not a speed-response input name (speed<a>_lag_<tau>min)")
    return float(match["a"] or 1.0), float(match["tau"])


def _kind_and_unit(name: str, spec: InputSpec) -> tuple[str, str]:
    """(kind, unit of the input) of input ``name`` under ``spec``."""
    if is_speed_feature(name):
        return SPEED, f"(krpm)^{_speed_parameters(name)[0]:g}"
    return (RISE, "K") if spec.features == RISE else (ABSOLUTE, "degC")


def _lagged_coefficients(
    estimator: LaggedLinearModel,
) -> tuple[float, list[tuple[str, int, float]]]:
    check_is_fitted(estimator, "coef_")
    table = estimator.coef_
    rows = [
        (str(sensor), int(lag), float(table.loc[sensor, lag]))
        for sensor in table.index
        for lag in table.columns
    ]
    return float(estimator.intercept_), rows


def _plain_linear_coefficients(
    estimator: LinearRegression,
) -> tuple[float, list[tuple[str, int, float]]]:
    check_is_fitted(estimator, "coef_")
    names = getattr(estimator, "feature_names_in_", None)
    if names is None:
        raise ValueError(
            "the linear regression was fitted without column names; fit it on the DataFrame of "
            "model inputs so its coefficients can be matched to inputs"
        )
    coef = np.ravel(estimator.coef_)
    return float(np.ravel(estimator.intercept_)[0]), [
        (str(n), 0, float(c)) for n, c in zip(names, coef, strict=True)
    ]


def _no_coefficients(estimator: NoCompensation) -> tuple[float, list[tuple[str, int, float]]]:
    return 0.0, []


LINEAR: tuple[tuple[type, Callable], ...] = (
    (NoCompensation, _no_coefficients),
    (LaggedLinearModel, _lagged_coefficients),
    (LinearRegression, _plain_linear_coefficients),
)
"""Linear models (class -> (intercept um, [(input, lag, coefficient)])); the lagged ones
(``dl``, ``pcdl``, ``ridge``, ``ridge_dl``, ``pls_dl``) store ``coef_`` already mapped back from
their standardised designs / components to the raw lagged inputs."""


def linear_form(estimator, spec: InputSpec) -> LinearForm | str:
    """Write a fitted candidate model as a linear function of its inputs and their lags.

    Parameters
    ----------
    estimator : fitted estimator of :data:`pipeline.models.registry.MODELS`
        ``none``, ``mlr``, ``ridge``, ``dl``, ``pcdl``, ``ridge_dl`` and ``pls_dl`` are linear;
        the others (and unknown estimators) get a reason.
    spec : InputSpec
        How the inputs were prepared (names, rise or absolute, window ``resample_s``).

    Returns
    -------
    LinearForm or str
        Intercept (um) and terms (input, lag in samples, um per unit of input); for a model
        that is not linear in its inputs, why no coefficient table exists.

    Raises
    ------
    sklearn.exceptions.NotFittedError
        If a linear model is not fitted.
    ValueError
        If the model uses an input ``spec`` does not define.
    """
    for cls, reason in NOT_LINEAR:
        if isinstance(estimator, cls):
            return f"{type(estimator).__name__} is not linear in its inputs: {reason}"
    extract = next((f for cls, f in LINEAR if isinstance(estimator, cls)), None)
    if extract is None:
        return (
            f"no coefficient table is known for {type(estimator).__name__}: only "
            f"{', '.join(cls.__name__ for cls, _ in LINEAR)} are written as linear forms"
        )
    intercept, rows = extract(estimator)
    unknown = sorted({name for name, _, _ in rows} - set(spec.inputs))
    if unknown:
        raise ValueError(
            f"the model uses input(s) {unknown} that its input spec does not define "
            f"(spec inputs: {list(spec.inputs)}); pass the spec of the model's card"
        )
    terms = tuple(Term(n, lag, c, *_kind_and_unit(n, spec)) for n, lag, c in rows)
    return LinearForm(intercept, terms, spec.resample_s)


def _reference_text(spec: InputSpec) -> str:
    if spec.reference == "first_sample":
        return "first sample of the run"
    return f"mean of the first {int(spec.reference_n)} samples of the run"


def _range(ranges: Mapping[str, Sequence[float]], key: str) -> list[float] | None:
    value = ranges.get(key)
    return None if value is None else [float(value[0]), float(value[1])]


def _input_definition(name: str, spec: InputSpec, ranges: Mapping[str, Sequence[float]]) -> dict:
    """Full definition of one input: what it is, its unit, reference and training range."""
    kind, unit = _kind_and_unit(name, spec)
    if kind == SPEED:
        exponent, tau = _speed_parameters(name)
        return {
            "kind": SPEED,
            "unit": unit,
            "exponent": exponent,
            "time_constant_min": tau,
            "recursion": (
                "s(t + dt) = s(t) exp(-dt / tau) + (rpm(t) / 1000)^a (1 - exp(-dt / tau)), "
                "tau in s = 60 time_constant_min, speed held between samples (zero-order hold)"
            ),
            "initial": "s = 0 at the run's first sample (spindle at rest)",
            "missing_speed": "0 rpm; over a break longer than 3 sampling intervals: stopped",
            "training_range": _range(ranges, name),
        }
    reading = _range(ranges, name)
    if kind == ABSOLUTE:
        return {
            "kind": ABSOLUTE,
            "sensor": name,
            "unit": "degC",
            "training_range": {"reading_degC": reading},
        }
    return {
        "kind": RISE,
        "sensor": name,
        "unit": "K",
        "definition": "reading (degC) minus the reading at the run's reference",
        "reference": _reference_text(spec),
        "reference_n": int(spec.reference_n) if spec.reference != "first_sample" else 1,
        "training_range": {"reading_degC": reading, "rise_K": _range(ranges, f"rise_{name}")},
    }


def coefficients_document(
    form: LinearForm | str,
    spec: InputSpec,
    training_ranges: Mapping[str, Sequence[float]],
    card: Mapping,
) -> dict:
    """Return the JSON-ready content of ``coefficients.json`` for one axis' champion.

    Parameters
    ----------
    form : LinearForm or str
        :func:`linear_form` of the champion.
    spec : InputSpec
        The champion's input spec.
    training_ranges : mapping
        ``{sensor: [min_degC, max_degC]}``, optionally ``{"rise_<sensor>": [min_K, max_K]}``
        and ``{speed input: [min, max]}``; missing entries are written as null.
    card : mapping
        The champion card (``axis``, ``model``, ``selection``, ``sample_interval_s``).

    Returns
    -------
    dict
        Linear: ``axis``, ``model``, ``selection``, ``linear`` (True), ``output`` (quantity,
        unit um, sign), ``equation``, ``sample_window_s``, ``intercept_um``, ``inputs``
        (name -> definition), ``terms`` (input, lag_samples, lag_s, coefficient,
        coefficient_unit). Not linear: ``axis``, ``model``, ``selection``, ``linear`` (False),
        ``reason``.
    """
    head = {"axis": card.get("axis"), "model": card["model"], "selection": card["selection"]}
    if isinstance(form, str):
        return {**head, "linear": False, "reason": form}
    window = form.window_s if form.window_s is not None else card.get("sample_interval_s")
    window = None if window is None else float(window)
    used = list(dict.fromkeys(t.input for t in form.terms))
    return {
        **head,
        "linear": True,
        "output": {"quantity": "predicted thermal error", "unit": "um", "sign": SIGN_NOTE},
        "equation": "e(t) = intercept_um + sum over terms of coefficient * input(t - lag_s)",
        "sample_window_s": window,
        "window_note": (
            "inputs are means over windows of sample_window_s (records sampled faster are "
            "averaged first); a lag counts whole windows"
        ),
        "intercept_um": float(form.intercept_um),
        "inputs": {name: _input_definition(name, spec, training_ranges) for name in used},
        "terms": [
            {
                "input": t.input,
                "lag_samples": int(t.lag),
                "lag_s": None if window is None else float(t.lag * window),
                "coefficient": float(t.coefficient),
                "coefficient_unit": f"um/{t.unit}",
            }
            for t in form.terms
        ],
    }


def _number(value: float, digits: int) -> str:
    """Shortest text of ``value`` rounded to ``digits`` significant digits (fixed or e-form)."""
    if value == 0.0:
        return "0"
    mantissa, exponent = f"{abs(value):.{digits - 1}e}".split("e")
    mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
    scientific = f"{mantissa}e{int(exponent)}"
    fixed = format(Decimal(f"{mantissa}e{int(exponent)}"), "f")
    fixed = fixed.rstrip("0").rstrip(".") if "." in fixed else fixed
    return min((fixed, scientific), key=len)


def _variables(
    terms: Sequence[Term], variables: Mapping[str, str] | None
) -> dict[str, tuple[str, str | None]]:
    """Input -> (operand of its reading, operand of its stored reference or None)."""
    names = dict(variables or {})
    out = {}
    for i, term in enumerate(dict.fromkeys(t.input for t in terms), start=1):
        reading = names.get(term, f"T{i:02d}")
        reference = names.get(f"ref_{term}", f"R{i:02d}")
        is_rise = next(t.kind for t in terms if t.input == term) == RISE
        out[term] = (reading, reference if is_rise else None)
    for operand in (v for pair in out.values() for v in pair if v is not None):
        if not re.fullmatch(r"[A-Z][A-Z0-9]*", operand):
            raise ValueError(
                f"TEMPCOMP variable '{operand}' must be upper case letters and digits "
                "(a PLC operand such as W486)"
            )
    return out


def _render(
    intercept_um: float,
    terms: Sequence[Term],
    operands: Mapping[str, tuple[str, str | None]],
    digits: int,
) -> tuple[str, float, dict[str, float]]:
    """Return the formula in mm at ``digits``, rounding errors: constant um, um/unit per input."""
    parts, errors = [], {}
    for term in terms:
        c_mm = term.coefficient / UM_PER_MM
        text = _number(c_mm, digits)
        errors[term.input] = abs(c_mm - math.copysign(float(text), c_mm)) * UM_PER_MM
        reading, reference = operands[term.input]
        variable = reading if reference is None else f"({reading}-{reference})"
        parts.append(("-" if c_mm < 0 else "+") + f"{text}*{variable}")
    constant = _number(intercept_um / UM_PER_MM, digits)
    rounded = math.copysign(float(constant), intercept_um)
    if float(constant) != 0.0:
        parts.append(("-" if intercept_um < 0 else "+") + constant)
    formula = "".join(parts).removeprefix("+") or "0"
    return formula, abs(intercept_um - rounded * UM_PER_MM), errors


def _stateful_reason(terms: Sequence[Term], window_s: float | None) -> str | None:
    lagged = [f"{t.input} at lag {t.lag}" for t in terms if t.lag > 0]
    speed = sorted({t.input for t in terms if t.kind == SPEED})
    problems = []
    if lagged:
        unit = f" x {window_s:g} s" if window_s else " samples"
        problems.append(f"past values ({', '.join(lagged)}{unit})")
    if speed:
        problems.append(f"speed responses {speed} (first-order lags: a recursion with state)")
    if not problems:
        return None
    return (
        "no TEMPCOMP formula: the TNC re-evaluates it every second from the current values of "
        f"its variables, with no memory, but this model needs {' and '.join(problems)}"
    )


def _bound_text(
    constant_um: float, errors: Mapping[str, float], ranges: Mapping[str, Sequence[float]] | None
) -> str:
    per_input = ", ".join(f"{name} {e:.3g} um/unit" for name, e in errors.items())
    text = f"rounding error at most {constant_um:.3g} um + sum of |input| x ({per_input or 'none'})"
    if ranges is None:
        return text
    total, missing = constant_um, []
    for name, error in errors.items():
        span = ranges.get(f"rise_{name}", ranges.get(name))
        if span is None:
            missing.append(name)
            continue
        total += error * max(abs(float(span[0])), abs(float(span[1])))
    if missing:
        return f"{text}; no training range for {missing}"
    return f"{text}; over the training ranges: at most {total:.3g} um"


def tempcomp_formula(
    form: LinearForm | str,
    spec: InputSpec,
    *,
    variables: Mapping[str, str] | None = None,
    training_ranges: Mapping[str, Sequence[float]] | None = None,
) -> tuple[str | None, str]:
    """Return a Heidenhain TNC ``TEMPCOMP`` formula for the model if it fits the limits.

    The formula gives the predicted thermal error in mm (coefficients in mm per K or per degC):
    [TNC] takes at most 31 characters and 16 variables (upper-case PLC operands), re-evaluated
    every second from their current values. A stateless formula cannot hold lags or speed
    responses: those models are rejected. A temperature *rise* needs the run's reference
    reading; the formula takes it as a second operand, ``c*(T01-R01)``, where the PLC stores
    the sensor's reading at the start of the run (the first sample, or the mean of the first n:
    ``spec.reference``) and keeps it until the next cold start. A constant reference in the
    formula is not offered: the model counts each rise from its own run's start, so a constant
    would add c (T_start - T_const) to every prediction of a run started at another
    temperature (2 um/K x 5 K = 10 um). Coefficients are rounded to the most significant
    digits (6 down to 2) that fit; below 2 the formula is rejected.

    Parameters
    ----------
    form : LinearForm or str
        :func:`linear_form` of the model.
    spec : InputSpec
        The model's input spec (its reference, for the text).
    variables : mapping, optional
        PLC operand per input (``{"T1": "W486", "ref_T1": "W600"}``); default placeholders
        ``T01``, ``R01``... (replace them: the length limit counts the real names).
    training_ranges : mapping, optional
        As for :func:`coefficients_document`; gives the rounding error over the training ranges.

    Returns
    -------
    tuple of (str or None, str)
        The formula (or None) and what it is (length, variables, rounding, error bound) or why
        there is none (which limit, with the numbers the formula would need).
    """
    if isinstance(form, str):
        return None, f"no TEMPCOMP formula: {form}"
    terms = [t for t in form.terms if t.coefficient != 0.0]
    reason = _stateful_reason(terms, form.window_s)
    if reason is not None:
        return None, reason
    operands = _variables(terms, variables)
    n_vars = len({v for pair in operands.values() for v in pair if v is not None})
    fitted = None
    for digits in range(TEMPCOMP_MAX_DIGITS, TEMPCOMP_MIN_DIGITS - 1, -1):
        fitted = (digits, *_render(form.intercept_um, terms, operands, digits))
        if len(fitted[1]) <= TEMPCOMP_MAX_CHARS:
            break
    digits, formula, constant_error, errors = fitted
    problems = []
    if len(formula) > TEMPCOMP_MAX_CHARS:
        problems.append(
            f"it needs {len(formula)} characters even with {TEMPCOMP_MIN_DIGITS} significant "
            f"digits, TEMPCOMP takes at most {TEMPCOMP_MAX_CHARS}"
        )
    if n_vars > TEMPCOMP_MAX_VARIABLES:
        problems.append(
            f"it needs {n_vars} variables, TEMPCOMP takes at most {TEMPCOMP_MAX_VARIABLES}"
        )
    if problems:
        return None, "no TEMPCOMP formula: " + "; ".join(problems)
    reference = (
        f"; rises as (reading - stored reference), the PLC latching the {_reference_text(spec)}"
        if any(t.kind == RISE for t in terms)
        else ""
    )
    return formula, (
        f"TEMPCOMP formula of the predicted thermal error in mm (the correction is its negative; "
        f"match the sign of W576-W584): {len(formula)} of {TEMPCOMP_MAX_CHARS} characters, "
        f"{n_vars} of {TEMPCOMP_MAX_VARIABLES} variables; coefficients to {digits} significant "
        f"digits, {_bound_text(constant_error, errors, training_ranges)}{reference}"
    )


MD32750_BITS = {
    0: "position-independent temperature compensation (K0, SD43900 $SA_TEMP_COMP_ABS_VALUE)",
    1: (
        "position-dependent temperature compensation (tan beta SD43910 $SA_TEMP_COMP_SLOPE, "
        "P0 SD43920 $SA_TEMP_COMP_REF_POSITION)"
    ),
    2: "temperature compensation in tool direction (MD20390 $MC_TOOL_TEMP_COMP_ON)",
}

MD32760_NOTE = (
    "MD32760 $MA_COMP_ADD_VELO_FACTOR (default 0.01, 0 to 0.10) caps the change of the "
    "compensation per interpolation cycle at this factor x MD32000 $MA_MAX_AX_VELO (a larger "
    "change is spread over several cycles, no alarm) and caps |tan beta| at the same value "
    "(0.01 = 0.57 deg); keep the default unless a step must be slower still: the runtime "
    "already limits the rate (compensation.limits.*.max_rate_um_per_s)"
)

WRITE_NOTE = (
    "write every few seconds to minutes (temperatures change slowly; [K3]: the PLC can acquire "
    "the temperature profile in a minutes cycle), e.g. each runtime cycle "
    "(compensation.cycle_s, 10 s by default), from the PLC user program or an OPC UA client"
)


def _md32750(bits: Sequence[int]) -> dict:
    return {
        "machine_data": "MD32750 $MA_TEMP_COMP_TYPE",
        "value": int(sum(1 << b for b in bits)),
        "bits_set": list(bits),
        "bits": {str(b): meaning for b, meaning in MD32750_BITS.items()},
        "effective": "after power on (BYTE, PowerOn)",
    }


def _has_axis_model(axis_model: Mapping, axis: str) -> bool:
    return (
        "slope_model" in axis_model
        and axis_model.get("status") in ("ok", "no_validation_campaign")
        and axis in [str(a) for a in axis_model.get("axis", [])]
    )


def _tan_beta(slope: Mapping, temperature: str) -> dict:
    """Return tan beta(T) = (k(T) - k0) / 1000 (um/mm to mm/mm), linear in the sensors."""
    per = "K of rise above the reading at the cold start" if temperature == "rise" else "degC"
    constant = (float(slope["intercept_um_per_mm"]) - float(slope["k0_um_per_mm"])) / UM_PER_MM
    coefficients = {s: float(c) / UM_PER_MM for s, c in slope["coefficients"].items()}
    symbol = "dT" if temperature == "rise" else "T"
    parts = [f"{'-' if c < 0 else '+'} {abs(c):.6g} {symbol}_{s}" for s, c in coefficients.items()]
    if constant != 0.0:
        parts.append(f"{'-' if constant < 0 else '+'} {abs(constant):.6g}")
    formula = " ".join(parts).removeprefix("+ ") or "0"
    return {
        "setting_data": "SD43910 $SA_TEMP_COMP_SLOPE",
        "unit": "1 (mm per mm)",
        "constant": constant,
        "coefficients_per_unit": coefficients,
        "temperature_unit": per,
        "formula": f"tan_beta = {formula}",
        "from_model": "tan_beta = (k(T) - k0) / 1000, k in um/mm",
    }


def sinumerik_mapping(axis_model: Mapping, axis: str) -> dict | None:
    """SINUMERIK 840D sl temperature-compensation data of the linear-axis composite model.

    The model ``E(x, T) = P_geo(x) + (k(T) - k0) x`` (``reports/axis_model.json``) has a thermal
    part ``(k(T) - k0) x``: an error line through x = 0 with gradient (k - k0) um/mm, and no
    position-independent part. In [K3]'s ``dK_x = K0(T) + tan beta(T) (P_x - P0)`` that is
    K0 = 0, P0 = 0 mm and tan beta = (k(T) - k0) / 1000; only MD32750 bit 1 is set (value 2, as
    in [K3]'s example). P_geo is the cold geometric error: it belongs to the leadscrew /
    encoder compensation, not here.

    Parameters
    ----------
    axis_model : mapping
        Content of ``reports/axis_model.json``.
    axis : str
        Axis name (``Y``).

    Returns
    -------
    dict or None
        ``controller``, ``axis``, ``equation``, ``K0``, ``tan_beta``, ``P0``, ``MD32750``,
        ``MD32760``, ``write``, ``sign``, ``not_in_temperature_compensation``; None when the
        document holds no linear-axis model of ``axis``.
    """
    if not _has_axis_model(axis_model, axis):
        return None
    temperature = str(axis_model.get("temperature", "rise"))
    return {
        "controller": "SINUMERIK 840D sl, temperature compensation (K3)",
        "axis": axis,
        "equation": "dK_x = K0(T) + tan_beta(T) * (P_x - P0)",
        "model": "E(x, T) = P_geo(x) + (k(T) - k0) x, x in mm, k in um/mm",
        "K0": {
            "setting_data": "SD43900 $SA_TEMP_COMP_ABS_VALUE",
            "value_mm": 0.0,
            "why": "the composite model has no position-independent thermal part",
        },
        "tan_beta": _tan_beta(axis_model["slope_model"], temperature),
        "P0": {
            "setting_data": "SD43920 $SA_TEMP_COMP_REF_POSITION",
            "value_mm": 0.0,
            "why": (
                "the thermal part (k - k0) x is counted from x = 0 of the laser targets; this "
                "assumes target_mm is the axis' machine position, else P0 = the machine "
                "position of target 0"
            ),
        },
        "MD32750": _md32750([1]),
        "MD32760": MD32760_NOTE,
        "write": f"SD43910 each cycle (SD43900, SD43920 once); {WRITE_NOTE}",
        "sign": (
            "the entries describe the error line as the laser measured it (deviation as its "
            "software reports it); [840C]: error = machine position - setpoint, positive moves "
            "the axis negative; not confirmed for the 840D sl: check with a small value"
        ),
        "not_in_temperature_compensation": (
            "P_geo(x), the cold geometric error: leadscrew / encoder error compensation "
            "([K3] 4.4 interpolatory compensation, $AA_ENC_COMP), written once"
        ),
    }


def spindle_k0_mapping(axis: str, offset_sign: int = -1) -> dict:
    """SINUMERIK 840D sl data for a spindle axis' runtime offset: the position-independent K0.

    The spindle's thermal drift does not depend on the axis position, so the runtime's value
    goes to K0 (SD43900) and only MD32750 bit 0 is set (value 1; 3 when the same axis also
    carries a position-dependent model). K0 describes the error ([K3]), so it is the predicted
    error in mm: ``SD43900 = offset_sign x offset_um / 1000`` for the runtime's offset
    ``offset_um = offset_sign x predicted error``.

    Parameters
    ----------
    axis : str
        The axis the spindle drift acts along (``Z``).
    offset_sign : {-1, 1}
        ``params.yaml`` ``compensation.offset_sign`` of the runtime.

    Returns
    -------
    dict
        ``controller``, ``axis``, ``K0`` (setting data, ``mm_per_offset_um``, formula),
        ``MD32750``, ``MD32760``, ``write``, ``sign``, ``alternative``.
    """
    if offset_sign not in (-1, 1):
        raise ValueError(f"offset_sign must be -1 or 1, got {offset_sign}")
    return {
        "controller": "SINUMERIK 840D sl, temperature compensation (K3)",
        "axis": axis,
        "K0": {
            "setting_data": "SD43900 $SA_TEMP_COMP_ABS_VALUE",
            "unit": "mm (assumed; see the module docstring)",
            "mm_per_offset_um": offset_sign / UM_PER_MM,
            "formula": f"SD43900 = {offset_sign:+d} x offset_um / 1000 = predicted error um / 1000",
        },
        "MD32750": _md32750([0]),
        "MD32760": MD32760_NOTE,
        "write": f"SD43900 each runtime cycle; {WRITE_NOTE}",
        "sign": (
            "K0 is the error in the axis' positive direction; the pipeline's drift is positive "
            "with the tool away from the table, which is +Z on a vertical spindle; check the "
            "other axes, and the sign on the machine, with a small value first"
        ),
        "alternative": (
            "MD32750 bit 2 (tool direction, MD20390 $MC_TOOL_TEMP_COMP_ON, SD42960 "
            "$SA_TOOL_TEMP_COMP) for a swivelling head; not mapped here"
        ),
    }

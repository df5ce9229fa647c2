"""Physical quantities in scene files: plain numbers are SI, strings carry a unit.

``"30 deg"``, ``"15 mm"`` and ``0.015`` are all accepted; the unit must belong to the quantity's
dimension, otherwise :class:`~pinstab.errors.SceneError` lists the units that would be valid.
"""

from __future__ import annotations

import math

from .errors import SceneError, choices

# dimension -> {unit: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "time": {"s": 1.0, "ms": 1e-3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0},
    "stiffness": {"N/m": 1.0, "kN/m": 1e3},
    "damping": {"N*s/m": 1.0, "Ns/m": 1.0},
    "torque": {"N*m": 1.0, "Nm": 1.0},
    "force": {"N": 1.0},
    "mass": {"kg": 1.0, "g": 1e-3},
    "density": {"kg/m^3": 1.0, "g/cm^3": 1e3},
    "velocity": {"m/s": 1.0, "mm/s": 1e-3},
    "angular-velocity": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
}

# [SI]: the largest stiffness, damping, mass, density, size, inertia or gain a scene may give
MAX_MAGNITUDE = 1e12
MAGNITUDE_REASON = (
    "beyond 1e12 in SI units (a stiffness of 1e12 N/m, a mass of 1e12 kg) a value is past any mechanism's and, "
    "next to values of order 1, leaves float64 fewer than 4 of its 16 digits; from about 1e154 the dynamics' "
    "products overflow"
)

# [kg]: the lightest body a scene may give (an object, a generated link): a microgram, a MEMS part's mass. Measured
# (a 1 m box on one plane-contact corner): event-driven contacts stay right at 1e-9 kg and find a false Painleve
# paradox from 1e-10 kg, their force slacks being absolute (MARGIN_SLACK (1 + |f|) [N]: a weight under 1e-9 N
# drowns in it); at 5e-324 kg the mass matrix is singular
MIN_MASS = 1e-9
MIN_MASS_REASON = (
    "lighter than a microgram (a MEMS part) a body's weight drowns in the contact solvers' force tolerances "
    "(1e-9 N) and its mass matrix in rounding"
)

# [m]: the smallest dimension of a body a scene may give (an object's radius, length or side, a generated ball's
# radius): a micrometre, a MEMS feature's. A body of mass m that thin has a principal moment of order m r^2, 1e-12 of
# its mass's scale at r = 1e-6 m: its mass matrix's condition number reaches 1e12 (a 100 kg cylinder of radius 1e-6 m
# still runs with every contact treatment); at r = 1e-300 m the moment is 0 next to the mass and the mass matrix's
# Cholesky factorization fails
MIN_LENGTH = 1e-6
MIN_LENGTH_REASON = (
    "thinner than a micrometre (a MEMS feature) a body's rotational inertia (of order its mass times its size "
    "squared) falls below 1e-12 of its mass and its mass matrix is singular in floating point"
)

MAX_COORDINATE = 1e6  # [m or rad]: a joint coordinate (or a target's value) beyond it is a mistake
COORDINATE_REASON = "where sines, cosines and positions lose their digits"
# [rad/s or m/s]: a joint rate (or a body's twist) beyond it is a mistake: the fastest rotors (ultracentrifuges,
# 1.6e4 rad/s) and projectiles (1e4 m/s) are far below, and beyond it the centrifugal and Coriolis terms (v^2)
# pass MAX_MAGNITUDE and a coordinate passes MAX_COORDINATE within a second
MAX_RATE = 1e6
RATE_REASON = (
    "past any mechanism's speed (ultracentrifuges turn at 1.6e4 rad/s); beyond it the centrifugal and Coriolis "
    "terms (rate^2) pass 1e12 and a coordinate passes 1e6 within a second"
)

# joint-coordinate dimensions: a revolute coordinate is an angle, a prismatic one a length
COORDINATE_DIMENSIONS = {"angle", "length"}
RATE_DIMENSIONS = {"angular-velocity", "velocity"}


def quantity(value: object, dimension: str, where: str) -> float:
    """Convert a scene value to SI.

    Args:
        value: a number (already SI) or a string ``"<number> <unit>"``.
        dimension: a key of :data:`UNITS`, or a set name (``"coordinate"``, ``"rate"``) that
            accepts any of several dimensions.
        where: the scene item being read, for error messages.

    Returns:
        The value in SI units.
    """
    allowed = _allowed_units(dimension)
    if isinstance(value, bool):
        raise SceneError(f"{where}: expected a number or a '<number> <unit>' string, got {value!r}")
    if isinstance(value, (int, float)):
        result = as_float(value)
    elif isinstance(value, str):
        parts = value.split()
        if len(parts) != 2:
            raise SceneError(
                f"{where}: cannot read {value!r}; write a number in SI units or '<number> <unit>' "
                f"with a unit among {choices(allowed)}"
            )
        number, unit = parts
        if unit not in allowed:
            raise SceneError(f"{where}: unit {unit!r} is not a unit of {dimension}; valid units: {choices(allowed)}")
        try:
            result = float(number) * allowed[unit]
        except ValueError:
            raise SceneError(f"{where}: {number!r} is not a number") from None
    else:
        raise SceneError(f"{where}: expected a number or a '<number> <unit>' string, got {type(value).__name__}")
    if not math.isfinite(result):
        raise SceneError(f"{where}: value {value!r} is not finite")
    return result


def as_float(value: int | float) -> float:
    """``float(value)``, or infinity for an integer beyond float64's range (TOML integers have no bound: 10**400
    made float() raise OverflowError); callers refuse it as not finite."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def finite_number(value: object, where: str) -> float:
    """``value`` as a float when it is a plain finite number (an int or a float, not a bool; an integer beyond
    float64's range counts as infinite).

    Raises:
        SceneError: ``"{where} must be a finite number, got {value!r}"``.
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(as_float(value)):
        raise SceneError(f"{where} must be a finite number, got {value!r}")
    return float(value)


def within_ceiling(value: float, where: str, unit: str, lower: str = "[0") -> float:
    """``value`` [SI] when at most :data:`MAX_MAGNITUDE`; ``lower`` opens the allowed range in the message
    (``"[0"``, ``"(0"``: the caller checks the lower end).

    Raises:
        SceneError: naming ``where``, the value and the allowed range.
    """
    if not value <= MAX_MAGNITUDE:
        raise SceneError(
            f"{where} = {value:.3g} {unit} is outside the allowed range {lower}, {MAX_MAGNITUDE:.0e}] {unit}: "
            f"{MAGNITUDE_REASON}"
        )
    return value


def _allowed_units(dimension: str) -> dict[str, float]:
    if dimension == "coordinate":
        dims = COORDINATE_DIMENSIONS
    elif dimension == "rate":
        dims = RATE_DIMENSIONS
    else:
        dims = {dimension}
    allowed: dict[str, float] = {}
    for dim in dims:
        allowed.update(UNITS[dim])
    return allowed

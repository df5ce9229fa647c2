"""The one check of a body's mass and rotational inertia, for every reader (URDF links, SDF links, MJCF bodies and
the inertias Pinocchio's MJCF parser infers from geoms): what Pinocchio would otherwise take silently (its MJCF
parser runs a mass of -0.5 kg as 0 and an inertia diagonal of (-1, 1, 1) as (0, 1, 1), a geom of negative density
as a body of negative mass).
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..units import within_ceiling

# How far below 0 the smallest principal moment (or below the sum of the other two, the largest) may be, relative to
# the largest: the rounding of the file's decimals to doubles and of the eigenvalue solve (a few machine epsilons,
# 2.2e-16, each; the bundled robots' PSD-but-singular inertias reach 2.6e-16). Beyond it the matrix is not an inertia:
# Cassie's 'left-plantar-rod' with ixx = 0 beside ixy = -2.34e-8 has a moment of -3.5e-13 (2e-10 of the largest),
# which Pinocchio's Inertia refuses ("The 3d inertia should be positive.") once rotated into its joint's frame.
INERTIA_TOLERANCE = 1e-14


def check_body(mass: float, inertia: np.ndarray, where: str, triangle: bool) -> None:
    """A body's mass [kg] and its rotational inertia (3 x 3, symmetric, about its centre of mass) [kg m^2]: see
    :func:`check_nonnegative` and :func:`check_inertia`.

    Raises:
        SceneError: naming ``where`` and the value.
    """
    check_nonnegative(mass, f"{where}: mass", "kg")
    check_inertia(inertia, where, triangle)


def check_nonnegative(value: float, where: str, unit: str) -> None:
    """A mass [kg], density [kg/m^3] or size [m] of a body: finite, at least 0, at most the ceiling
    (:data:`~pinstab.units.MAX_MAGNITUDE`).

    Raises:
        SceneError: ``"<where> <value> <unit> is negative"``, or the ceiling's message.
    """
    if value < 0:
        raise SceneError(f"{where} {value} {unit} is negative")
    within_ceiling(value, where, unit)


def check_inertia(inertia: np.ndarray, where: str, triangle: bool) -> None:
    """A body's rotational inertia (3 x 3, symmetric) [kg m^2]: finite, positive semidefinite, its largest principal
    moment within the ceiling and, when ``triangle``, each moment at most the sum of the other two.

    Raises:
        SceneError: naming ``where`` and the principal moments.
    """
    if not np.isfinite(inertia).all():
        raise SceneError(f"{where}: inertia {np.asarray(inertia).tolist()} kg m^2 is not finite")
    moments = np.linalg.eigvalsh(inertia)
    tolerance = INERTIA_TOLERANCE * max(abs(moments[0]), abs(moments[2]))
    if moments[0] < -tolerance:
        raise SceneError(
            f"{where}: inertia is not positive semidefinite: {_moments(moments)} (the smallest may be below 0 by at "
            f"most {INERTIA_TOLERANCE:g} x the largest, a rounding); the inertia [kg m^2]: {_matrix(inertia)}"
        )
    within_ceiling(float(moments[2]), f"{where}: inertia's largest principal moment", "kg m^2")
    if triangle and moments[2] > moments[0] + moments[1] + tolerance:
        raise SceneError(
            f"{where}: inertia violates the triangle inequality: {_moments(moments)} "
            "(each must be at most the sum of the other two)"
        )


def rotated(inertia: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``rotation @ inertia @ rotation.T`` [kg m^2] of an inertia :func:`check_inertia` took, its principal moments
    below 0 (a rounding) set to 0: positive semidefinite as computed, each diagonal entry a sum of terms >= 0, so
    that Pinocchio's ``Inertia`` (which refuses a diagonal entry below 0) takes it whatever the rotation."""
    moments, axes = np.linalg.eigh(inertia)
    turned = rotation @ axes
    matrix = (turned * np.maximum(moments, 0.0)) @ turned.T
    return (matrix + matrix.T) / 2


def _moments(moments: np.ndarray) -> str:
    return f"principal moments {_six_digits(moments)} kg m^2"


def _matrix(inertia: np.ndarray) -> str:
    """The entries ixx, iyy, izz, ixy, ixz, iyz."""
    entries = {"ixx": (0, 0), "iyy": (1, 1), "izz": (2, 2), "ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}
    return ", ".join(f"{name} {_six_digits([inertia[index]])[0]}" for name, index in entries.items())


def _six_digits(values) -> list[float]:
    """The values to 6 significant digits (a moment of -3.5e-13 beside one of 1.8e-3 kept)."""
    return [float(f"{value:.6g}") for value in values]

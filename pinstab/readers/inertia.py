"""The one check of a body's mass and rotational inertia, for every reader (URDF links, SDF links, MJCF bodies and
the inertias Pinocchio's MJCF parser infers from geoms): what Pinocchio would otherwise take silently (its MJCF
parser runs a mass of -0.5 kg as 0 and an inertia diagonal of (-1, 1, 1) as (0, 1, 1), a geom of negative density
as a body of negative mass).
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..units import within_ceiling

INERTIA_TOLERANCE = 1e-9  # relative to the largest principal moment


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
        raise SceneError(f"{where}: inertia is not positive semidefinite: {_moments(moments)}")
    within_ceiling(float(moments[2]), f"{where}: inertia's largest principal moment", "kg m^2")
    if triangle and moments[2] > moments[0] + moments[1] + tolerance:
        raise SceneError(
            f"{where}: inertia violates the triangle inequality: {_moments(moments)} "
            "(each must be at most the sum of the other two)"
        )


def _moments(moments: np.ndarray) -> str:
    return f"principal moments {np.round(moments, 12).tolist()} kg m^2"

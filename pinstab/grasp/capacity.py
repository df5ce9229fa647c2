"""What a grasp can carry, on the exact round cones (:mod:`pinstab.grasp.holding`): the squeeze it needs
to hold the object's weight, the largest load for a given squeeze, and the largest tilt of the hand.

Frames: O is the object's body frame; G (:mod:`pinstab.grasp.analysis`) takes the contact forces to the
wrench on the object in O about O's origin. The weight m g acts at the object's centre of mass c (in O):
the contacts hold it when ``G lambda = -(m g_O, c x m g_O)``. The *squeeze* is the largest normal force
of a contact [N]. A *tilt* by an angle theta about a world axis a turns the hand (and the grasped object
with it) by theta about a; the hand then feels gravity ``exp(-theta a^) g`` in its own (the world's) axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .holding import least_squeeze

TILT_STEP = 5.0  # [deg] the scan for the first tilt that slips; bisection then to TILT_TOLERANCE
TILT_TOLERANCE = 1e-6  # [deg]
LARGEST_TILT = 180.0  # [deg]


@dataclass(frozen=True)
class Weight:
    """The object's weight as the grasp sees it.

    Attributes:
        mass: [kg]. centre: the centre of mass in O [m]. gravity: g in world axes [m/s^2].
        rotation: O's axes in the world at the grasp (3 x 3).
    """

    mass: float
    centre: np.ndarray
    gravity: np.ndarray
    rotation: np.ndarray

    def load(self, tilt: float = 0.0, axis: np.ndarray | None = None) -> np.ndarray:
        """The wrench the contacts must exert on the object in O [N, N m] (about O's origin) to hold its
        weight with the hand tilted by ``tilt`` [rad] about the world ``axis`` (unit)."""
        gravity = self.gravity if axis is None else pin.exp3(-tilt * np.asarray(axis, float)) @ self.gravity
        force = self.mass * (self.rotation.T @ gravity)
        return -np.concatenate([force, np.cross(self.centre, force)])


def first_slip_tilt(grasp_map: np.ndarray, contacts: list, weight: Weight, axis: np.ndarray, squeeze: float) -> float:
    """The smallest tilt [deg] of the hand about the world ``axis`` (right-handed, 0 to 180 deg) at which no
    contact forces with every normal force <= ``squeeze`` [N] hold the weight: there the first contact
    leaves its cone. 0 when the grasp does not hold at the start; inf when it holds at every tilt.
    The tilts are scanned every :data:`TILT_STEP` deg, then bisected to :data:`TILT_TOLERANCE` deg."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)

    def holds(degrees: float) -> bool:
        need = least_squeeze(grasp_map, weight.load(math.radians(degrees), axis), contacts).squeeze
        return need <= squeeze * (1.0 + 1e-12)

    if not holds(0.0):
        return 0.0
    low = 0.0
    while low < LARGEST_TILT:
        high = min(low + TILT_STEP, LARGEST_TILT)
        if not holds(high):
            while high - low > TILT_TOLERANCE:
                middle = 0.5 * (low + high)
                low, high = (middle, high) if holds(middle) else (low, middle)
            return 0.5 * (low + high)
        low = high
    return math.inf


def horizontal_axes(gravity: np.ndarray) -> dict[str, np.ndarray]:
    """Two world axes perpendicular to gravity, named: the two world axes least along gravity (x, y for
    gravity along -z), made perpendicular to it."""
    down = np.asarray(gravity, float) / np.linalg.norm(gravity)
    names = sorted(range(3), key=lambda k: abs(down[k]))[:2]
    axes = {}
    for k in sorted(names):
        axis = np.eye(3)[k] - down[k] * down
        axes["xyz"[k]] = axis / np.linalg.norm(axis)
    return axes


@dataclass(frozen=True)
class Capacity:
    """What a grasp carries.

    Attributes:
        load: the object's weight m |g| [N]. squeeze_needed: the least squeeze that holds it [N] (inf: no
            forces inside the cones hold it). forces: those contact forces (stacked, in the contact frames
            [N, N m]), or None. squeeze: the squeeze the largest load and the tilts are for [N], or None.
        largest_load: the largest weight that squeeze holds, along the same gravity [N] (None without a
            squeeze). tilts: per tilt axis (``+x``, ``-x``, ...: a world axis and its sense) the first tilt
            at which a contact leaves its cone [deg] (inf: none up to 180 deg; empty without a squeeze).
    """

    load: float
    squeeze_needed: float
    forces: np.ndarray | None
    squeeze: float | None
    largest_load: float | None
    tilts: dict[str, float]


def grasp_capacity(
    grasp_map: np.ndarray, contacts: list, weight: Weight, squeeze: float | None, axes: dict[str, np.ndarray]
) -> Capacity:
    """The :class:`Capacity` of a grasp (G, its contacts) holding ``weight``; with ``squeeze`` [N] the
    largest load (the problem is homogeneous: load / squeeze_needed per newton of squeeze) and the first
    slipping tilt about each of ``axes`` (name -> world axis), both senses."""
    load = weight.mass * float(np.linalg.norm(weight.gravity))
    holding = least_squeeze(grasp_map, weight.load(), contacts)
    if squeeze is None:
        return Capacity(load, holding.squeeze, holding.forces, None, None, {})
    largest = 0.0 if not holding.holds else (math.inf if holding.squeeze == 0 else load * squeeze / holding.squeeze)
    tilts = {
        f"{sign_name}{name}": first_slip_tilt(grasp_map, contacts, weight, sign * axis, squeeze)
        for name, axis in axes.items()
        for sign_name, sign in (("+", 1.0), ("-", -1.0))
    }
    return Capacity(load, holding.squeeze, holding.forces, squeeze, largest, tilts)

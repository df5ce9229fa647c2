"""A frame's point following a path in time, or a frame's orientation held: targets for servos (a hand
that must trace a curve, a tool kept level), usable as real constraints too.

Kinds:

* ``frame-path`` (3 rows, world axes): the point ``offset`` [m] of ``frame`` is at
  ``p(t) = centre + amplitude * sin(omega t + phase)`` (per axis: ``amplitude`` [m] and ``phase`` [rad]
  are 3-vectors, ``omega`` [rad/s] one rate; ``centre`` defaults to the point's start position): a line,
  an ellipse or a Lissajous curve.
* ``frame-orientation`` (3 rows): ``frame``'s rotation stays at its start, ``log3(R_0^T R)`` [rad].
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms
from .loops import FrameClosure

PATH_KEYS = {"name", "kind", "frame", "offset", "centre", "amplitude", "omega", "phase"}
ORIENTATION_KEYS = {"name", "kind", "frame"}


class FramePath(Constraint):
    """``p_frame - p(t)`` [m], world axes; multipliers: the force on the frame's body [N], world axes."""

    holonomic = True
    rows = 3

    def __init__(
        self, name: str, frame: int, centre: np.ndarray, amplitude: np.ndarray, omega: float, phase: np.ndarray
    ) -> None:
        self.name, self.kind, self.frame = name, "frame-path", frame
        self.centre, self.amplitude, self.omega, self.phase = centre, amplitude, omega, phase
        self.force_frame = "world axes, force on the frame's body"

    def target(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p, dp/dt, d2p/dt2) at time t [s]: [m, m/s, m/s^2]."""
        angle = self.omega * t + self.phase
        wave = self.amplitude * np.sin(angle)
        return self.centre + wave, self.amplitude * self.omega * np.cos(angle), -(self.omega**2) * wave

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return kin.placement(self.frame).translation - self.target(t)[0]

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        return VelocityTerms(kin.jacobian(self.frame)[:3], -self.target(t)[1])

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return kin.drift_acceleration(self.frame).linear - self.target(t)[2]


class FrameOrientation(Constraint):
    """``log3(R_0^T R)`` [rad] of the frame's rotation R against its start orientation R_0 (a weld's rotation
    rows); the multipliers are the moment on the frame's body [N m] (in the log's axes)."""

    holonomic = True
    rows = 3

    def __init__(self, name: str, frame: int, start: pin.SE3) -> None:
        self.name, self.kind, self.frame = name, "frame-orientation", frame
        self._weld = FrameClosure(name, "weld", frame, None, start)  # its rotation rows are these rows
        self.force_frame = "moment on the frame's body, log3(R_0^T R) axes"

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return self._weld.residual(kin, q, t)[3:]

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        jacobian, time_term = self._weld.velocity_terms(kin, q, t)
        return VelocityTerms(jacobian[3:], time_term[3:])

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return self._weld.drift(kin, q, v, t)[3:]


def parse_frame_path(entry: dict, tables: SceneTables, name: str, where: str) -> FramePath:
    """Scene table: ``frame`` + ``offset`` [m], ``centre`` [m] (default: the point's start), ``amplitude``
    [m] and ``phase`` [rad] (3 each), ``omega`` [rad/s]."""
    tables.check_keys(entry, PATH_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/point", where)
    start = tables.initial_placement(frame).translation
    centre = tables.vector(entry["centre"], 3, f"{where}.centre", "length") if "centre" in entry else start
    amplitude = tables.vector(entry.get("amplitude", [0.0, 0.0, 0.0]), 3, f"{where}.amplitude", "length")
    phase = tables.vector(entry.get("phase", [0.0, 0.0, 0.0]), 3, f"{where}.phase", "angle")
    omega = tables.quantity(entry.get("omega", 0.0), "angular-velocity", f"{where}.omega")
    return FramePath(name, frame, centre, amplitude, omega, phase)


def parse_frame_orientation(entry: dict, tables: SceneTables, name: str, where: str) -> FrameOrientation:
    """Scene table: ``frame`` (its start orientation is held)."""
    tables.check_keys(entry, ORIENTATION_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/frame", where)
    return FrameOrientation(name, frame, tables.initial_placement(frame))


CONSTRAINT_KINDS.register(
    "frame-path", parse_frame_path, summary="3 rows: a frame point at centre + amplitude sin(omega t + phase)"
)
CONSTRAINT_KINDS.register(
    "frame-orientation", parse_frame_orientation, summary="3 rows: a frame's orientation held at its start"
)

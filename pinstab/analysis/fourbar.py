"""An independent reference for the four-bar: its one-DOF Lagrange equation in the crank angle.

The planar four-bar (crank and rocker pinned to the ground, coupler on the crank tip, the loop closed
between the coupler's end and the rocker's end) has the crank angle th as its only coordinate. The
coupler and rocker angles follow from the loop closure in closed form (two circles intersecting), and
their first and second derivatives with respect to th from the differentiated loop equation, so

    I(th) th'' + I'(th) th'^2 / 2 + V'(th) = 0,
    I = sum_i m_i |dp_i/dth|^2 + J_i (da_i/dth)^2,   V = -sum_i m_i g . p_i,

with p_i the centres of mass and a_i the absolute link angles. Nothing here uses a constraint solver:
only the link lengths, masses, centres of mass and inertias, read from the scene's model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import PinstabError
from ..scene import Scene
from .references import EXACT_REFERENCES, EXACT_TOLERANCE, Reference, solve_exact, wrapped_like


def _rot(angle: float, x: float, y: float) -> tuple[float, float]:
    c, s = math.cos(angle), math.sin(angle)
    return c * x - s * y, s * x + c * y


@dataclass(frozen=True)
class FourBarGeometry:
    """The planar data of a four-bar [m, kg, kg m^2]: pivots, lengths, centres of mass and inertias
    (index 0 crank, 1 coupler, 2 rocker), gravity in the plane [m/s^2]."""

    rocker_pivot: tuple[float, float]
    crank_length: float
    coupler_length: float
    rocker_length: float
    masses: tuple[float, float, float]
    levers: tuple[tuple[float, float], ...]
    inertias: tuple[float, float, float]
    gravity: tuple[float, float]
    branch: float

    @classmethod
    def of(cls, scene: Scene, q0: np.ndarray) -> FourBarGeometry:
        """Read the geometry from the scene's model; the assembly branch from the configuration q0.

        Raises:
            PinstabError: the scene is not the bundled four-bar's structure.
        """
        model = scene.model
        names = [model.names[j] for j in range(1, model.njoints)]
        if names != ["crank", "coupler", "rocker"] or len(scene.constraints) != 1:
            raise PinstabError("the four-bar reference needs joints crank, coupler, rocker and one closure")
        closure = scene.constraints[0]
        offset_a = model.frames[closure.frame_a].placement.translation
        offset_b = model.frames[closure.frame_b].placement.translation
        inertias = [model.inertias[j] for j in (1, 2, 3)]
        geometry = cls(
            rocker_pivot=tuple(model.jointPlacements[3].translation[:2]),
            crank_length=float(model.jointPlacements[2].translation[0]),
            coupler_length=float(offset_a[0]),
            rocker_length=float(offset_b[0]),
            masses=tuple(float(i.mass) for i in inertias),
            levers=tuple((float(i.lever[0]), float(i.lever[1])) for i in inertias),
            inertias=tuple(float(i.inertia[2, 2]) for i in inertias),
            gravity=tuple(model.gravity.linear[:2]),
            branch=1.0,
        )
        alpha2, _ = geometry.angles(q0[0], 1.0)
        branch = 1.0 if abs(math.remainder(alpha2 - (q0[0] + q0[1]), 2 * math.pi)) < 1e-6 else -1.0
        return cls(**{**geometry.__dict__, "branch": branch})

    def angles(self, theta: float, branch: float | None = None) -> tuple[float, float]:
        """Absolute coupler and rocker angles [rad] at crank angle theta, on the assembly branch."""
        branch = self.branch if branch is None else branch
        px, py = self.crank_length * math.cos(theta), self.crank_length * math.sin(theta)
        dx, dy = self.rocker_pivot[0] - px, self.rocker_pivot[1] - py
        d = math.hypot(dx, dy)
        a = (self.coupler_length**2 - self.rocker_length**2 + d * d) / (2 * d)
        h = math.sqrt(max(self.coupler_length**2 - a * a, 0.0))
        bx = px + (a * dx - branch * h * dy) / d
        by = py + (a * dy + branch * h * dx) / d
        alpha2 = math.atan2(by - py, bx - px)
        alpha3 = math.atan2(by - self.rocker_pivot[1], bx - self.rocker_pivot[0])
        return alpha2, alpha3

    def acceleration(self, theta: float, rate: float) -> tuple[float, float, float]:
        """(theta'' [rad/s^2], coupler angle, rocker angle) at crank angle theta and rate theta'."""
        l1, l2, l3 = self.crank_length, self.coupler_length, self.rocker_length
        a1 = theta
        a2, a3 = self.angles(theta)
        c1, s1, c2, s2, c3, s3 = math.cos(a1), math.sin(a1), math.cos(a2), math.sin(a2), math.cos(a3), math.sin(a3)
        # L2 e'(a2) a2' - L3 e'(a3) a3' = -L1 e'(a1), e'(a) = (-sin a, cos a)
        m11, m12, m21, m22 = -l2 * s2, l3 * s3, l2 * c2, -l3 * c3
        det = m11 * m22 - m12 * m21
        r1, r2 = l1 * s1, -l1 * c1
        d2 = (r1 * m22 - m12 * r2) / det
        d3 = (m11 * r2 - r1 * m21) / det
        # second derivative: same matrix, right side L1 e(a1) + L2 e(a2) a2'^2 - L3 e(a3) a3'^2
        r1 = l1 * c1 + l2 * c2 * d2**2 - l3 * c3 * d3**2
        r2 = l1 * s1 + l2 * s2 * d2**2 - l3 * s3 * d3**2
        dd2 = (r1 * m22 - m12 * r2) / det
        dd3 = (m11 * r2 - r1 * m21) / det
        (lx1, ly1), (lx2, ly2), (lx3, ly3) = self.levers
        # centre-of-mass velocities and accelerations per unit crank rate, d/dth and d2/dth2
        v1 = _rot(a1, -ly1, lx1)
        w1 = _rot(a1, -lx1, -ly1)
        sx2, sy2 = _rot(a2, -ly2, lx2)
        rx2, ry2 = _rot(a2, lx2, ly2)
        v2 = (-l1 * s1 + sx2 * d2, l1 * c1 + sy2 * d2)
        w2 = (-l1 * c1 + sx2 * dd2 - rx2 * d2**2, -l1 * s1 + sy2 * dd2 - ry2 * d2**2)
        sx3, sy3 = _rot(a3, -ly3, lx3)
        rx3, ry3 = _rot(a3, lx3, ly3)
        v3 = (sx3 * d3, sy3 * d3)
        w3 = (sx3 * dd3 - rx3 * d3**2, sy3 * dd3 - ry3 * d3**2)
        (m1, m2, m3), (j1, j2, j3), (gx, gy) = self.masses, self.inertias, self.gravity
        inertia = 0.0
        inertia_rate = 0.0
        potential_rate = 0.0
        for m, v, w in ((m1, v1, w1), (m2, v2, w2), (m3, v3, w3)):
            inertia += m * (v[0] ** 2 + v[1] ** 2)
            inertia_rate += 2 * m * (v[0] * w[0] + v[1] * w[1])
            potential_rate -= m * (gx * v[0] + gy * v[1])
        inertia += j1 + j2 * d2**2 + j3 * d3**2
        inertia_rate += 2 * (j2 * d2 * dd2 + j3 * d3 * dd3)
        return -(0.5 * inertia_rate * rate**2 + potential_rate) / inertia, a2, a3


@EXACT_REFERENCES.register("fourbar", summary="the crank-angle equation (one coordinate, closed-form loop)")
def fourbar_motion(scene: Scene, q0: np.ndarray, v0: np.ndarray, times: np.ndarray) -> Reference:
    """The four-bar's motion from (q0, v0) at ``times`` [s]: the crank-angle equation integrated by SciPy's
    DOP853 at 1e-13, coupler and rocker angles from the loop in closed form on q0's assembly branch.

    Raises:
        PinstabError: the scene is not the bundled four-bar's structure.
    """
    geometry = FourBarGeometry.of(scene, q0)

    def slope(_: float, state: np.ndarray) -> np.ndarray:
        return np.array([state[1], geometry.acceleration(state[0], state[1])[0]])

    crank = solve_exact(slope, np.array([q0[0], v0[0]]), times)[:, 0]
    angles = np.array([(theta, *geometry.angles(theta)) for theta in crank])
    absolute = np.column_stack([crank, wrapped_like(angles[:, 1], q0[0] + q0[1]), wrapped_like(angles[:, 2], q0[2])])
    q = np.column_stack([absolute[:, 0], absolute[:, 1] - absolute[:, 0], absolute[:, 2]])
    kind = f"exact: the crank-angle equation (SciPy DOP853, rtol = atol = {EXACT_TOLERANCE:g})"
    return Reference(kind, q, ("crank",))

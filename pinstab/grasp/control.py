"""``grasp-control``: computed torque in object coordinates [MLS 6.3] (docs/mathematics.md section 4).

The object follows a pose path from where the scene starts it: translated by ``move`` [m] (world axes)
and turned by ``turn`` [rad] about the world ``axis``, along a quintic time law over ``duration`` [s]
from ``start`` [s]. Per state:

1. the object's desired acceleration: the path's, plus PD feedback on the pose error (``kp`` [1/s^2],
   ``kd`` [1/s]);
2. the hand's joint accelerations that the contacts then impose (least squares through the contact
   rows), plus a posture PD (``posture_kp``, ``posture_kd``) in the rows' null space;
3. the contact forces: the object's Newton-Euler equations fix their resultant; the internal forces (the
   null space) come from a ProxSuite QP that minimizes the joint torques |tau|^2 subject to every
   contact force inside its linearized friction cone with ``margin`` [N] to spare and every joint
   torque within the URDF's effort limit;
4. the joint torques that make those forces and accelerations the solution of the dynamics:
   ``tau = (M a + h)_hand - A_hand^T lambda``.

With ``internal_forces = false`` step 3 takes the smallest forces that move the object (no internal
force, no cone): under gravity a side grasp then needs a contact to pull or slide, and the run stops
with :class:`~pinstab.errors.GraspLostError` naming it — which is why the QP is there.

A welded grasp (``closures``: two ``weld`` closures between the object and two hands, in place of
``contacts``) has no cones: step 3 takes the smallest forces that move the object plus the internal force
``squeeze`` [N] between the two hands, set exactly (:mod:`pinstab.grasp.welded`); the posture PD of step 2
then steers the arms' self-motion (the joint rates the welds leave free) back to the start posture.

A run reports the object's largest position and orientation errors against the path, and for a welded
grasp the internal force measured from the closures' multipliers against its set value
(:meth:`GraspControl.run_figures`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ..actuation import effort_bounds
from ..constraints.grasp_contacts import cross
from ..contact.cones import MAX_CONE_FACETS
from ..errors import ContactInfeasibleError, SceneError
from ..forces.base import FORCE_KINDS, ForceElement, Sample
from ..kinematics import Kinematics
from ..tables import SceneTables
from ..units import within_ceiling
from .hold import contact_rows, grasped_contacts, grasped_object, hand_columns
from .holding import WarmQP, cone_columns, pyramid_rows
from .linalg import closest_solution, pinv
from .welded import WeldedGrasp, welded_grasp

CONTROL_KEYS = {
    "name",
    "kind",
    "object",
    "contacts",
    "move",
    "turn",
    "axis",
    "start",
    "duration",
    "kp",
    "kd",
    "posture_kp",
    "posture_kd",
    "margin",
    "facets",
    "internal_forces",
    "closures",
    "squeeze",
}
CONTACT_ONLY = ("margin", "facets", "internal_forces")  # the cones of a grasp on contacts
WELD_ONLY = ("squeeze",)  # the internal force of a welded grasp


@dataclass(frozen=True)
class PosePath:
    """The object's desired pose: ``start_pose`` moved by ``s(t) move`` and turned by ``s(t) turn`` about
    ``axis`` (world), s the quintic 10 u^3 - 15 u^4 + 6 u^5 of u = (t - start) / duration in [0, 1].

    Attributes: start_pose: world placement at t <= start. move [m]. turn [rad]. axis: unit, world.
    start, duration [s].
    """

    start_pose: pin.SE3
    move: np.ndarray
    turn: float
    axis: np.ndarray
    start: float
    duration: float

    def _law(self, t: float) -> tuple[float, float, float]:
        """(s, ds/dt [1/s], d2s/dt2 [1/s^2])."""
        u = min(max((t - self.start) / self.duration, 0.0), 1.0)
        if u <= 0.0 or u >= 1.0:
            return u, 0.0, 0.0
        s = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
        ds = 30.0 * u**2 * (1.0 - u) ** 2 / self.duration
        dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / self.duration**2
        return s, ds, dds

    def pose(self, t: float) -> pin.SE3:
        """Desired world placement at time t [s]."""
        s, _, _ = self._law(t)
        rotation = pin.exp3(s * self.turn * self.axis) @ self.start_pose.rotation
        return pin.SE3(rotation, self.start_pose.translation + s * self.move)

    def motion(self, t: float) -> tuple[pin.SE3, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(pose, world velocity [m/s], world angular velocity [rad/s], their rates [m/s^2, rad/s^2])."""
        s, ds, dds = self._law(t)
        spin = self.turn * self.axis
        return self.pose(t), ds * self.move, ds * spin, dds * self.move, dds * spin


class GraspControl(ForceElement):
    """Object-level computed torque with a cone-keeping internal-force QP, or for a welded grasp a set squeeze
    (see the module docstring).

    Args:
        name: element name. model: the scene model. contacts: the grasp contact blocks on the object (the
            two weld closures of a welded grasp).
        object_frame: the object's body frame. object_columns: its velocity indices. path: the pose path.
        gains: (kp [1/s^2], kd [1/s], posture_kp [1/s^2], posture_kd [1/s]).
        margin: cone margin [N]. facets: sides of the linearized cones. internal_forces: run the QP.
        q_start: the posture the hand's null space is pulled back to.
        welds: the welded grasp (``contacts`` its closures; no cones), or None for a grasp on contacts.
    """

    def __init__(
        self,
        name: str,
        model: pin.Model,
        contacts: list[Any],
        object_frame: int,
        object_columns: np.ndarray,
        path: PosePath,
        gains: tuple[float, float, float, float],
        margin: float,
        facets: int,
        internal_forces: bool,
        q_start: np.ndarray,
        welds: WeldedGrasp | None = None,
    ) -> None:
        self.name, self.model, self.contacts = name, model, contacts
        self.object_frame, self.object_columns, self.path = object_frame, object_columns, path
        self.kp, self.kd, self.posture_kp, self.posture_kd = gains
        self.margin, self.internal_forces = margin, internal_forces
        self.hand_columns = hand_columns(model.nv, object_columns)
        self.q_start = q_start.copy()
        lower, upper = effort_bounds(model, self.hand_columns)
        self.effort_limit = np.minimum(-lower, upper)  # symmetric: the tighter side (a URDF's are symmetric)
        self.welds = welds
        self.cone_rows, self.cone_bounds = self._cone_constraints(facets) if welds is None else (None, None)
        self._qp = WarmQP()  # the internal-force QP, warm-started from the previous evaluation's

    # -- pieces ----------------------------------------------------------------------------------------
    def _cone_constraints(self, facets: int) -> tuple[np.ndarray, np.ndarray]:
        """(C, bounds) with C lambda >= bounds: each friction contact's force inside its inscribed pyramid
        with ``margin`` [N] to spare (distances to the facets), every pushing contact's normal force >=
        margin (a soft finger's torsion within its bounds); a rigid contact carries anything."""
        columns, count = cone_columns(self.contacts)
        matrix = pyramid_rows(columns, count, facets)
        return matrix, np.full(len(matrix), self.margin)

    def desired_acceleration(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        """The object's desired acceleration (body twist rate, linear first) [m/s^2, rad/s^2]: the path's
        plus PD feedback on the pose error, in world axes, carried to the free flyer's coordinates."""
        placement = kin.placement(self.object_frame)
        rotation = placement.rotation
        velocity = v[self.object_columns]
        linear_world, angular_world = rotation @ velocity[:3], rotation @ velocity[3:]
        pose, linear_d, angular_d, linear_dd, angular_dd = self.path.motion(t)
        position_error = placement.translation - pose.translation
        rotation_error = pose.rotation @ pin.log3(pose.rotation.T @ rotation)  # world axes
        linear = linear_dd - self.kd * (linear_world - linear_d) - self.kp * position_error
        angular = angular_dd - self.kd * (angular_world - angular_d) - self.kp * rotation_error
        # d/dt (R^T p_dot) = R^T p_ddot - omega_b x (R^T p_dot); d/dt (R^T omega) = R^T omega_dot
        omega_body = velocity[3:]
        return np.concatenate([rotation.T @ linear - cross(omega_body, velocity[:3]), rotation.T @ angular])

    def _hand_acceleration(self, kin: Kinematics, v: np.ndarray, t: float, rows: np.ndarray, object_acc: np.ndarray):
        """Joint accelerations consistent with the contacts for the object's acceleration, the posture PD in
        the rows' null space [rad/s^2]."""
        drift = np.concatenate([c.drift(kin, kin.q, v, t) for c in self.contacts])
        hand_rows = rows[:, self.hand_columns]
        pseudo = pinv(hand_rows)
        particular = pseudo @ (-drift - rows[:, self.object_columns] @ object_acc)
        deviation = pin.difference(self.model, self.q_start, kin.q)[self.hand_columns]
        posture = -self.posture_kp * deviation - self.posture_kd * v[self.hand_columns]
        return particular + posture - pseudo @ (hand_rows @ posture)

    def _internal_force_qp(self, carrier: np.ndarray, wrench: np.ndarray, hand_rows: np.ndarray, demand: np.ndarray):
        """(contact forces lambda with ``carrier lambda = wrench`` minimizing |demand - hand_rows^T lambda|^2
        (the joint torques), inside the cones with margin and within the effort limits; whether ProxQP solved it; its
        info)."""
        count = carrier.shape[1]
        hessian = hand_rows @ hand_rows.T + 1e-9 * np.eye(count)
        gradient = -hand_rows @ demand
        finite = np.isfinite(self.effort_limit)
        torque_rows = -hand_rows.T[finite]  # tau = demand - A_h^T lambda within +-limit
        inequality = np.vstack([self.cone_rows, torque_rows])
        lower = np.concatenate([self.cone_bounds, -self.effort_limit[finite] - demand[finite]])
        upper = np.concatenate([np.full(len(self.cone_bounds), 1e30), self.effort_limit[finite] - demand[finite]])
        return self._qp.solve(hessian, gradient, carrier, wrench, inequality, lower, upper)

    # -- ForceElement ----------------------------------------------------------------------------------
    def plan(self, kin: Kinematics, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(joint torques tau (nv,) [N m], the contact forces lambda they produce [N, N m], the accelerations
        a (nv,) [m/s^2, rad/s^2]) at ``kin``'s state: (a, lambda) solve the dynamics under tau.

        Raises:
            ContactInfeasibleError: no contact forces move the object inside the cones and the torque limits.
        """
        rows = contact_rows(self.contacts, kin, t)
        object_acc = self.desired_acceleration(kin, v, t)
        acceleration = np.zeros(self.model.nv)
        acceleration[self.object_columns] = object_acc
        acceleration[self.hand_columns] = self._hand_acceleration(kin, v, t, rows, object_acc)
        needed = kin.mass_matrix @ acceleration + kin.bias  # M a + h
        carrier, wrench = rows[:, self.object_columns].T, needed[self.object_columns]
        hand_rows, demand = rows[:, self.hand_columns], needed[self.hand_columns]
        if self.welds is not None:
            forces = self.welds.forces(kin, carrier, wrench)
        elif self.internal_forces:
            forces, solved, info = self._internal_force_qp(carrier, wrench, hand_rows, demand)
            if not solved:
                raise ContactInfeasibleError(
                    f"grasp control at t = {t:.6g} s: no contact forces move the object with every force inside "
                    f"its cone (margin {self.margin:g} N) and every joint torque within its limit (ProxQP: "
                    f"{info.status.name} after {info.iter} iterations)",
                    [c.name for c in self.contacts],
                    t,
                )
            # ProxQP meets the object's balance carrier f = wrench only to its eps_abs (1e-10 N, or 1e-6 with older
            # proxsuite releases), which a light object turns into 1e-8..1e-6 m/s^2 of planned acceleration the
            # torques do not produce: the closest forces that meet it meet it to rounding (the cones keep their margin)
            forces = closest_solution(carrier, wrench, forces)
        else:
            forces = closest_solution(carrier, wrench, np.zeros(carrier.shape[1]))  # the least-norm forces
        tau = np.zeros(self.model.nv)
        tau[self.hand_columns] = demand - hand_rows.T @ forces
        return tau, forces, acceleration

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        return self.plan(kin, v, t)[0]

    def tracking_error(self, placement: pin.SE3, t: float) -> tuple[float, float]:
        """(position error [m], orientation error [rad]) of an object placement against the path at t [s]."""
        pose = self.path.pose(t)
        return (
            float(np.linalg.norm(placement.translation - pose.translation)),
            float(np.linalg.norm(pin.log3(pose.rotation.T @ placement.rotation))),
        )

    def run_figures(self, samples: Iterator[Sample]) -> dict[str, Any]:
        """Over a run's samples: the object's largest position error [m] and orientation error [rad] against
        the path; for a welded grasp the squeeze's set value, range and largest deviation [N] (and relative
        to the set value) and the largest other internal force [N, N m], measured from the closures'
        multipliers (:meth:`~pinstab.grasp.welded.WeldedGrasp.internal_force`)."""
        position, orientation, squeezes, others = [], [], [], []
        for sample in samples:
            errors = self.tracking_error(sample.kin.placement(self.object_frame), sample.t)
            position.append(errors[0])
            orientation.append(errors[1])
            if self.welds is not None:
                forces = np.concatenate([sample.multipliers[c.name] for c in self.contacts])
                if np.all(np.isfinite(forces)):
                    carrier = contact_rows(self.contacts, sample.kin, sample.t)[:, self.object_columns].T
                    squeeze, other = self.welds.internal_force(sample.kin, carrier, forces)
                    squeezes.append(squeeze)
                    others.append(other)
        if not position:
            return {}
        figures: dict[str, Any] = {
            "max_object_position_error": max(position),
            "max_object_orientation_error": max(orientation),
        }
        if self.welds is None or not squeezes:
            return figures
        target = self.welds.squeeze
        deviation = max(abs(value - target) for value in squeezes)
        figures.update(
            internal_force_set=target,
            internal_force_range=[min(squeezes), max(squeezes)],
            max_internal_force_deviation=deviation,
            max_other_internal_force=max(others),
        )
        if target:  # relative to a set value of zero: none
            figures["max_internal_force_deviation_relative"] = deviation / abs(target)
        return figures


@FORCE_KINDS.register(
    "grasp-control",
    summary="object-level computed torque along a pose path, internal forces kept in the cones (contacts) or set "
    "to a squeeze (two welds)",
)
def parse_grasp_control(entry: dict, tables: SceneTables, name: str, where: str) -> GraspControl:
    """Scene table: ``object``, ``contacts``, ``move`` [m], ``turn`` [rad], ``axis``, ``start`` and
    ``duration`` [s], ``kp`` [1/s^2], ``kd`` [1/s], ``posture_kp``, ``posture_kd``, ``margin`` [N],
    ``facets``, ``internal_forces`` (true); for a welded grasp ``closures`` (two welds) and ``squeeze`` [N]
    in place of ``contacts``, ``margin``, ``facets`` and ``internal_forces``."""
    tables.check_keys(entry, CONTROL_KEYS, where)
    welded = "closures" in entry
    if welded and "contacts" in entry:
        raise SceneError(f"{where}: give 'contacts' (a grasp on contacts) or 'closures' (a welded grasp), not both")
    for key in WELD_ONLY if not welded else CONTACT_ONLY:
        if key in entry:
            grasp, other = ("welded grasp ('closures')", "contacts") if welded else ("grasp on contacts", "closures")
            raise SceneError(f"{where}.{key} does not apply to a {grasp}: it goes with '{other}'")
    if welded:
        item, columns = grasped_object(entry, tables, where)
        welds = welded_grasp(entry, tables, item.joint, where)
        contacts = list(welds.closures)
    else:
        item, contacts, columns = grasped_contacts(entry, tables, where)
        welds = None
    move = tables.vector(entry.get("move", [0.0, 0.0, 0.0]), 3, f"{where}.move", "length")
    turn = tables.quantity(entry.get("turn", 0.0), "angle", f"{where}.turn")
    axis = tables.direction(entry.get("axis", [0.0, 0.0, 1.0]), f"{where}.axis")
    start = tables.quantity(entry.get("start", 0.0), "time", f"{where}.start")
    duration = tables.quantity(entry.get("duration", 1.0), "time", f"{where}.duration")
    if not duration > 0 or start < 0:
        raise SceneError(f"{where}: 'duration' must be > 0 and 'start' >= 0 [s]")
    gains = tuple(
        _non_negative(tables, entry, key, default, where)
        for key, default in (("kp", 400.0), ("kd", 40.0), ("posture_kp", 100.0), ("posture_kd", 20.0))
    )
    margin = tables.quantity(entry.get("margin", 0.1), "force", f"{where}.margin")
    facets = entry.get("facets", 8)
    if isinstance(facets, bool) or not isinstance(facets, int) or not 3 <= facets <= MAX_CONE_FACETS:
        raise SceneError(f"{where}.facets must be a whole number >= 3 (at most {MAX_CONE_FACETS}), got {facets!r}")
    internal = entry.get("internal_forces", True)
    if not isinstance(internal, bool):
        raise SceneError(f"{where}.internal_forces must be true or false, got {internal!r}")
    path = PosePath(tables.initial_placement(item.frame), move, turn, axis, start, duration)
    return GraspControl(
        name, tables.model, contacts, item.frame, columns, path, gains, margin, facets, internal, tables.q0, welds
    )


def _non_negative(tables: SceneTables, entry: dict, key: str, default: float, where: str) -> float:
    value = tables.number(entry, key, where, default=default)
    if value < 0:
        raise SceneError(f"{where}.{key} must be >= 0, got {value!r}")
    return within_ceiling(value, f"{where}.{key}", "1/s^2" if key.endswith("kp") else "1/s")

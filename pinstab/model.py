"""``ConstrainedModel``: a scene's mechanics, independent of how it is stepped.

It owns the Pinocchio model and one kinematics pass per state, the stacked constraint rows and the
force elements, and answers what the stabilizers, projection, assembly, stability maps and the viewer
ask: constraint values, mass matrix, energy, the terms of the KKT system, and integration on the
configuration group. The stepping system (:mod:`pinstab.system`) adds a stabilizer and a solver.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from .constraints import ConstraintSet, ConstraintValues, Violation
from .forces.base import batched
from .kinematics import Kinematics, symmetric_mass_matrix
from .memory import data_bytes, model_size, new_data, require
from .scene import Scene


class DynamicsTerms(NamedTuple):
    """The unconstrained dynamics and the constraint rows at one state.

    Attributes:
        mass_matrix: M [kg, kg m^2]. bias: h = C v + g [N, N m]. tau: applied forces [N, N m].
        values: constraint values with drift terms.
    """

    mass_matrix: np.ndarray
    bias: np.ndarray
    tau: np.ndarray
    values: ConstraintValues


class ConstrainedModel:
    """A scene's model, kinematics, constraint set and force elements.

    Args:
        scene: the scene.

    Attributes:
        scene: the scene. model: its Pinocchio model. kin: the kinematics pass.
        constraints: the stacked constraint rows. forces: the force elements.
        length_scale: the largest joint or frame offset [m], the mechanism's size.
        flat: every joint has one velocity coordinate. euclidean: and one configuration coordinate.
        forces_need_kinematics: some force element reads frame placements or Jacobians.
        no_force: a read-only zero vector (nv,), the applied force of a scene without force elements.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.model = scene.model
        require({"two Pinocchio Data": 2 * data_bytes(self.model.nv, self.model.njoints)}, model_size(self.model))
        self.kin = Kinematics(scene.model)
        self.constraints: ConstraintSet = scene.constraint_set
        self.forces = scene.forces
        self._evaluated = batched(self.forces)  # what applied_force calls: those of a class batched
        self.forces_need_kinematics = any(element.needs_kinematics for element in self.forces)
        self._data = new_data(scene.model)
        self._scratch_kin: Kinematics | None = None
        joints = [self.model.joints[j] for j in range(1, self.model.njoints)]
        self.flat = all(joint.nv == 1 for joint in joints)
        self.euclidean = self.flat and all(joint.nq == 1 for joint in joints)  # q (+) dq = q + dq
        self.no_force = np.zeros(self.model.nv)
        self._neutral = pin.neutral(self.model)
        self.no_force.flags.writeable = False
        placements = [*self.model.jointPlacements, *(frame.placement for frame in self.model.frames)]
        offsets = np.array([p.translation for p in placements]).reshape(-1, 3)
        with np.errstate(over="ignore"):  # an offset too large for floating point is refused at assembly
            self.length_scale = float(np.max(np.linalg.norm(offsets, axis=1), initial=0.0))

    @property
    def scratch(self) -> pin.Data:
        """A Pinocchio ``Data`` for one-off passes (mass matrix, energy, sizes, checks); each overwrites it.
        (A ``Data`` grows as nv^3 and is slow to build for a long chain: the passes share this one.)"""
        return self._data

    def position_tolerance(self, tolerance: float) -> float:
        """An absolute position tolerance [m or rad] for a relative one: ``tolerance`` times the
        mechanism's size in metres, at least 1 (rounding in the coordinates grows with their size;
        angles are of order 1)."""
        return tolerance * max(1.0, self.length_scale)

    @property
    def nv(self) -> int:
        """Velocity dimension."""
        return self.model.nv

    @property
    def nq(self) -> int:
        """Configuration dimension."""
        return self.model.nq

    def applied_force_at(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """:meth:`applied_force` at (q, v, t) [N, N m], after a Jacobian pass at q when a force element reads the
        kinematics (the compiled paths make none of their own in ``kin``)."""
        if self.forces_need_kinematics:
            self.kin.update_jacobians(q)
        return self.applied_force(v, t)

    def applied_force(self, v: np.ndarray, t: float, elements: list | None = None) -> np.ndarray:
        """Sum of the force elements [N, N m] (``elements``, default all); ``kin`` must be current where they need
        it."""
        elements = self._evaluated if elements is None else elements
        if not elements:
            return self.no_force
        tau = np.zeros(self.model.nv)
        for element in elements:
            tau += element.generalized_force(self.kin, v, t)
        return tau

    def dynamics_terms(self, q: np.ndarray, v: np.ndarray, t: float) -> DynamicsTerms:
        """One full kinematics pass at (q, v): M, h, applied forces and constraint values with drift (under the
        scene's gravity at t when it tilts)."""
        tau = self.forces_at(q, v, t)
        values = self.constraints.values(self.kin, q, v, t, with_drift=True)
        return DynamicsTerms(self.kin.mass_matrix, self.kin.bias, tau, values)

    def forces_at(self, q: np.ndarray, v: np.ndarray, t: float, elements: list | None = None) -> np.ndarray:
        """The force elements' sum [N, N m] (``elements``, default all) after one full kinematics pass at (q, v) in
        :attr:`kin` (M, h, placements, Jacobians, drifts: what an element may read), under the scene's gravity at t
        when it tilts."""
        tilt = self.scene.tilt
        if tilt is not None:
            self.model.gravity = pin.Motion(tilt.gravity(t), np.zeros(3))
        try:
            self.kin.update(q, v)
            return self.applied_force(v, t, elements)
        finally:
            if tilt is not None:
                self.model.gravity = pin.Motion(tilt.gravity0, np.zeros(3))

    def constraint_values(
        self, q: np.ndarray, v: np.ndarray, t: float, kin: Kinematics | None = None
    ) -> ConstraintValues:
        """phi, G, g at (q, v, t) without drift terms (one Jacobian pass in ``kin``: the model's own by default,
        :attr:`scratch_kinematics` for a one-off evaluation)."""
        kin = self.kin if kin is None else kin
        kin.update_jacobians(q)
        return self.constraints.values(kin, q, v, t, with_drift=False)

    @property
    def scratch_kinematics(self) -> Kinematics:
        """A :class:`Kinematics` over :attr:`scratch`, for one-off evaluations (the assembly before a run) that need
        not build the model's own ``Data`` (``kin``'s, built at first use: a run whose compiled kernel makes every
        pass never does)."""
        if self._scratch_kin is None:
            self._scratch_kin = Kinematics(self.model, self._data)
        return self._scratch_kin

    def violation(self, q: np.ndarray, v: np.ndarray, t: float) -> Violation:
        """The constraint violation at (q, v, t) [m or rad, m/s or rad/s]."""
        return self.constraints.violation(self.constraint_values(q, v, t))

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia M(q), symmetric [kg, kg m^2]."""
        nv = self.model.nv
        return symmetric_mass_matrix(self.model, self._data, q, np.empty((nv, nv)), self.kin.lower)

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic + gravity + spring energy [J]; placements at q must be current in ``kin``."""
        data = self._data
        kinetic = kinetic_energy(self.model, data, q, v)
        potential = pin.computePotentialEnergy(self.model, data, q)
        springs = sum(element.potential_energy(self.kin) for element in self.forces)
        return float(kinetic + potential + springs)

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q (+) dq on the configuration group."""
        return q + dq if self.euclidean else pin.integrate(self.model, q, dq)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The tangent vector dq with q0 (+) dq = q1."""
        return pin.difference(self.model, q0, q1)

    def magnitude(self, q: np.ndarray) -> np.ndarray:
        """The size of each coordinate of q in the tangent space (nv,) [rad or m]: ``|q|`` on models whose joints
        have one coordinate each, else ``|neutral (-) q|`` (angles of rotations, translations of free flyers);
        what a relative error tolerance is relative to."""
        if self.euclidean:
            return np.abs(q)
        return np.abs(pin.difference(self.model, self._neutral, q))

    def to_start_tangent(self, q: np.ndarray, q_stage: np.ndarray, v_stage: np.ndarray) -> np.ndarray:
        """A velocity at ``q_stage`` carried to the tangent space at ``q`` (exact ``dexp^-1`` through
        ``pin.dDifference``; the identity on models of 1-DOF joints)."""
        if self.flat:
            return v_stage
        return pin.dDifference(self.model, q, q_stage, pin.ArgumentPosition.ARG1) @ v_stage


def kinetic_energy(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray) -> float:
    """Kinetic energy [J] at (q, v): the bodies' (Pinocchio's sum, ``data`` left at (q, v)) and the rotors'
    ``armature . v^2 / 2`` (MJCF ``armature``, in the mass matrix Pinocchio's CRBA and ABA use). Pinocchio 4.1's
    ``computeKineticEnergy`` adds the rotors' on the joints of a coordinate axis only (on a revolute joint of
    another axis it adds a wrong term: a 1 % energy drift that is not there), so its sum is taken without them."""
    armature = np.array(model.armature)  # a copy: the model's own is overwritten below
    if not armature.any():
        return float(pin.computeKineticEnergy(model, data, q, v))
    model.armature = np.zeros(model.nv)
    try:
        bodies = pin.computeKineticEnergy(model, data, q, v)
    finally:
        model.armature = armature
    return float(bodies + 0.5 * armature @ (v * v))

"""Pinocchio 4.1's own contact solver as a peer: ADMM on Coulomb cones (``pin.ADMMConstraintSolver``).

Each contact of a scene becomes a ``pin.PointContactConstraintModel``. Pinocchio's convention: the
residual is ``e = R_c1^T (p_c2 - p_c1)`` in the axes of the frame c1 on joint 1, the multiplier is the
force of body 1 on body 2 in c1's axes, and the friction cone's normal is c1's z axis (3rd component).

* ``grasp-contact`` (``point-friction``): joint 1 is the object's, c1 the contact frame C on the object
  turned by pi about its x axis (axes ``(x, -y, -z)``: the normal out of the object, the direction in
  which the object pushes the finger); joint 2 is the finger's, c2 the finger's copy of C. Then
  ``e = -F R_C^T (p_o - p_f)`` with ``F = diag(1, -1, -1)``: pinstab's rows up to the fixed map F, at
  every state (also where the two material points have crept apart), and pinstab's multipliers (the
  force of the finger on the object in C) are ``-F`` times Pinocchio's. (With joint 1 the finger's, the
  residual would be in the finger's axes: equal on the constraint manifold only.)
* ``plane-contact`` with ``mu``: joint 1 is the world, c1 at the anchor with axes ``(t1, t2, n)``; joint
  2 the body. Pinocchio's multiplier is the ground's force on the body in ``(t1, t2, n)``, pinstab's the
  same in ``(n, t1, t2)``.

At the acceleration level the contact problem is the NCP ``D f + g in K*``, ``f in K`` with the Delassus
matrix ``D = J M^-1 J^T`` and ``g = J a_free + gamma + Kd J v + Kp e`` (``gamma``: Pinocchio's drift
``constraint_acceleration_error``; ``Kp``, ``Kd``: Baumgarte's gains on Pinocchio's own errors, 0 for the
plain drift). Sticking contacts inside their cones solve ``J a = -gamma - Kd J v - Kp e``: the rows
pinstab solves with ``method="none"`` (Kp = Kd = 0) or ``"baumgarte"`` (its Kp, Kd).

The stepping loop (:func:`run_peer`) applies the scene's ``grasp-hold`` and ``external-force`` elements
natively from the same Pinocchio pass, and steps either at the acceleration level (semi-implicit Euler
or RK4, an ADMM solve per stage, Baumgarte's corrector) or at the velocity level as Pinocchio's example
``admm-constraint-solver.py`` does (impulses on ``g = J v_free + (erp / dt) e``, with a compliance).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..constraints import PointContact
from ..constraints.contacts import contact_basis
from ..constraints.grasp_contacts import FingertipContact
from ..errors import PinstabError
from ..forces import ExternalForce
from ..grasp.hold import GraspHold
from ..kinematics import mirror_indices, symmetric_mass_matrix
from ..scene import Scene
from ..solvers.ncp import CONE_ORDER, NcpSolver

FLIP = np.diag([1.0, -1.0, -1.0])  # C turned by pi about x: the normal out of the object
PLANE_ORDER = CONE_ORDER.T  # (t1, t2, n) -> pinstab's (n, t1, t2)
ACCELERATION_SCHEMES = ("semi-implicit-euler", "rk4")
PEER_SCHEMES = (*ACCELERATION_SCHEMES, "velocity-level")


@dataclass(frozen=True)
class PeerContact:
    """One contact as a Pinocchio constraint model.

    Attributes:
        name: the scene's contact name. model: Pinocchio's constraint model.
        to_pinstab: 3 x 3: pinstab's multipliers = ``to_pinstab @`` Pinocchio's.
        axes: 3 x 3: the world axes of pinstab's multipliers are ``oMc1.rotation @ axes``.
        radius: for a plane contact (joint 1 the world), the radius [m] of a ball centred at c2's
            placement on its body, whose lowest point touches the plane; 0: c2 itself (a vertex).
    """

    name: str
    model: pin.PointContactConstraintModel
    to_pinstab: np.ndarray
    axes: np.ndarray
    radius: float = 0.0


def _grasp_contact(model: pin.Model, contact: FingertipContact) -> PeerContact:
    if contact.model != "point-friction":
        raise PinstabError(
            f"ADMM peer: grasp contact {contact.name!r} is {contact.model!r}; only point-friction contacts have a "
            "PointContactConstraintModel counterpart"
        )
    on_object, on_finger = model.frames[contact.object_frame], model.frames[contact.finger_frame]
    link = pin.PointContactConstraintModel(
        model,
        on_object.parentJoint,
        on_object.placement * pin.SE3(FLIP, np.zeros(3)),
        on_finger.parentJoint,
        on_finger.placement,
    )
    link.setFriction(contact.mu)
    return PeerContact(contact.name, link, -FLIP, FLIP)


def plane_contact(model: pin.Model, contact: PointContact, frictionless: bool = False) -> PeerContact:
    """A plane contact as a Pinocchio point contact with the world (c1 at the anchor, axes (t1, t2, n)),
    with the contact's radius.

    Args:
        frictionless: take a contact without mu as the cone mu = 0 (its normal ray); otherwise refuse it.

    Raises:
        PinstabError: a frictionless contact, unless ``frictionless``.
    """
    if contact.friction is None and not frictionless:
        raise PinstabError(f"ADMM peer: plane contact {contact.name!r} is frictionless; give it a mu (a cone)")
    normal, first, second = contact_basis(contact.selection[0])
    anchor = pin.SE3(np.column_stack([first, second, normal]), contact.plane_point)  # on the plane, whatever the radius
    frame = model.frames[contact.frame_a]
    link = pin.PointContactConstraintModel(model, 0, anchor, frame.parentJoint, frame.placement)
    link.setFriction(0.0 if contact.friction is None else contact.friction.mu)
    return PeerContact(contact.name, link, PLANE_ORDER, PLANE_ORDER.T, contact.radius)


def peer_contacts(scene: Scene) -> list[PeerContact]:
    """The scene's contacts as Pinocchio constraint models, in the scene's order.

    Raises:
        PinstabError: a constraint other than a point-friction grasp contact or a plane contact with mu.
    """
    contacts = []
    for constraint in scene.constraints:
        if isinstance(constraint, FingertipContact):
            contacts.append(_grasp_contact(scene.model, constraint))
        elif isinstance(constraint, PointContact):
            contacts.append(plane_contact(scene.model, constraint))
        else:
            raise PinstabError(
                f"ADMM peer: constraint {constraint.name!r} ({constraint.kind}) is not a contact; the peer takes "
                "point-friction grasp contacts and plane contacts with mu"
            )
    return contacts


@dataclass(frozen=True)
class AdmmSolution:
    """One ADMM solve.

    Attributes:
        forces: the contact forces in pinstab's convention, stacked in the scene's order like
            ``trajectory.multipliers`` [N] (for a velocity-level solve: the impulse over the step / dt).
        names: the contacts' names. iterations: ADMM iterations. converged: ADMM's flag.
        primal_feasibility, dual_feasibility, complementarity: ADMM's residuals at the end [m/s^2 or
            m/s, the velocity/acceleration units of g; complementarity their product with forces].
        motion: the generalized acceleration (acceleration level) [m/s^2, rad/s^2] or the velocity at the
            step's end (velocity level) [m/s, rad/s] the solve gives.
    """

    forces: np.ndarray
    names: tuple[str, ...]
    iterations: int
    converged: bool
    primal_feasibility: float
    dual_feasibility: float
    complementarity: float
    motion: np.ndarray = field(repr=False)

    def by_contact(self) -> dict[str, np.ndarray]:
        """The forces per contact name, 3 each [N]."""
        return {name: self.forces[3 * i : 3 * i + 3] for i, name in enumerate(self.names)}


@dataclass(frozen=True)
class ContactTerms:
    """Pinocchio's terms at one state.

    Attributes:
        mass: M [kg, kg m^2] (symmetric). bias: h = C v + g [N, N m]. jacobian: J (3 n x nv).
        position: e [m]. velocity: J v [m/s]. drift: gamma, J's rate times v [m/s^2].
    """

    mass: np.ndarray
    bias: np.ndarray
    jacobian: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    drift: np.ndarray


def mass_solves(terms: ContactTerms, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M^-1 J^T, the free acceleration M^-1 (tau - h) [m/s^2, rad/s^2]) in one solve."""
    solved = np.linalg.solve(terms.mass, np.column_stack([terms.jacobian.T, tau - terms.bias]))
    return solved[:, :-1], solved[:, -1]


class AdmmContactPeer:
    """The contact problem of a scene's contacts, solved by Pinocchio's ADMM (in NCP mode).

    Args:
        scene: a scene whose constraints are point-friction grasp contacts and plane contacts with mu
            (:meth:`from_contacts`: a Pinocchio model and its contacts instead).
        tolerance: ADMM's absolute and relative feasibility and complementarity tolerances.
        max_iterations: ADMM's iteration limit.
        compliance: the compliance R added to the Delassus matrix's diagonal [(m/s)/(N s) at the velocity
            level, (m/s^2)/N at the acceleration level], 0 for rigid contacts.
        warm_start: start each solve from the previous one's forces.
    """

    def __init__(
        self,
        scene: Scene,
        tolerance: float = 1e-12,
        max_iterations: int = 10_000,
        compliance: float = 0.0,
        warm_start: bool = False,
    ) -> None:
        self._build(scene.model, peer_contacts(scene), tolerance, max_iterations, compliance, warm_start)

    @classmethod
    def from_contacts(
        cls,
        model: pin.Model,
        contacts: list[PeerContact],
        tolerance: float = 1e-12,
        max_iterations: int = 10_000,
        compliance: float = 0.0,
        warm_start: bool = False,
    ) -> AdmmContactPeer:
        """The peer of a Pinocchio ``model`` with the given contacts (the other arguments: the constructor's)."""
        peer = cls.__new__(cls)
        peer._build(model, contacts, tolerance, max_iterations, compliance, warm_start)
        return peer

    def _build(
        self,
        model: pin.Model,
        contacts: list[PeerContact],
        tolerance: float,
        max_iterations: int,
        compliance: float,
        warm_start: bool,
    ) -> None:
        self.model = model
        self.data = pin.Data(self.model)
        self.contacts = contacts
        self.models, self.datas = pin.StdVec_ConstraintModel(), pin.StdVec_ConstraintData()
        for contact in self.contacts:
            self.models.append(contact.model)
            self.datas.append(self.models[len(self.models) - 1].createData())
        # balls: (index, joint 2, c2's placement at the centre, -r n in world axes): c2 is moved to the
        # lowest point at every pass
        self._balls = [
            (
                i,
                contact.model.joint2_id,
                contact.model.joint2_placement.translation.copy(),
                -contact.radius * contact.model.joint1_placement.rotation[:, 2],
            )
            for i, contact in enumerate(contacts)
            if contact.radius > 0.0
        ]
        self.size = 3 * len(self.contacts)
        self.to_pinstab = np.zeros((self.size, self.size))
        for i, contact in enumerate(self.contacts):
            self.to_pinstab[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = contact.to_pinstab
        self.names = tuple(contact.name for contact in self.contacts)
        self.ncp = NcpSolver(self.size, tolerance, max_iterations, compliance, warm_start)
        self._options = (tolerance, max_iterations, compliance, warm_start)
        self._subsets: dict[tuple[int, ...], NcpSolver] = {}
        self._last = self.ncp
        self._zero = np.zeros(self.model.nv)
        self._lower = mirror_indices(self.model.nv)

    def terms(self, q: np.ndarray, v: np.ndarray) -> ContactTerms:
        """One Pinocchio pass at (q, v): M, h, the contacts' Jacobian, errors and drift (a ball's contact
        point c2 placed at its lowest point first, so that its normal error is the ball's gap)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, self._zero)
        pin.computeJointJacobians(model, data)  # from the placements just computed
        for i, joint, centre, lowest in self._balls:
            self.models[i].extract().joint2_placement = pin.SE3(np.eye(3), centre + data.oMi[joint].rotation.T @ lowest)
        for contact_model, contact_data in zip(self.models, self.datas, strict=True):
            contact_model.calc(model, data, contact_data)
        extracted = [contact_data.extract() for contact_data in self.datas]
        jacobian = pin.getConstraintsJacobian(model, data, self.models, self.datas)
        return ContactTerms(
            symmetric_mass_matrix(model, data, q, np.empty((model.nv, model.nv)), self._lower),
            pin.nle(model, data, q, v),
            jacobian,
            np.concatenate([d.constraint_position_error for d in extracted]),
            jacobian @ v,
            np.concatenate([d.constraint_acceleration_error for d in extracted]),
        )

    def world_forces(self, solution: AdmmSolution) -> np.ndarray:
        """The last solve's forces in world axes, one row per contact (n, 3) [N]: on the body of a plane
        contact, of the finger on the object for a grasp contact; ``datas`` must be of that solve."""
        rows = []
        for i, (contact, contact_data) in enumerate(zip(self.contacts, self.datas, strict=True)):
            rotation = contact_data.extract().oMc1.rotation
            rows.append(rotation @ contact.axes @ solution.forces[3 * i : 3 * i + 3])
        return np.array(rows)

    def _problem(self, active: tuple[int, ...] | None):
        """(models, datas, solver) of the contacts ``active`` (None: all); a subset's solver is kept for its
        next solve (warm start)."""
        if active is None:
            return self.models, self.datas, self.ncp
        models, datas = pin.StdVec_ConstraintModel(), pin.StdVec_ConstraintData()
        for i in active:
            models.append(self.models[i])
            datas.append(self.datas[i])
        if active not in self._subsets:
            self._subsets[active] = NcpSolver(3 * len(active), *self._options)
        return models, datas, self._subsets[active]

    def _solve(
        self, mass_inverse_jt: np.ndarray, jacobian: np.ndarray, g: np.ndarray, active: tuple[int, ...] | None = None
    ) -> np.ndarray:
        """ADMM on ``D f + g``, D = J M^-1 J^T (+ compliance), over the contacts ``active`` (None: all;
        ``jacobian``, ``g`` their rows): the forces in Pinocchio's convention."""
        models, datas, ncp = self._problem(active)
        self._last = ncp
        return ncp.solve(jacobian @ mass_inverse_jt, g, models, datas)

    def _solution(self, pinocchio_forces: np.ndarray, motion: np.ndarray, scale: float) -> AdmmSolution:
        """The last solve's result; pinstab's forces are ``scale`` times the converted ones."""
        return AdmmSolution(self.to_pinstab @ pinocchio_forces * scale, self.names, *self._last.status(), motion)

    def active_impulses(
        self, active: tuple[int, ...], mass_inverse_jt: np.ndarray, jacobian: np.ndarray, g: np.ndarray
    ) -> AdmmSolution:
        """The impulses [N s] of the contacts ``active`` alone on ``D p + g`` (``mass_inverse_jt``,
        ``jacobian`` and ``g`` [m/s]: their rows), pinstab's convention, 0 for the other contacts; its
        ``motion`` is the velocity change M^-1 J^T p [m/s, rad/s]."""
        impulses = self._solve(mass_inverse_jt, jacobian, g, active)
        every = np.zeros(self.size)
        for k, i in enumerate(active):
            every[3 * i : 3 * i + 3] = impulses[3 * k : 3 * k + 3]
        return self._solution(every, mass_inverse_jt @ impulses, 1.0)

    def solve(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, kp: float = 0.0, kd: float = 0.0) -> AdmmSolution:
        """The contact forces at (q, v) under the applied generalized forces ``tau`` [N, N m], at the
        acceleration level with Baumgarte's ``kp`` [1/s^2] and ``kd`` [1/s] (0: the plain drift).

        Returns:
            the solution; its ``motion`` is the acceleration a [m/s^2, rad/s^2].
        """
        return self.acceleration_solve(self.terms(q, v), tau, kp, kd)

    def acceleration_solve(self, terms: ContactTerms, tau: np.ndarray, kp: float, kd: float) -> AdmmSolution:
        """:meth:`solve` on the terms of a pass at the state (:meth:`terms`)."""
        mass_inverse_jt, free = mass_solves(terms, tau)
        g = terms.jacobian @ free + terms.drift + kd * terms.velocity + kp * terms.position
        forces = self._solve(mass_inverse_jt, terms.jacobian, g)
        return self._solution(forces, free + mass_inverse_jt @ forces, 1.0)

    def impulse_step(self, terms: ContactTerms, v: np.ndarray, tau: np.ndarray, dt: float, erp: float) -> AdmmSolution:
        """A velocity-level step from Pinocchio's example: ``v_free = v + dt M^-1 (tau - h)``, impulses
        on ``g = J v_free + (erp / dt) e`` (``erp``: the fraction [-] of the position error removed per
        step), forces = impulses / dt [N].

        Returns:
            the solution; its ``motion`` is the velocity at the step's end [m/s, rad/s].
        """
        mass_inverse_jt, acceleration = mass_solves(terms, tau)
        free = v + dt * acceleration
        g = terms.jacobian @ free + (erp / dt) * terms.position
        impulses = self._solve(mass_inverse_jt, terms.jacobian, g)
        return self._solution(impulses, free + mass_inverse_jt @ impulses, 1.0 / dt)


def admm_contact_forces(scene: Scene, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """World-axes contact forces (n, 3) [N] of Pinocchio's ADMM (tolerances 1e-12) at (q, v) under the
    applied forces ``tau`` [N, N m], acceleration level without Baumgarte terms: on the body of each
    plane contact, of the finger on the object for each grasp contact.

    Raises:
        PinstabError: ADMM did not converge.
    """
    peer = AdmmContactPeer(scene)
    solution = peer.solve(q, v, tau)
    if not solution.converged:
        raise PinstabError(f"ADMM did not converge in {solution.iterations} iterations")
    return peer.world_forces(solution)


# -- the scene's force elements, from the peer's own Pinocchio pass ---------------------------------------
class PeerForces:
    """The applied forces of the scene's ``grasp-hold`` and ``external-force`` elements, computed from
    the peer's Pinocchio data and contact Jacobian (pinstab's rows are ``to_pinstab @ J``).

    Raises:
        PinstabError: another force element.
    """

    def __init__(self, scene: Scene, peer: AdmmContactPeer) -> None:
        self.peer = peer
        self.holds, self.pushes = [], []
        for element in scene.forces:
            if isinstance(element, GraspHold):
                index = [peer.names.index(contact.name) for contact in element.contacts]
                rows = np.concatenate([np.arange(3 * i, 3 * i + 3) for i in index])
                self.holds.append((element, rows))
            elif isinstance(element, ExternalForce):
                self.pushes.append(element)
            else:
                raise PinstabError(f"ADMM peer: force element {element.name!r} is not a grasp hold or external force")

    def __call__(self, q: np.ndarray, v: np.ndarray, jacobian: np.ndarray) -> np.ndarray:
        """tau [N, N m] at (q, v); the peer's ``terms`` at q must be current (``jacobian`` its J)."""
        model, data = self.peer.model, self.peer.data
        tau = np.zeros(model.nv)
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for push in self.pushes:
            tau += pin.getFrameJacobian(model, data, push.frame, world).T @ push.wrench
        if self.holds:
            gravity = pin.computeGeneralizedGravity(model, data, q)
            rows = self.peer.to_pinstab @ jacobian
            for hold, selected in self.holds:
                tau += hold.torques(rows[selected], gravity, q, v)
        return tau


# -- the stepping loop ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PeerRun:
    """A run of the peer loop, kept every ``record_every`` steps.

    Attributes:
        t: [s]. q, v: the states. forces: the contact forces of the step from each kept state, pinstab's
            convention [N]. cpu_s: CPU seconds of the loop. iterations: ADMM iterations per solve
            (mean, max). worst_primal, worst_dual, worst_complementarity: ADMM's largest residuals.
        failed: ADMM solves that did not converge.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    forces: np.ndarray
    cpu_s: float
    iterations: tuple[float, int]
    worst_primal: float
    worst_dual: float
    worst_complementarity: float
    failed: int


@dataclass
class SolveStatistics:
    """ADMM's iterations per solve, its largest residuals and the solves that did not converge."""

    iterations: list[int] = field(default_factory=list)
    primal: float = 0.0
    dual: float = 0.0
    complementarity: float = 0.0
    failed: int = 0

    def add(self, solution: AdmmSolution) -> AdmmSolution:
        """Count one solve; returns it."""
        self.iterations.append(solution.iterations)
        self.primal = max(self.primal, solution.primal_feasibility)
        self.dual = max(self.dual, solution.dual_feasibility)
        self.complementarity = max(self.complementarity, solution.complementarity)
        self.failed += not solution.converged
        return solution


@dataclass(frozen=True)
class PeerSettings:
    """The peer loop's settings.

    Attributes:
        scheme: one of :data:`PEER_SCHEMES`. dt: step [s].
        kp, kd: Baumgarte's gains [1/s^2], [1/s] (acceleration-level schemes).
        erp: the fraction of the position error removed per step [-] (velocity level).
        compliance: the contacts' compliance (see :class:`AdmmContactPeer`).
        tolerance: ADMM's tolerances. warm_start: start each solve from the previous forces.
    """

    scheme: str
    dt: float
    kp: float = 100.0
    kd: float = 20.0
    erp: float = 0.2
    compliance: float = 0.0
    tolerance: float = 1e-12
    warm_start: bool = True


def _acceleration_step(peer: AdmmContactPeer, forces: PeerForces, settings: PeerSettings, statistics: SolveStatistics):
    """``step(q, v) -> (q, v, forces at q)`` of semi-implicit Euler or RK4 on ADMM's accelerations (RK4 on
    the configuration group: stage velocities carried back to q's tangent space with ``pin.dDifference``,
    as pinstab's RK4 does)."""
    model, dt, kp, kd = peer.model, settings.dt, settings.kp, settings.kd
    integrate = pin.integrate

    def solve(q: np.ndarray, v: np.ndarray) -> AdmmSolution:
        terms = peer.terms(q, v)
        return statistics.add(peer.acceleration_solve(terms, forces(q, v, terms.jacobian), kp, kd))

    def euler(q: np.ndarray, v: np.ndarray):
        first = solve(q, v)
        v = v + dt * first.motion
        return integrate(model, q, dt * v), v, first.forces

    half, sixth = 0.5 * dt, dt / 6.0
    stage_position = pin.ArgumentPosition.ARG1

    def slope(q: np.ndarray, q_stage: np.ndarray, v_stage: np.ndarray) -> np.ndarray:
        """A stage velocity carried to the tangent space at q (the free flyer's dexp^-1)."""
        return pin.dDifference(model, q, q_stage, stage_position) @ v_stage

    def rk4(q: np.ndarray, v: np.ndarray):
        first = solve(q, v)
        a1 = first.motion
        v2, q2 = v + half * a1, integrate(model, q, half * v)
        a2 = solve(q2, v2).motion
        k2 = slope(q, q2, v2)
        v3, q3 = v + half * a2, integrate(model, q, half * k2)
        a3 = solve(q3, v3).motion
        k3 = slope(q, q3, v3)
        v4, q4 = v + dt * a3, integrate(model, q, dt * k3)
        a4 = solve(q4, v4).motion
        q_next = integrate(model, q, sixth * (v + 2.0 * (k2 + k3) + slope(q, q4, v4)))
        return q_next, v + sixth * (a1 + 2.0 * (a2 + a3) + a4), first.forces

    return euler if settings.scheme == "semi-implicit-euler" else rk4


def _velocity_step(peer: AdmmContactPeer, forces: PeerForces, settings: PeerSettings, statistics: SolveStatistics):
    """``step(q, v) -> (q, v, forces)`` of the velocity-level scheme (impulses, then q with v_next)."""
    model, dt, erp = peer.model, settings.dt, settings.erp

    def step(q: np.ndarray, v: np.ndarray):
        terms = peer.terms(q, v)
        solution = statistics.add(peer.impulse_step(terms, v, forces(q, v, terms.jacobian), dt, erp))
        return pin.integrate(model, q, dt * solution.motion), solution.motion, solution.forces

    return step


def run_peer(
    scene: Scene, q0: np.ndarray, v0: np.ndarray, settings: PeerSettings, duration: float, record_every: int = 1
) -> PeerRun:
    """Step the scene from (q0, v0) for ``duration`` [s] with Pinocchio's ADMM, keeping every
    ``record_every``-th state (and its step's contact forces); the last state's forces are solved
    after the loop (not timed).

    Raises:
        PinstabError: an unknown scheme, or what :func:`peer_contacts` and :class:`PeerForces` refuse.
    """
    if settings.scheme not in PEER_SCHEMES:
        raise PinstabError(f"unknown ADMM peer scheme {settings.scheme!r}; schemes: {', '.join(PEER_SCHEMES)}")
    peer = AdmmContactPeer(scene, settings.tolerance, compliance=settings.compliance, warm_start=settings.warm_start)
    forces = PeerForces(scene, peer)
    statistics = SolveStatistics()
    build = _velocity_step if settings.scheme == "velocity-level" else _acceleration_step
    step = build(peer, forces, settings, statistics)
    return run_loop(step, q0, v0, settings.dt, duration, record_every, peer.size, statistics)


def run_loop(
    step,
    q0: np.ndarray,
    v0: np.ndarray,
    dt: float,
    duration: float,
    record_every: int,
    size: int,
    statistics: SolveStatistics,
) -> PeerRun:
    """Apply ``step(q, v) -> (q, v, forces)`` (steps of ``dt`` [s], ``size`` forces) for ``duration`` [s]
    from (q0, v0), keeping every ``record_every``-th state and its step's forces; the last state's forces
    come from one more step after the loop (not timed). ``statistics`` collects the step's ADMM solves."""
    steps = round(duration / dt)
    kept = steps // record_every + 1
    qs, vs, fs = np.empty((kept, len(q0))), np.empty((kept, len(v0))), np.empty((kept, size))
    q, v = q0.copy(), v0.copy()
    qs[0], vs[0] = q, v
    began = time.process_time()
    for k in range(1, steps + 1):
        q, v, contact = step(q, v)
        if (k - 1) % record_every == 0:
            fs[(k - 1) // record_every] = contact
        if k % record_every == 0:
            qs[k // record_every], vs[k // record_every] = q, v
    cpu = time.process_time() - began
    fs[-1] = step(q, v)[2]
    iterations = statistics.iterations or [0]
    return PeerRun(
        np.arange(kept) * record_every * dt,
        qs,
        vs,
        fs,
        cpu,
        (float(np.mean(iterations)), int(np.max(iterations))),
        statistics.primal,
        statistics.dual,
        statistics.complementarity,
        statistics.failed,
    )

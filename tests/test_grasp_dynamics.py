"""The Lagrange-d'Alembert object-space form of a grasp (docs/mathematics.md section 4, [MLS 6.2]) against the full KKT
solution (docs/mathematics.md eq. 4), on trifinger-cube (three 3-DOF fingers, three point contacts: J_h is 9 x 9).

Everything on the object-space side is built here, without pinstab's constraint rows: the contact points and
frames from the cube's geometry at the start (contact point = fingertip centre projected on the nearest face,
z = the inward face normal, tangents of our own choosing), G from :mod:`pinstab.grasp`, J_h from Pinocchio
frame Jacobians of the fingertip material points rotated into the contact frames (which move with the cube),
M, C, N from Pinocchio, and the velocity-product term ``w = d/dt(J_h) theta_dot - d/dt(G^T) xi`` from
Pinocchio's classical accelerations (checked against a finite difference along the zero-acceleration flow).
With ``theta_dot = J_h^-1 G^T xi`` and ``theta_ddot = J_h^-1 (G^T xi_dot - w)``, the hand's equation
``M_h theta_ddot + h_h + J_h^T f = tau_h`` and the object's ``M_o xi_dot + h_o = G f + tau_o`` give

    M~ xi_dot + C~ xi + N~ = F~,   M~ = M_o + G J_h^-T M_h J_h^-1 G^T,
    C~ xi = C_o xi + G J_h^-T (C_h theta_dot - M_h J_h^-1 w),   N~ = N_o + G J_h^-T N_h,   F~ = G J_h^-T tau_h + tau_o.

The object's velocity xi is Pinocchio's free-flyer velocity: the body twist, linear first, in the cube frame,
so the contact frames are fixed in it and d/dt(G) = 0 there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

from pinstab import load_scene, simulate
from pinstab.grasp import GraspContact, analyse_grasp, grasp_map
from pinstab.model import ConstrainedModel
from pinstab.scene import Scene
from pinstab.system import build_system

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FINGERS = ("finger0_", "finger120_", "finger240_")
CUBE_EDGE = 0.065  # [m], robots/trifinger-cube.toml
TIP_RADIUS = 0.0095  # [m]
ACCELERATION_TOLERANCE = 1e-9  # [m/s^2, rad/s^2]
FORCE_TOLERANCE = 1e-9  # [N]
TOUCH_TOLERANCE = 1e-9  # [m]: the loader closed the gap to the face
NEWTON_STEPS = 3
RATE_STEP = 1e-6  # [s]: central difference of the contact velocities along the zero-acceleration flow


@dataclass
class Grasp:
    """The grasp as built here: a model with our own frames at the fingertip material points, the contacts
    (positions and frames in the cube frame) and the column split."""

    model: pin.Model
    data: pin.Data
    points: list[int]
    contacts: list[GraspContact]
    cube_frame: int
    hand: np.ndarray
    cube: np.ndarray

    @property
    def grasp_map(self) -> np.ndarray:
        return grasp_map(self.contacts)


def face_contact(centre: np.ndarray, name: str) -> GraspContact:
    """The contact of a fingertip sphere centred at ``centre`` (cube frame) [m] touching the nearest face: the
    point of the sphere on the face's inward normal (on the face within the loader's gap, asserted below 1e-9 m;
    the acceleration is sensitive to where the contact point is, see the comparison's docstring), z the inward
    normal, tangents our own (not pinstab's: the cube's acceleration does not depend on them)."""
    axis = int(np.argmax(np.abs(centre)))
    side = float(np.sign(centre[axis]))
    assert abs(abs(centre[axis]) - CUBE_EDGE / 2 - TIP_RADIUS) < TOUCH_TOLERANCE  # touching, from outside
    normal = -side * np.eye(3)[axis]
    point = centre + TIP_RADIUS * normal
    assert np.all(np.abs(np.delete(point, axis)) < CUBE_EDGE / 2)  # inside the face
    first = np.eye(3)[(axis + 1) % 3]
    return GraspContact(name, "point-friction", point, np.column_stack([first, np.cross(normal, first), normal]), 0.8)


def build_grasp(scene: Scene) -> Grasp:
    """Contacts from the cube's geometry at the scene's start; our own frames at the fingertip material points."""
    model = scene.model.copy()
    data = model.createData()
    pin.framesForwardKinematics(model, data, scene.q0)
    cube = scene.objects[0]
    world_cube = data.oMf[cube.frame]
    contacts, points = [], []
    for prefix in FINGERS:
        tip = model.getFrameId(f"{prefix}finger_tip_link", pin.FrameType.BODY)
        contact = face_contact(world_cube.actInv(data.oMf[tip].translation), prefix)
        on_tip = data.oMf[tip].actInv(world_cube.act(contact.position))
        frame = model.frames[tip]
        points.append(
            model.addFrame(
                pin.Frame(
                    f"lda/{prefix}", frame.parentJoint, tip, frame.placement * pin.SE3(np.eye(3), on_tip), pin.OP_FRAME
                )
            )
        )
        contacts.append(contact)
    joint = model.joints[cube.joint]
    cube_columns = np.arange(joint.idx_v, joint.idx_v + 6)
    hand = np.setdiff1d(np.arange(model.nv), cube_columns)
    return Grasp(model, model.createData(), points, contacts, cube.frame, hand, cube_columns)


def contact_rotations(grasp: Grasp) -> list[np.ndarray]:
    """World axes of the contact frames (they move with the cube); placements must be current."""
    cube = grasp.data.oMf[grasp.cube_frame].rotation
    return [cube @ contact.rotation for contact in grasp.contacts]


def hand_jacobian(grasp: Grasp) -> np.ndarray:
    """J_h (9 x 9): fingertip material point velocities in the contact frames per hand joint rate."""
    rotations = contact_rotations(grasp)
    rows = [
        rotation.T @ pin.getFrameJacobian(grasp.model, grasp.data, point, LWA)[:3]
        for rotation, point in zip(rotations, grasp.points, strict=True)
    ]
    return np.vstack(rows)[:, grasp.hand]


def update(grasp: Grasp, q: np.ndarray, v: np.ndarray) -> None:
    """Placements, Jacobians and zero-acceleration motions at (q, v)."""
    pin.forwardKinematics(grasp.model, grasp.data, q, v, np.zeros(grasp.model.nv))
    pin.computeJointJacobians(grasp.model, grasp.data)
    pin.updateFramePlacements(grasp.model, grasp.data)


def velocity_product(grasp: Grasp, v: np.ndarray) -> np.ndarray:
    """w = d/dt(J_h) theta_dot - d/dt(G^T) xi at zero accelerations (9,) [m/s^2]: the fingertip points'
    classical accelerations seen from the contact frames, which turn with the cube (G^T xi is fixed in the
    cube frame, so its rate is zero)."""
    omega = grasp.data.oMf[grasp.cube_frame].rotation @ v[grasp.cube[3:]]
    terms = []
    for rotation, point in zip(contact_rotations(grasp), grasp.points, strict=True):
        acceleration = pin.getFrameClassicalAcceleration(grasp.model, grasp.data, point, LWA).linear
        velocity = pin.getFrameVelocity(grasp.model, grasp.data, point, LWA).linear
        terms.append(rotation.T @ (acceleration - np.cross(omega, velocity)))
    return np.concatenate(terms)


def separation(grasp: Grasp) -> np.ndarray:
    """Fingertip material points minus the cube's contact points, in the contact frames (9,) [m]."""
    cube = grasp.data.oMf[grasp.cube_frame]
    return np.concatenate(
        [
            rotation.T @ (grasp.data.oMf[point].translation - cube.act(contact.position))
            for rotation, point, contact in zip(contact_rotations(grasp), grasp.points, grasp.contacts, strict=True)
        ]
    )


def on_grasp(grasp: Grasp, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The state (q, v) with the fingers moved onto the grasp exactly (cube held): Newton on the finger joints
    (J_h is d separation / d theta), then theta_dot = J_h^-1 G^T xi."""
    q = q.copy()
    for _ in range(NEWTON_STEPS):
        update(grasp, q, v)
        step = np.zeros(grasp.model.nv)
        step[grasp.hand] = -np.linalg.solve(hand_jacobian(grasp), separation(grasp))
        q = pin.integrate(grasp.model, q, step)
    update(grasp, q, v)
    assert np.abs(separation(grasp)).max() < 1e-15
    v = v.copy()
    v[grasp.hand] = np.linalg.solve(hand_jacobian(grasp), grasp.grasp_map.T @ v[grasp.cube])
    return q, v


def relative_velocity(grasp: Grasp, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """J_h theta_dot - G^T xi at (q, v) [m/s] (zero on the grasp)."""
    update(grasp, q, v)
    return hand_jacobian(grasp) @ v[grasp.hand] - grasp.grasp_map.T @ v[grasp.cube]


def velocity_product_by_difference(grasp: Grasp, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """w as the central difference of J_h theta_dot - G^T xi along q(s) = q (+) s v with v held: Pinocchio's
    velocity coordinates (joint rates, the cube's body twist) constant is zero acceleration."""
    forward = relative_velocity(grasp, pin.integrate(grasp.model, q, RATE_STEP * v), v)
    backward = relative_velocity(grasp, pin.integrate(grasp.model, q, -RATE_STEP * v), v)
    return (forward - backward) / (2.0 * RATE_STEP)


@dataclass
class ObjectSpace:
    """The object-space solution: the cube's acceleration [m/s^2, rad/s^2] and the contact forces of the
    fingers on the cube in world axes (3 per contact) [N]."""

    acceleration: np.ndarray
    forces: np.ndarray
    hand_jacobian: np.ndarray


def lagrange_dalembert(grasp: Grasp, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> ObjectSpace:
    """M~ xi_dot + C~ xi + N~ = F~ at (q, v) under the applied forces ``tau`` [N, N m]."""
    model, data, hand, cube = grasp.model, grasp.data, grasp.hand, grasp.cube
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    gravity = pin.computeGeneralizedGravity(model, data, q)
    coriolis = pin.nonLinearEffects(model, data, q, v) - gravity  # C v
    update(grasp, q, v)
    jacobian = hand_jacobian(grasp)
    inverse = np.linalg.inv(jacobian)
    G, w = grasp.grasp_map, velocity_product(grasp, v)
    M_h, M_o = mass[np.ix_(hand, hand)], mass[np.ix_(cube, cube)]
    assert np.abs(mass[np.ix_(hand, cube)]).max() == 0.0  # the fingers and the cube are separate bodies
    to_object = G @ inverse.T
    M_tilde = M_o + to_object @ M_h @ inverse @ G.T
    C_tilde_xi = coriolis[cube] + to_object @ (coriolis[hand] - M_h @ inverse @ w)
    N_tilde = gravity[cube] + to_object @ gravity[hand]
    F_tilde = to_object @ tau[hand] + tau[cube]
    xi_dot = np.linalg.solve(M_tilde, F_tilde - C_tilde_xi - N_tilde)
    theta_ddot = inverse @ (G.T @ xi_dot - w)
    force = inverse.T @ (tau[hand] - M_h @ theta_ddot - coriolis[hand] - gravity[hand])
    return ObjectSpace(xi_dot, world_forces(grasp, force), jacobian)


def world_forces(grasp: Grasp, force: np.ndarray) -> np.ndarray:
    """Contact forces in their contact frames (3 per contact) turned into world axes [N]."""
    blocks = force.reshape(-1, 3)
    return np.concatenate([rotation @ block for rotation, block in zip(contact_rotations(grasp), blocks, strict=True)])


def numpy_kkt(grasp: Grasp, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The cube's acceleration from the full KKT system (docs/mathematics.md eq. 4) solved with numpy, the constraint
    ``A = [J_h, -G^T]`` built here (rows: J_h theta_ddot - G^T xi_dot = -w)."""
    model, data = grasp.model, grasp.data
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.nonLinearEffects(model, data, q, v)
    update(grasp, q, v)
    rows = np.zeros((9, model.nv))
    rows[:, grasp.hand] = hand_jacobian(grasp)
    rows[:, grasp.cube] = -grasp.grasp_map.T
    kkt = np.block([[mass, rows.T], [rows, np.zeros((9, 9))]])
    solution = np.linalg.solve(kkt, np.concatenate([tau - bias, -velocity_product(grasp, v)]))
    return solution[grasp.cube]


@pytest.fixture(scope="module")
def run():
    """trifinger-cube for 1 s: the 0.1 N push and 2 mN m twist of the scene move the cube."""
    scene = load_scene("trifinger-cube")
    trajectory = simulate(scene, method="baumgarte", integrator="rk4", dt=1e-3, duration=1.0, record_every=10)
    return scene, trajectory


def test_the_cube_moves_and_the_grasp_holds(run):
    """The scene's run (what ``pinstab run trifinger-cube --duration 1`` does): the cube moves by millimetres and
    turns, every contact keeps pressing inside its cone, the drift stays below 1e-8."""
    scene, trajectory = run
    cube = scene.objects[0]
    joint = scene.model.joints[cube.joint]
    position = trajectory.q[:, cube.idx_q : cube.idx_q + 3]
    spin = np.linalg.norm(trajectory.v[:, joint.idx_v + 3 : joint.idx_v + 6], axis=1)
    summary = trajectory.summary()
    assert np.linalg.norm(position - position[0], axis=1).max() > 5e-3  # [m]
    assert spin.max() > 0.1  # [rad/s]
    assert summary["max_position_drift"] <= 1e-8
    assert summary["min_normal_force"] > 1.0 and summary["min_cone_margin"] > 0.5  # [N]


def test_the_grasp_is_force_closure():
    """The three point contacts (mu = 0.8) on the cube: G is onto and the grasp is force closure."""
    analysis = analyse_grasp(build_grasp(load_scene("trifinger-cube")).contacts, length=CUBE_EDGE / 2)
    assert analysis.rank == 6 and analysis.force_closure
    assert analysis.quality > 0.3  # [N] per unit total normal force, moments over half the edge


def test_velocity_product_matches_a_finite_difference(run):
    """Pinocchio's classical accelerations give w; the central difference along the flow agrees to 1e-6."""
    scene, trajectory = run
    grasp = build_grasp(scene)
    worst = 0.0
    for q, v in zip(trajectory.q[::10], trajectory.v[::10], strict=True):
        update(grasp, q, v)
        exact = velocity_product(grasp, v)
        difference = velocity_product_by_difference(grasp, q, v)
        worst = max(worst, float(np.abs(exact - difference).max() / max(np.abs(exact).max(), 1e-3)))
    assert worst < 1e-6


def test_object_space_form_equals_the_kkt_solution(run):
    """At every recorded sample, put on the grasp exactly (a shift below 1e-9), the object-space form gives
    pinstab's KKT cube acceleration (baumgarte, dense) and a plain numpy KKT solve's within 1e-9, and the same
    fingertip forces as pinstab's multipliers (in world axes) within 1e-9 N.

    The samples themselves are off the grasp by the run's drift (~1e-12 m), which the object-space form cannot
    see: with 2 N contact forces on a cube of rotational inertia 7e-5 kg m^2, moving a contact point by d
    changes the angular acceleration by about 2 N d / I = 3e4 d, i.e. some 1e-8 rad/s^2 at the raw samples."""
    scene, trajectory = run
    grasp = build_grasp(scene)
    model = ConstrainedModel(scene)
    system = build_system(model, "baumgarte", "dense")
    frames = [c.object_frame for c in scene.constraints]
    worst = {"pinstab": 0.0, "numpy": 0.0, "force": 0.0, "shift": 0.0}
    largest = 0.0
    for t, sample_q, sample_v in zip(trajectory.t, trajectory.q, trajectory.v, strict=True):
        q, v = on_grasp(grasp, sample_q, sample_v)
        shift = max(np.abs(pin.difference(grasp.model, sample_q, q)).max(), np.abs(v - sample_v).max())
        evaluation = system.dynamics(q, v, t)
        tau = model.dynamics_terms(q, v, t).tau
        rotations = [model.kin.placement(frame).rotation for frame in frames]
        pinstab_forces = np.concatenate(
            [r @ f for r, f in zip(rotations, evaluation.multipliers.reshape(-1, 3), strict=True)]
        )
        object_space = lagrange_dalembert(grasp, q, v, tau)
        assert np.linalg.cond(object_space.hand_jacobian) < 100.0
        reference = evaluation.acceleration[grasp.cube]
        largest = max(largest, float(np.abs(reference).max()))
        worst["shift"] = max(worst["shift"], float(shift))
        worst["pinstab"] = max(worst["pinstab"], float(np.abs(object_space.acceleration - reference).max()))
        worst["numpy"] = max(
            worst["numpy"], float(np.abs(numpy_kkt(grasp, q, v, tau) - object_space.acceleration).max())
        )
        worst["force"] = max(worst["force"], float(np.abs(object_space.forces - pinstab_forces).max()))
    assert largest > 1.0  # [m/s^2 or rad/s^2]: the comparison is not of zeros
    assert worst["shift"] < 1e-9, worst  # [rad, m, rad/s, m/s]
    assert worst["pinstab"] < ACCELERATION_TOLERANCE, worst
    assert worst["numpy"] < ACCELERATION_TOLERANCE, worst
    assert worst["force"] < FORCE_TOLERANCE, worst

"""Rolling fingertip contacts: the rows against finite differences and against the material points' relative
velocity for each object surface (sphere, box face, cylinder side and cap); the contact-point path of a fingertip
rolling on a fixed sphere against Montana's contact-kinematics ODE [MLS ch. 5] integrated on its own; no slip
and no spin over a run; a rolling contact point moves where a sticking one stays; the multipliers as the force
on the object; grasp loss and bad input named."""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import coal
import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from conftest import ROBOTS
from pinstab import SceneError, load_scene, simulate
from pinstab.cli import main
from pinstab.constraints.rolling_contacts import surface_of
from pinstab.errors import GraspLostError
from pinstab.kernels import contact_point_jacobian, contact_point_residual
from pinstab.kinematics import Kinematics
from pinstab.scene import Scene, scene_from_dict
from pinstab.system import build_system
from pinstab.trajectory import Trajectory

URDF = ROBOTS / "urdf" / "rolling-finger.urdf"
FINGER_Q = {"knuckle_yaw": 0.0, "knuckle_pitch": 0.6, "middle": 0.9, "wrist_x": 0.0, "wrist_y": 0.0, "wrist_z": 0.0}
TIP_RADIUS = 0.01  # [m], the URDF's fingertip sphere
BALL_RADIUS = 0.03  # [m]
GAP = 5e-4  # [m] left between fingertip and object by initial.q (the loader closes it)
SCALE = 0.01  # [rad, m]: the random step from the start of the row tests
RPY = [0.3, -0.2, 0.5]  # the object's frame is not the world's
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@cache
def tip_start() -> np.ndarray:
    """The fingertip sphere's centre at FINGER_Q [m] (world)."""
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.array(list(FINGER_Q.values())))
    return data.oMf[model.getFrameId("tip")].translation.copy()


def facing(axis: int, reach: float, direction: np.ndarray) -> list[float]:
    """An object position [m] such that its frame's ``axis`` (turned by RPY) points from the fingertip along
    ``direction`` x sign and the feature ``reach`` [m] from its centre is GAP beyond touching the fingertip."""
    along = pin.rpy.rpyToMatrix(np.array(RPY))[:, axis]
    along = along * np.sign(along @ direction)
    return [float(x) for x in tip_start() + (TIP_RADIUS + GAP + reach) * along]


DOWN = np.array([0.0, 0.0, -1.0])
SHAPES = {  # object table and the position that makes the fingertip face the named feature
    "sphere": ({"shape": "sphere", "radius": BALL_RADIUS}, (0, BALL_RADIUS)),
    "box-face": ({"shape": "box", "size": [0.05, 0.04, 0.06]}, (0, 0.025)),
    "cylinder-side": ({"shape": "cylinder", "radius": 0.02, "length": 0.08}, (0, 0.02)),
    "cylinder-cap": ({"shape": "cylinder", "radius": 0.02, "length": 0.08}, (2, 0.04)),
}


def contact_entry(model: str = "point-friction", **changes: Any) -> dict:
    """A rolling-contact table ``tip`` of ``model`` (mu = 1, torsion 10 mm where the model takes them)."""
    entry = {"name": "tip", "kind": "rolling-contact", "finger": "tip", "object": "ball", "model": model}
    entry |= {"radius": TIP_RADIUS, "mu": 1.0} if model != "frictionless" else {"radius": TIP_RADIUS}
    if model == "soft-finger":
        entry["torsion"] = 0.01
    return entry | changes


def free_object(shape: str, model: str = "point-friction") -> dict:
    """Scene-file content: the 6-DOF finger touching a free object of ``shape`` (a SHAPES key) named ``ball``."""
    table, (axis, reach) = SHAPES[shape]
    item = {"name": "ball", "mass": 0.05, "rpy": RPY, "position": facing(axis, reach, DOWN), **table}
    return {
        "robot": {"urdf": str(URDF)},
        "objects": [item],
        "contacts": [contact_entry(model)],
        "initial": {"q": dict(FINGER_Q)},
    }


def fixed_ball(model: str = "point-friction", contact: dict | None = None, press: dict | None = None) -> dict:
    """Scene-file content: the 6-DOF finger on a 30 mm ball welded to the world, no gravity; a spring (50 N/m, rest
    length 0) pulls the fingertip's centre to the ball's (a purely normal press of 2 N) and a constant torque of
    1 mN m on the knuckle's yaw joint drives the fingertip around on the ball."""
    ball = facing(0, BALL_RADIUS, DOWN)
    spring = {"name": "press", "kind": "spring-damper", "frame_a": "tip", "offset_b": ball, "stiffness": 50.0}
    return {
        "robot": {"urdf": str(URDF)},
        "gravity": [0.0, 0.0, 0.0],
        "objects": [
            {"name": "ball", "shape": "sphere", "radius": BALL_RADIUS, "mass": 0.05, "rpy": RPY, "position": ball}
        ],
        "closures": [{"name": "hold", "kind": "weld", "frame_a": "ball", "offset_b": ball, "rpy_b": RPY}],
        "contacts": [contact or contact_entry(model)],
        "forces": [
            spring | (press or {}),
            {"name": "yaw", "kind": "joint-torque", "joint": "knuckle_yaw", "torque": 0.001},
        ],
        "initial": {"q": dict(FINGER_Q)},
    }


def block(scene: Scene, name: str):
    return next(c for c in scene.constraints if c.name == name)


# -- an independent description of the contact ---------------------------------------------------------------
def outward_normal(shape: str, body: pin.SE3, centre: np.ndarray) -> np.ndarray:
    """The object's outward unit normal (world) at the point nearest to the fingertip centre ``centre``, from
    the shape's definition: the line of centres, the radial direction of the cylinder, or the axis (SHAPES) of the
    box face or cylinder cap that faces the fingertip."""
    if shape == "sphere":
        offset = centre - body.translation
        return offset / np.linalg.norm(offset)
    axis, _ = SHAPES[shape][1]
    if shape == "cylinder-side":
        offset = centre - body.translation
        radial = offset - (offset @ body.rotation[:, 2]) * body.rotation[:, 2]
        return radial / np.linalg.norm(radial)
    outward = body.rotation[:, axis]
    return outward * np.sign(outward @ (centre - body.translation))


def point_velocity(kin: Kinematics, frame: int, point: np.ndarray) -> np.ndarray:
    """Velocity [m/s] of the material point of ``frame``'s body at ``point`` (world)."""
    motion = kin.velocity(frame)
    return motion.linear + np.cross(motion.angular, point - kin.placement(frame).translation)


def perturbed(scene: Scene) -> tuple[Kinematics, np.ndarray, np.ndarray]:
    """Kinematics at a random configuration near the start (finger and object moved: phi != 0) and a random
    velocity."""
    rng = np.random.default_rng(7)
    q = pin.integrate(scene.model, scene.q0, SCALE * rng.standard_normal(scene.model.nv))
    v = rng.standard_normal(scene.model.nv)
    kin = Kinematics(scene.model)
    kin.update(q, v)
    return kin, q, v


# -- rows and drift ------------------------------------------------------------------------------------------
STEP = 1e-7  # [rad, m]: central differences of phi
RATE_STEP = 1e-6  # [s]: central differences of G v along q (+) s v
JACOBIAN_TOLERANCE = 1e-6  # relative to max |G|
DRIFT_TOLERANCE = 1e-6  # relative to max |gamma0|


def rows_times(scene: Scene, constraint, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    kin = Kinematics(scene.model)
    kin.update_jacobians(q)
    return constraint.velocity_terms(kin, q, 0.0).jacobian @ v


@pytest.mark.parametrize("shape", SHAPES)
def test_touching_row_is_the_derivative_of_the_gap(shape):
    """The touching row G = d phi / dq (through pin.integrate, column by column) within 1e-6 of max |G| at a
    configuration 0.5-5 mm off the surface (or into it), and phi is the distance from the fingertip sphere to the
    surface, measured with coal, within 1e-12 m."""
    scene = scene_from_dict(free_object(shape))
    touch = block(scene, "tip")
    kin, q, _ = perturbed(scene)
    rows = touch.velocity_terms(kin, q, 0.0).jacobian
    item = scene.objects[0]
    placed = kin.placement(item.frame) * item.geometries[0][1]
    gap = coal.distance(
        coal.Sphere(TIP_RADIUS),
        coal.Transform3s(np.eye(3), kin.placement(scene.frame_id("tip")).translation),
        item.geometries[0][0],
        coal.Transform3s(placed.rotation, placed.translation),
        coal.DistanceRequest(),
        coal.DistanceResult(),
    )
    phi = touch.residual(kin, q, 0.0)
    columns = []
    for k in range(scene.model.nv):
        step = np.zeros(scene.model.nv)
        step[k] = STEP
        values = []
        for sign in (1.0, -1.0):
            kin.update_positions(pin.integrate(scene.model, q, sign * step))
            values.append(touch.residual(kin, q, 0.0))
        columns.append((values[0] - values[1]) / (2 * STEP))
    assert 5e-4 < abs(phi[0]) < 1e-2 and abs(phi[0] - gap) < 1e-12
    assert np.abs(np.column_stack(columns) - rows).max() < JACOBIAN_TOLERANCE * np.abs(rows).max()


@pytest.mark.parametrize("model", ["point-friction", "soft-finger"])
@pytest.mark.parametrize("shape", SHAPES)
def test_drift_is_the_rate_of_the_rows(shape, model):
    """For both blocks, gamma0 = d/dt (G v) along q(s) = q (+) s v with v held, within 1e-6 of max |gamma0|, away
    from the constraint (phi != 0, random v: the fingertip slides); the turning contact frame's term
    dR_C^T/dt Delta alone is more than 100 times that tolerance."""
    scene = scene_from_dict(free_object(shape, model))
    kin, q, v = perturbed(scene)
    for constraint in scene.constraints:
        drift = constraint.drift(kin, q, v, 0.0)
        forward = rows_times(scene, constraint, pin.integrate(scene.model, q, RATE_STEP * v), v)
        backward = rows_times(scene, constraint, pin.integrate(scene.model, q, -RATE_STEP * v), v)
        tolerance = DRIFT_TOLERANCE * np.abs(drift).max()
        assert np.abs(drift).max() > 1.0
        assert np.abs((forward - backward) / (2 * RATE_STEP) - drift).max() < tolerance, constraint.name
    rolling = block(scene, "tip/rolling")
    geometry = rolling.geometry
    state = geometry.state(kin)
    centre, _, relative, _ = geometry.rates(kin, state)
    slip = -centre - TIP_RADIUS * np.cross(state.axes[:, 2], relative)
    turning = geometry.axes_rate(kin, state, centre)[:, :2].T @ slip
    assert np.abs(turning).max() > 100 * DRIFT_TOLERANCE * np.abs(rolling.drift(kin, q, v, 0.0)).max()


@pytest.mark.parametrize("shape", SHAPES)
def test_rows_are_the_relative_velocity_at_the_contact_point(shape):
    """Against the shape's own geometry (outward_normal, p = c - r n): the touching row is n . (v_f(p) - v_o(p)),
    the no-slip rows' norm is the tangential part of v_o(p) - v_f(p), the spin row n . (omega_f - omega_o),
    the contact frame's z is -n and the contact point in the object and finger frames is p, to 1e-12."""
    scene = scene_from_dict(free_object(shape, "soft-finger"))
    kin, q, v = perturbed(scene)
    touch, rolling = block(scene, "tip"), block(scene, "tip/rolling")
    body, tip = kin.placement(scene.objects[0].frame), kin.placement(scene.frame_id("tip"))
    normal = outward_normal(shape, body, tip.translation)
    point = tip.translation - TIP_RADIUS * normal
    relative = point_velocity(kin, scene.objects[0].frame, point) - point_velocity(kin, scene.frame_id("tip"), point)
    spin = normal @ (kin.velocity(scene.frame_id("tip")).angular - kin.velocity(scene.objects[0].frame).angular)
    touching = touch.velocity_terms(kin, q, 0.0).jacobian @ v
    rows = rolling.velocity_terms(kin, q, 0.0).jacobian @ v
    on_object, on_finger = rolling.geometry.contact_points(kin)
    assert abs(touching[0] + normal @ relative) < 1e-12
    assert abs(np.linalg.norm(rows[:2]) - np.linalg.norm(relative - (relative @ normal) * normal)) < 1e-12
    assert abs(rows[2] - spin) < 1e-12 and abs(spin) > 0.01
    assert np.abs(rolling.geometry.state(kin).axes[:, 2] + normal).max() < 1e-12
    assert np.abs(on_object - body.actInv(point)).max() < 1e-12 and np.abs(on_finger - tip.actInv(point)).max() < 1e-12


def test_the_centre_rows_are_the_fingertip_point_rows():
    """The rolling contact's J_w and w are minus the fingertip point rows in world axes (cpp/contact_terms.cpp):
    R_o times the central difference of R_o^T (p_o - p_f) along q (+) s v, within 1e-6 of |w|, is -w = -J_w v; J_w v
    and w agree to 1e-12 (relative); R_o^T of the world rows is the point rows' Jacobian to 1e-12."""
    scene = scene_from_dict(free_object("sphere"))
    kin, q, v = perturbed(scene)
    geometry = block(scene, "tip").geometry
    state = geometry.state(kin)
    jacobian, _ = geometry.jacobians(kin, state)
    centre = geometry.rates(kin, state)[0]
    rotation = kin.placement(geometry.object_frame).rotation
    frames = (geometry.object_frame, geometry.finger_frame)

    def residual(step: float) -> np.ndarray:
        moved = Kinematics(scene.model)
        moved.update_positions(pin.integrate(scene.model, q, step * v))
        return contact_point_residual(scene.model, moved.data, *frames)

    difference = rotation @ (residual(RATE_STEP) - residual(-RATE_STEP)) / (2 * RATE_STEP)
    assert np.abs(difference + centre).max() < 1e-6 * np.linalg.norm(centre) and np.linalg.norm(centre) > 0.01
    np.testing.assert_allclose(jacobian @ v, centre, rtol=0, atol=1e-12 * np.linalg.norm(centre))
    point_rows = contact_point_jacobian(scene.model, kin.data, *frames)
    np.testing.assert_allclose(-rotation.T @ jacobian, point_rows, rtol=0, atol=1e-12 * np.abs(point_rows).max())


# -- Montana's contact kinematics [MLS ch. 5] --------------------------------------------------------------------
class SphereChart:
    """The orthogonal, right-handed chart of a sphere of ``radius`` [m] used in [MLS ch. 5] (latitude u, longitude v):
    c(u, v) = radius (cos u cos v, -cos u sin v, sin u) in the axes ``reference`` (3 x 3, body frame), metric
    M = diag(radius, radius cos u), curvature K = E / radius, torsion T = (0, -tan u / radius)."""

    def __init__(self, radius: float, reference: np.ndarray) -> None:
        self.radius, self.reference = radius, reference

    @classmethod
    def centred_on(cls, radius: float, normal: np.ndarray) -> SphereChart:
        """The chart whose origin (u, v) = (0, 0) is the point of outward ``normal`` (body frame)."""
        _, _, rows = np.linalg.svd(normal.reshape(1, 3))
        reference = np.column_stack([normal, rows[1], rows[2]])
        reference[:, 2] *= np.sign(np.linalg.det(reference))
        return cls(radius, reference)

    def gauss_frame(self, u: float, v: float) -> np.ndarray:
        """Columns x = c_u / |c_u|, y = c_v / |c_v|, z = x cross y (outward), body frame."""
        x = [-math.sin(u) * math.cos(v), math.sin(u) * math.sin(v), math.cos(u)]
        y = [-math.sin(v), -math.cos(v), 0.0]
        z = [math.cos(u) * math.cos(v), -math.cos(u) * math.sin(v), math.sin(u)]
        return self.reference @ np.column_stack([x, y, z])

    def coordinates(self, normal: np.ndarray) -> np.ndarray:
        """(u, v) of the point of outward unit ``normal`` (body frame)."""
        m = self.reference.T @ normal
        return np.array([math.asin(m[2]), math.atan2(-m[1], m[0])])

    def metric(self, u: float) -> np.ndarray:
        return np.diag([self.radius, self.radius * math.cos(u)])

    def curvature(self) -> np.ndarray:
        return np.eye(2) / self.radius

    def torsion(self, u: float) -> np.ndarray:
        return np.array([0.0, -math.tan(u) / self.radius])


def montana_rates(finger: SphereChart, target: SphereChart, eta: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """d eta / dt for eta = (alpha_f, alpha_o, psi) (Montana's equations [MLS ch. 5]) given the finger frame's body
    twist relative to the object, (v, omega) in finger axes at its origin (the sphere's centre) [m/s, rad/s]: the
    twist is moved to the finger's contact frame C_f (the Gauss frame at alpha_f) and

        alpha_f' = M_f^-1 (K_f + K~_o)^-1 ((-w_y, w_x) - K~_o (v_x, v_y))
        alpha_o' = M_o^-1 R_psi (K_f + K~_o)^-1 ((-w_y, w_x) + K_f (v_x, v_y))
        psi'     = w_z + T_f M_f alpha_f' + T_o M_o alpha_o'

    with R_psi = [[cos psi, -sin psi], [-sin psi, -cos psi]] and K~_o = R_psi K_o R_psi."""
    (uf, vf), (uo, _), psi = eta[:2], eta[2:4], eta[4]
    axes = finger.gauss_frame(uf, vf)
    omega = axes.T @ twist[3:]
    velocity = axes.T @ (twist[:3] + np.cross(twist[3:], finger.radius * axes[:, 2]))
    turn = np.array([[math.cos(psi), -math.sin(psi)], [-math.sin(psi), -math.cos(psi)]])
    k_f, k_o = finger.curvature(), turn @ target.curvature() @ turn
    inverse = np.linalg.inv(k_f + k_o)
    rolling = np.array([-omega[1], omega[0]])
    m_f, m_o = finger.metric(uf), target.metric(uo)
    rate_f = np.linalg.solve(m_f, inverse @ (rolling - k_o @ velocity[:2]))
    rate_o = np.linalg.solve(m_o, turn @ inverse @ (rolling + k_f @ velocity[:2]))
    rate_psi = omega[2] + finger.torsion(uf) @ m_f @ rate_f + target.torsion(uo) @ m_o @ rate_o
    return np.concatenate([rate_f, rate_o, [rate_psi]])


class ContactRecord:
    """From a trajectory of the fixed-ball scene, per sample: the relative twist of the fingertip frame F with
    respect to the ball frame O (F axes, at F's origin) and the contact coordinates (alpha_f, alpha_o, psi) read
    from the configuration: the contact point is on the line of centres; each sphere's chart is centred on the
    start's contact point; psi is the angle from the object's Gauss x axis to the finger's (MLS: x_f = cos psi x_o
    - sin psi y_o)."""

    def __init__(self, scene: Scene, trajectory: Trajectory) -> None:
        self.model, self.data = scene.model, scene.model.createData()
        self.finger, self.target = scene.frame_id("tip"), scene.objects[0].frame
        self.t = trajectory.t
        first, body, _ = self._frames(trajectory.q[0], trajectory.v[0])
        normal = self._normal(first, body)
        self.finger_chart = SphereChart.centred_on(TIP_RADIUS, first.rotation.T @ -normal)
        self.target_chart = SphereChart.centred_on(BALL_RADIUS, body.rotation.T @ normal)
        rows = [self._sample(q, v) for q, v in zip(trajectory.q, trajectory.v, strict=True)]
        self.twist = np.array([row[0] for row in rows])
        self.coordinates = np.array([row[1] for row in rows])

    def _frames(self, q: np.ndarray, v: np.ndarray) -> tuple[pin.SE3, pin.SE3, np.ndarray]:
        pin.forwardKinematics(self.model, self.data, q, v)
        pin.updateFramePlacements(self.model, self.data)
        tip, body = self.data.oMf[self.finger].copy(), self.data.oMf[self.target].copy()
        motion_f = pin.getFrameVelocity(self.model, self.data, self.finger, LWA)
        motion_o = pin.getFrameVelocity(self.model, self.data, self.target, LWA)
        omega = motion_f.angular - motion_o.angular
        linear = motion_f.linear - motion_o.linear - np.cross(motion_o.angular, tip.translation - body.translation)
        return tip, body, np.concatenate([tip.rotation.T @ linear, tip.rotation.T @ omega])

    @staticmethod
    def _normal(tip: pin.SE3, body: pin.SE3) -> np.ndarray:
        offset = tip.translation - body.translation
        return offset / np.linalg.norm(offset)

    def _sample(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tip, body, twist = self._frames(q, v)
        normal = self._normal(tip, body)
        alpha_f = self.finger_chart.coordinates(tip.rotation.T @ -normal)
        alpha_o = self.target_chart.coordinates(body.rotation.T @ normal)
        x_f = tip.rotation @ self.finger_chart.gauss_frame(*alpha_f)[:, 0]
        frame_o = body.rotation @ self.target_chart.gauss_frame(*alpha_o)
        psi = math.atan2(-frame_o[:, 1] @ x_f, frame_o[:, 0] @ x_f)
        return twist, np.concatenate([alpha_f, alpha_o, [psi]])

    def integrate(self) -> np.ndarray:
        """Montana's ODE from the first sample's coordinates, driven by the recorded twist (cubic spline through
        every sample), DOP853 at rtol 1e-12, atol 1e-14; eta at the sample times."""
        spline = CubicSpline(self.t, self.twist)
        solution = solve_ivp(
            lambda t, eta: montana_rates(self.finger_chart, self.target_chart, eta, spline(t)),
            (self.t[0], self.t[-1]),
            self.coordinates[0],
            method="DOP853",
            rtol=1e-12,
            atol=1e-14,
            t_eval=self.t,
        )
        assert solution.success
        return solution.y.T


def wrapped(angles: np.ndarray) -> np.ndarray:
    return (angles + math.pi) % (2 * math.pi) - math.pi


@cache
def rolling_run(model: str) -> tuple[Scene, Trajectory]:
    """1 s of the fixed-ball scene (Mukharlyamov with its dead-beat gains, RK4, 1 ms, dense KKT solve), every step
    kept; the URDF's +/-3.14 rad joint bounds are placeholders, not limits (the wrist passes one)."""
    scene = scene_from_dict(fixed_ball(model))
    return scene, simulate(scene, "mukharlyamov", "rk4", dt=1e-3, duration=1.0, solver="dense", limits=False)


@pytest.mark.parametrize("model", ["point-friction", "soft-finger"])
def test_contact_path_follows_montanas_equations(model):
    """Acceptance: the fingertip (10 mm) rolls on the fixed ball (30 mm) for 1 s, driven by the knuckle's torque;
    fed the simulated relative twist (recorded every 1 ms, cubic spline), Montana's ODE integrated with SciPy
    gives the contact coordinates (u_f, v_f, u_o, v_o, psi) read from the simulated configurations within 1e-8
    rad at every sample, while they travel over 0.5 rad (the fingertip's point over 3 rad) and stay 0.3 rad away
    from the charts' poles."""
    scene, trajectory = rolling_run(model)
    record = ContactRecord(scene, trajectory)
    error = wrapped(record.integrate() - record.coordinates)
    travel = np.abs(wrapped(record.coordinates - record.coordinates[0])).max(axis=0)
    assert np.abs(record.coordinates[:, [0, 2]]).max() < math.pi / 2 - 0.3
    assert travel[2:4].max() > 0.5 and travel[:2].max() > 3.0
    assert np.abs(error).max() < 1e-8


def slip_and_spin(
    scene: Scene, trajectory: Trajectory, tip: str = "tip", radius: float = TIP_RADIUS
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: the tangential velocity of the ball's material point at the contact point (line of centres)
    relative to the fingertip's (sphere of ``radius`` [m] about frame ``tip``) [m/s], the relative angular
    velocity about the normal [rad/s] and the speed of the fingertip's centre [m/s]."""
    kin = Kinematics(scene.model)
    finger, target = scene.frame_id(tip), scene.objects[0].frame
    slip, spin, speed = [], [], []
    for q, v in zip(trajectory.q, trajectory.v, strict=True):
        kin.update(q, v)
        centre, body = kin.placement(finger).translation, kin.placement(target).translation
        normal = (centre - body) / np.linalg.norm(centre - body)
        point = centre - radius * normal
        relative = point_velocity(kin, target, point) - point_velocity(kin, finger, point)
        slip.append(np.linalg.norm(relative - (relative @ normal) * normal))
        spin.append(normal @ (kin.velocity(finger).angular - kin.velocity(target).angular))
        speed.append(np.linalg.norm(kin.velocity(finger).linear))
    return np.array(slip), np.array(spin), np.array(speed)


def test_no_slip_and_spin_per_model():
    """Over the 1 s runs the material points at the contact point move together: tangential relative velocity
    <= 1e-10 m/s at every sample (the fingertip centre moves at up to 0.05 m/s); a soft finger also does not spin
    (<= 1e-10 rad/s) while a point contact with friction does (over 1 rad/s)."""
    for model in ("point-friction", "soft-finger"):
        scene, trajectory = rolling_run(model)
        slip, spin, speed = slip_and_spin(scene, trajectory)
        assert slip.max() <= 1e-10 and speed.max() > 0.04, model
        if model == "soft-finger":
            assert np.abs(spin).max() <= 1e-10
        else:
            assert np.abs(spin).max() > 1.0


def test_the_bundled_scene_rolls_the_ball():
    """robots/finger-rolling.toml, 1 s (Baumgarte, RK4, 1 ms, dense KKT solve): finger_edu's fingertip rolls on the
    pinned ball without slipping or spinning (<= 1e-10 m/s, rad/s), the ball turns by over 20 degrees about its
    pin, the contact point travels over 3 mm on it and the normal force stays over 1.5 N."""
    scene = load_scene("finger-rolling")
    trajectory = simulate(scene, "baumgarte", "rk4", dt=1e-3, duration=1.0, solver="dense")
    slip, spin, _ = slip_and_spin(scene, trajectory, "finger_tip_link", 0.0095)
    data = scene.model.createData()
    turned, travel = [], []
    for q in trajectory.q:
        pin.framesForwardKinematics(scene.model, data, q)
        body, centre = data.oMf[scene.objects[0].frame], data.oMf[scene.frame_id("finger_tip_link")].translation
        turned.append(np.linalg.norm(pin.log3(body.rotation)))
        travel.append(body.actInv(centre) / np.linalg.norm(centre - body.translation))
    assert slip.max() <= 1e-10 and np.abs(spin).max() <= 1e-10
    assert max(turned) > math.radians(20) and turned[0] < 1e-12
    assert 0.03 * np.linalg.norm(np.array(travel) - travel[0], axis=1).max() > 3e-3
    assert trajectory.multipliers_of("tip").min() > 1.5


def material_point_track(scene: Scene, trajectory: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Per sample [m]: how far the fingertip's material point that touched at the start is from the ball's
    material point that touched at the start, and how far the current contact point (line of centres) is from
    the latter (both in the ball's frame)."""
    data = scene.model.createData()
    finger, target = scene.frame_id("tip"), scene.objects[0].frame
    apart, moved = [], []
    for k, q in enumerate(trajectory.q):
        pin.framesForwardKinematics(scene.model, data, q)
        tip, body = data.oMf[finger], data.oMf[target]
        normal = (tip.translation - body.translation) / np.linalg.norm(tip.translation - body.translation)
        point = body.actInv(tip.translation - TIP_RADIUS * normal)
        if k == 0:
            start_object, start_finger = point, tip.actInv(tip.translation - TIP_RADIUS * normal)
        apart.append(np.linalg.norm(body.actInv(tip.act(start_finger)) - start_object))
        moved.append(np.linalg.norm(point - start_object))
    return np.array(apart), np.array(moved)


def test_a_rolling_contact_point_moves_where_a_sticking_one_stays():
    """The same drive for 0.1 s (a point-friction grasp-contact with mu = 5 would slide at 0.13 s): with a sticking
    contact the fingertip's start point stays on the ball's (<= 1e-10 m); with a rolling contact the contact point
    moves over 0.3 mm on the ball and the fingertip's start point leaves the ball's by over 10 um (it rolls off)."""
    sticking = contact_entry("point-friction", kind="grasp-contact", mu=5.0)
    runs = {}
    for label, contact in (("sticking", sticking), ("rolling", None)):
        scene = scene_from_dict(fixed_ball(contact=contact))
        trajectory = simulate(scene, "baumgarte", "rk4", dt=1e-3, duration=0.1, solver="dense")
        runs[label] = material_point_track(scene, trajectory)
    assert runs["sticking"][0].max() <= 1e-10
    assert runs["rolling"][1].max() > 3e-4 and runs["rolling"][0].max() > 1e-5


def test_multipliers_are_the_force_on_the_object():
    """At the start of the fixed-ball scene the contact's multipliers (f_x, f_y from the rolling block, f_n from the
    touching block), turned from C to world axes, are the opposite of the weld's force on the ball (nothing else
    acts on it) to 1e-9 N; the normal force is about the spring's 2 N press (within 0.01 N: the knuckle's torque
    adds its share)."""
    scene = scene_from_dict(fixed_ball("point-friction"))
    system = build_system(scene, "baumgarte", "dense")
    slices = system.model.constraints.slices
    evaluation = system.dynamics(scene.q0, scene.v0, 0.0)
    kin = system.model.kin
    kin.update(scene.q0, scene.v0)
    force = np.concatenate([evaluation.multipliers[slices["tip/rolling"]], evaluation.multipliers[slices["tip"]]])
    world = block(scene, "tip").geometry.state(kin).axes @ force
    weld = evaluation.multipliers[slices["hold"]][:3]
    assert np.abs(world + weld).max() < 1e-9
    assert abs(force[2] - 50.0 * (TIP_RADIUS + BALL_RADIUS)) < 0.01


def test_a_contact_that_would_have_to_pull_is_lost():
    """A spring that pushes the fingertip away (rest length 0.1 m > 0.04 m): GraspLostError at t = 0 naming the
    contact, the violated margin the (negative) normal force."""
    scene = scene_from_dict(fixed_ball(press={"rest_length": 0.1}))
    with pytest.raises(GraspLostError, match=r"contact 'tip' \(tip on ball\) would have to pull") as caught:
        simulate(scene, "baumgarte", "rk4", dt=1e-3, duration=0.01)
    assert caught.value.contacts == ["tip"] and caught.value.time == 0.0 and caught.value.margin < -1.0


# -- bad input -------------------------------------------------------------------------------------------------
BAD_ROLLING = [
    (
        {"model": "rigid"},
        r"contact 'tip': a rolling contact's model is one of frictionless, point-friction, soft-finger, got 'rigid' "
        r"\(a rigid contact cannot roll\)",
    ),
    ({"torsion": 0.01}, r"contact 'tip': a 'point-friction' contact takes no 'torsion'"),
    ({"model": "soft-finger"}, r"contact 'tip': a 'soft-finger' contact needs 'torsion' \(>= 0\)"),
    ({"model": "frictionless"}, r"contact 'tip': a 'frictionless' contact takes no 'mu'"),
    ({"spin": True}, r"contact 'tip': unknown key 'spin'; valid keys: finger, kind, model, mu, name, object, radius"),
    ({"object": "distal_link"}, r"contact 'tip'\.object: 'distal_link' is not an object of the scene"),
]


@pytest.mark.parametrize(("changes", "pattern"), BAD_ROLLING)
def test_bad_rolling_contact_is_named(changes, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(fixed_ball(contact=contact_entry() | changes))


EDGES = [
    ({"shape": "box", "size": [0.05, 0.04, 0.06]}, [1, 1, 0], r"touches the box at an edge or a corner"),
    ({"shape": "cylinder", "radius": 0.02, "length": 0.08}, [1, 0, 1], r"touches the cylinder's rim"),
]


@pytest.mark.parametrize(("table", "corner", "pattern"), EDGES)
def test_an_edge_is_refused(table, corner, pattern):
    """A fingertip facing a box edge or a cylinder rim (the object turned by RPY, its feature at ``corner``):
    SceneError naming the contact."""
    rotation = pin.rpy.rpyToMatrix(np.array(RPY))
    size = np.array(table.get("size", [0.04, 0.04, 0.08])) / 2
    feature = rotation @ (np.array(corner) * size)
    position = tip_start() - feature - (TIP_RADIUS + GAP) * feature / np.linalg.norm(feature)
    data = fixed_ball()
    data["objects"][0] = {"name": "ball", "mass": 0.05, "rpy": RPY, "position": list(position), **table}
    data["closures"] = []
    with pytest.raises(SceneError, match=r"contact 'tip': the fingertip " + pattern):
        scene_from_dict(data)


def test_an_unsupported_shape_is_refused():
    """A capsule (a shape a URDF object may bring): SceneError naming the item and the shapes that roll."""
    with pytest.raises(SceneError, match=r"contact 'tip': the fingertip touches a Capsule; a rolling contact rolls on"):
        surface_of(coal.Capsule(0.02, 0.1), pin.SE3.Identity(), np.array([0.05, 0.0, 0.0]), "contact 'tip'")


def test_cli_names_a_bad_rolling_contact(capsys, tmp_path):
    """``pinstab run`` on the bundled scene with its contact made rigid: exit 2, the item named, no traceback."""
    text = (ROBOTS / "finger-rolling.toml").read_text()
    path = tmp_path / "finger-rolling.toml"
    path.write_text(text.replace('model = "soft-finger"', 'model = "rigid"').replace("urdf/", f"{ROBOTS}/urdf/"))
    code = main(["run", str(path), "--quiet"])
    _, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in err
    assert "contact 'tip': a rolling contact's model is one of frictionless, point-friction, soft-finger" in err


def test_a_rolling_contact_that_would_slide_is_named():
    """The no-slip block checks its tangential force against mu times the touching block's normal force:
    forces (f_n, f_x, f_y) = (1, 0.9, 0) N with mu = 0.8 would slide (margin 0.8 - 0.9 N); (1, 0.5, 0.5) holds;
    the set hands the block the touching block's multiplier first."""
    scene = load_scene("finger-rolling")
    touch, rolling = (c for c in scene.constraints if c.kind == "rolling-contact")
    assert rolling.force_partners == (touch.name,)
    mu = rolling.limits.mu
    wrench = [1.0, mu + 0.1, 0.0] + [0.0] * (rolling.rows - 2)
    with pytest.raises(GraspLostError, match=rf"contact '{touch.name}' .* would slide") as info:
        rolling.check_force(np.array(wrench), 0.5)
    assert info.value.margin == pytest.approx(-0.1, abs=1e-12)
    rolling.check_force(np.array([1.0, 0.5 * mu, 0.5 * mu] + [0.0] * (rolling.rows - 2)), 0.5)
    constraint_set = scene.constraint_set
    rows = dict((c.name, r) for c, r in constraint_set.force_limited)[rolling.name]
    slices = constraint_set.slices
    expected = [slices[touch.name].start, *range(slices[rolling.name].start, slices[rolling.name].stop)]
    assert list(rows) == expected

"""The rolling disk [MLS ex. 6.2]: the bundled scene against its closed form, the ``rolling-disk`` and
``disk-touch`` rows against finite differences, its recording, and bad input.

Closed form (MLS ex. 6.2, no forces): with ``A = [[1, 0, 0, -r cos(theta)], [0, 1, 0, -r sin(theta)]]``
on ``(x, y, theta, phi)`` the Lagrange-d'Alembert equations give ``I theta'' = 0`` and
``(J + m r^2) phi'' = 0``: both rates stay constant and the contact point runs on the circle of radius
``R = r phi' / theta'`` about ``(x0 - R sin(theta0), y0 + R cos(theta0))``. The multipliers are
``lambda = m (x'', y'')``: the force of the floor on the disk is the centripetal
``m V^2 / R = m r phi' theta'`` (V = r phi'), pointing from the contact point to the circle's centre,
``m r phi' theta' (-sin(theta), cos(theta), 0)``, and nothing along the heading.
"""

from __future__ import annotations

import base64
import math
import re

import numpy as np
import pinocchio as pin
import pytest
import umsgpack

import pinstab
from conftest import ROBOTS
from pinstab.assembly import assemble
from pinstab.constraints.contacts import contact_basis
from pinstab.constraints.rolling_disk import DiskPlaneContact
from pinstab.errors import ConstraintError, SceneError
from pinstab.kinematics import Kinematics
from pinstab.model import ConstrainedModel
from pinstab.scene import Scene, scene_from_dict
from pinstab.viz.recording import write_recording

# the bundled scene, as its files state it
RADIUS, MASS = 0.3, 2.0  # [m], [kg]
SPIN_INERTIA, DIAMETER_INERTIA = MASS * RADIUS**2 / 2, MASS * RADIUS**2 / 4  # thin disk [kg m^2]
HEADING_RATE, SPIN_RATE = 1.0, 5.0  # [rad/s]
CIRCLE = RADIUS * SPIN_RATE / HEADING_RATE  # [m] 1.5
GRAVITY = 9.81
DURATION, DT = 5.0, 1e-3
EPS = 1e-6  # finite-difference step (central differences: error ~ EPS^2)

DISK_URDF = """<?xml version="1.0"?>
<robot name="coin">
  <link name="coin">
    <inertial><mass value="2.0"/><inertia ixx="0.045" ixy="0" ixz="0" iyy="0.09" iyz="0" izz="0.045"/></inertial>
  </link>
</robot>"""


@pytest.fixture(scope="module")
def run():
    """The bundled scene for 5 s: RK4 + projection at dt = 1 ms."""
    return pinstab.simulate("rolling-disk", method="projection", integrator="rk4", dt=DT, duration=DURATION)


def _coin(tilt: float, contacts: list[dict], v: list[float] | None = None) -> Scene:
    """A free-flying 2 kg disk of radius 0.3 m (axis y), tilted by ``tilt`` [rad] about x, its lowest point
    on the floor; local-frame velocity ``v`` (6,) [m/s, rad/s]."""
    quaternion = pin.Quaternion(pin.exp3(np.array([tilt, 0.0, 0.0])))
    height = RADIUS * math.cos(tilt)
    return scene_from_dict(
        {
            "robot": {"urdf_text": DISK_URDF, "free_flyer": True},
            "contacts": contacts,
            "initial": {
                "q": {"root_joint": [0.0, 0.0, height, *quaternion.coeffs().tolist()]},
                "v": {"root_joint": v or [0.0] * 6},
            },
        },
        name="coin",
    )


def _disk(kind: str, **changes) -> dict:
    return {"name": f"coin-{kind}", "kind": kind, "frame": "coin", "axis": [0, 1, 0], "radius": RADIUS, **changes}


# -- the closed form ---------------------------------------------------------------------------------------
def _contact_points(run) -> np.ndarray:
    """The disk's lowest point at every sample (from the disk frame's placement; it stays upright) [m]."""
    scene = pinstab.load_scene("rolling-disk")
    kin = Kinematics(scene.model)
    frame = scene.frame_id("disk")
    points = []
    for q in run.q:
        kin.update_positions(q)
        points.append(kin.placement(frame).translation - [0.0, 0.0, RADIUS])
    return np.array(points)


def _fit_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares circle through 2-D points: x^2 + y^2 + D x + E y + F = 0 (centre, radius) [m]."""
    design = np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))])
    d, e, f = np.linalg.lstsq(design, -(points**2).sum(axis=1), rcond=None)[0]
    centre = np.array([-d / 2, -e / 2])
    return centre, math.sqrt(centre @ centre - f)


def test_scene_states_the_closed_form_start():
    """The bundled scene starts at the origin heading along +x with x' = r phi' (consistent rows)."""
    scene = pinstab.load_scene("rolling-disk")
    np.testing.assert_array_equal(scene.v0, [RADIUS * SPIN_RATE, 0.0, HEADING_RATE, SPIN_RATE])
    np.testing.assert_array_equal(scene.q0, np.zeros(4))
    mass = pin.crba(scene.model, scene.model.createData(), scene.q0)
    np.testing.assert_allclose(np.diag(mass), [MASS, MASS, DIAMETER_INERTIA, SPIN_INERTIA], rtol=1e-15)


def test_rates_stay_constant(run):
    """theta' and phi' keep their start values to 1e-9 rad/s; the height stays r (upright by joints)."""
    assert np.abs(run.v[:, 2] - HEADING_RATE).max() < 1e-9
    assert np.abs(run.v[:, 3] - SPIN_RATE).max() < 1e-9
    assert run.t[-1] == pytest.approx(DURATION, abs=1e-12) and len(run.t) == round(DURATION / DT) + 1


def test_contact_point_traces_the_closed_form_circle(run):
    """Over 5 s the fitted radius is r phi' / theta' = 1.5 m within 1e-6 relative, and every sample lies
    within 1e-6 R of the closed-form circle about (0, R); the points agree with the closed-form path
    (R sin(theta' t), R (1 - cos(theta' t))) within 1e-6 R too."""
    points = _contact_points(run)
    assert np.abs(points[:, 2]).max() < 1e-15
    centre, radius = _fit_circle(points[:, :2])
    assert abs(radius - CIRCLE) / CIRCLE < 1e-6
    assert np.abs(centre - [0.0, CIRCLE]).max() / CIRCLE < 1e-6
    distances = np.linalg.norm(points[:, :2] - [0.0, CIRCLE], axis=1)
    assert np.abs(distances - CIRCLE).max() / CIRCLE < 1e-6
    angle = HEADING_RATE * run.t
    path = CIRCLE * np.column_stack([np.sin(angle), 1.0 - np.cos(angle)])
    assert np.abs(points[:, :2] - path).max() / CIRCLE < 1e-6


def test_energy_is_conserved_and_equals_the_closed_form(run):
    """Energy varies by less than 1e-8 J over 5 s and equals m V^2/2 + I theta'^2/2 + J phi'^2/2 + m g r."""
    closed = (
        MASS * (RADIUS * SPIN_RATE) ** 2 / 2
        + DIAMETER_INERTIA * HEADING_RATE**2 / 2
        + SPIN_INERTIA * SPIN_RATE**2 / 2
        + MASS * GRAVITY * RADIUS
    )
    assert np.ptp(run.energy) < 1e-8
    assert abs(run.energy[0] - closed) < 1e-12


def test_no_slip_rows_hold(run):
    """The nonholonomic rows hold within 1e-10 m/s at every sample (velocity drift)."""
    assert np.max(run.velocity_drift) < 1e-10
    assert np.max(run.position_drift) == 0.0  # no holonomic rows


def test_multipliers_are_the_centripetal_force(run):
    """The floor's force on the disk, T^T lambda in world axes, is m r phi' theta' = 3 N towards the circle's
    centre, (-sin(theta), cos(theta), 0) 3 N, within 1e-6 N at every sample."""
    tangents = contact_basis([0.0, 0.0, 1.0])[1:]
    force = run.multipliers_of("floor") @ tangents
    heading = run.q[:, 2]
    expected = (
        MASS
        * RADIUS
        * SPIN_RATE
        * HEADING_RATE
        * np.column_stack([-np.sin(heading), np.cos(heading), np.zeros_like(heading)])
    )
    assert MASS * RADIUS * SPIN_RATE * HEADING_RATE == pytest.approx(MASS * (RADIUS * SPIN_RATE) ** 2 / CIRCLE)
    assert np.abs(force - expected).max() < 1e-6


def test_assembly_projects_the_start_velocity_in_the_kinetic_metric():
    """Given only theta' = 1 and phi' = 5, assembly keeps the least kinetic-metric change: x' = r phi',
    phi' = 5 J / (J + m r^2) = 5/3 rad/s (minimize m x'^2 + J (phi' - 5)^2 on x' = r phi')."""
    scene = pinstab.load_scene("rolling-disk")
    start = assemble(ConstrainedModel(scene), scene.q0, np.array([0.0, 0.0, HEADING_RATE, SPIN_RATE]))
    spin = SPIN_RATE * SPIN_INERTIA / (SPIN_INERTIA + MASS * RADIUS**2)
    np.testing.assert_allclose(start.v, [RADIUS * spin, 0.0, HEADING_RATE, spin], atol=1e-12)
    assert start.velocity_residual < 1e-14


# -- rows and drift against finite differences ---------------------------------------------------------------
def _states(scene: Scene, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` random states (q about the scene's start, v normal) of a scene, seeded."""
    rng = np.random.default_rng(11)
    return [
        (
            pin.integrate(scene.model, scene.q0, 0.3 * rng.standard_normal(scene.model.nv)),
            rng.standard_normal(scene.model.nv),
        )
        for _ in range(count)
    ]


def _tilted_plane_coin(kind: str) -> Scene:
    return _coin(0.4, [_disk(kind, normal=[0.2, -0.3, 1.0], point=[0.1, 0.2, -0.05], offset=[0.0, 0.01, 0.02])])


SCENES = {
    "MLS disk": lambda: pinstab.load_scene("rolling-disk"),
    "tilted coin, tilted plane": lambda: _tilted_plane_coin("rolling-disk"),
}


def _rows(scene: Scene) -> tuple[DiskPlaneContact, Kinematics]:
    (constraint,) = scene.constraints
    return constraint, Kinematics(scene.model)


def _material_point_velocity(scene, constraint, kin, q, v) -> np.ndarray:
    """d/de of the disk's material point at the contact at q, carried along q (+) e v (central) [m/s]."""
    kin.update_positions(q)
    _, towards, _ = constraint.contact_direction(kin)
    centre = kin.placement(constraint.frame)
    local = centre.actInv(centre.translation - constraint.radius * towards)
    moved = []
    for step in (EPS, -EPS):
        kin.update_positions(pin.integrate(scene.model, q, step * v))
        moved.append(kin.placement(constraint.frame).act(local))
    return (moved[0] - moved[1]) / (2 * EPS)


@pytest.mark.parametrize("name", SCENES)
def test_rows_are_the_material_contact_point_velocity(name):
    """G v = T d/dt(material point at the contact), central differences, within 1e-8 m/s at 5 states."""
    scene = SCENES[name]()
    constraint, kin = _rows(scene)
    for q, v in _states(scene, 5):
        kin.update_jacobians(q)
        jac, time_term = constraint.velocity_terms(kin, q, 0.0)
        expected = constraint.selection @ _material_point_velocity(scene, constraint, kin, q, v)
        assert np.abs(jac @ v - expected).max() < 1e-8
        assert not time_term.any()


def _drift_by_differences(scene, constraint, kin, q, v) -> np.ndarray:
    """d/de [G(q (+) e v) v] at e = 0 (zero joint acceleration), central differences [m/s^2]."""
    values = []
    for step in (EPS, -EPS):
        moved = pin.integrate(scene.model, q, step * v)
        kin.update_jacobians(moved)
        values.append(constraint.velocity_terms(kin, moved, 0.0).jacobian @ v)
    return (values[0] - values[1]) / (2 * EPS)


@pytest.mark.parametrize("name", SCENES)
def test_drift_matches_finite_differences(name):
    """gamma0 = dG/dt v at zero acceleration, within 1e-7 m/s^2 (relative to 1 + |gamma0|) at 5 states."""
    scene = SCENES[name]()
    constraint, kin = _rows(scene)
    for q, v in _states(scene, 5):
        kin.update(q, v)
        drift = constraint.drift(kin, q, v, 0.0)
        expected = _drift_by_differences(scene, constraint, kin, q, v)
        assert np.abs(drift - expected).max() < 1e-7 * (1 + np.abs(expected).max())


def test_touch_row_is_the_derivative_of_its_residual():
    """disk-touch: phi = n . (c - p0) - r sqrt(1 - (n . a)^2), its G = d phi/dq along pin.integrate (1e-8),
    and its drift = d/dt (G v) (1e-7 relative) at 5 states of a coin over a tilted plane."""
    scene = _tilted_plane_coin("disk-touch")
    constraint, kin = _rows(scene)
    assert constraint.holonomic and constraint.rows == 1
    normal = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    for q, v in _states(scene, 5):
        kin.update(q, v)
        centre = kin.placement(constraint.frame)
        axis = centre.rotation[:, 1]
        closed = normal @ (centre.translation - [0.1, 0.2, -0.05]) - RADIUS * math.sqrt(1 - (normal @ axis) ** 2)
        assert constraint.residual(kin, q, 0.0)[0] == pytest.approx(closed, abs=1e-15)
        drift = constraint.drift(kin, q, v, 0.0)
        kin.update_jacobians(q)
        jac = constraint.velocity_terms(kin, q, 0.0).jacobian
        columns = []
        for direction in np.eye(scene.model.nv):
            ends = []
            for step in (EPS, -EPS):
                moved = pin.integrate(scene.model, q, step * direction)
                kin.update_positions(moved)
                ends.append(constraint.residual(kin, moved, 0.0))
            columns.append((ends[0] - ends[1]) / (2 * EPS))
        assert np.abs(jac - np.column_stack(columns)).max() < 1e-8
        expected = _drift_by_differences(scene, constraint, kin, q, v)
        assert np.abs(drift - expected).max() < 1e-7 * (1 + np.abs(expected).max())


def test_free_coin_rolling_straight_follows_the_closed_form():
    """A free-flying upright coin with disk-touch + rolling-disk, rolling along x at phi' = 5 rad/s: for
    0.5 s (RK4 + projection, 1 ms) its centre moves at x' = r phi' = 1.5 m/s within 1e-9 m, stays at height r
    and upright, energy within 1e-9 J; the floor carries its weight m g on the touch row within 1e-9 N."""
    scene = _coin(0.0, [_disk("disk-touch"), _disk("rolling-disk")], v=[RADIUS * SPIN_RATE, 0, 0, 0, SPIN_RATE, 0])
    run = pinstab.simulate(scene, method="projection", integrator="rk4", dt=DT, duration=0.5)
    final = pin.XYZQUATToSE3(run.q[-1][:7])
    assert np.abs(final.translation - [RADIUS * SPIN_RATE * 0.5, 0.0, RADIUS]).max() < 1e-9
    assert abs(final.rotation[2, 1]) < 1e-12  # the axis stays horizontal
    assert np.ptp(run.energy) < 1e-9
    assert np.abs(run.multipliers_of("coin-disk-touch")[:, 0] - MASS * GRAVITY).max() < 1e-9
    assert np.max(run.position_drift) < 1e-12 and np.max(run.velocity_drift) < 1e-10


def test_a_disk_lying_flat_has_no_contact_point():
    """Axis along the normal: refused at load (SceneError), and by the rows at run time (ConstraintError)."""
    flat = _disk("rolling-disk", axis=[0, 0, 1])
    with pytest.raises(SceneError, match=r"contact 'coin-rolling-disk': the disk lies flat"):
        _coin(0.0, [flat])
    scene = _coin(0.0, [_disk("rolling-disk")])
    constraint, kin = _rows(scene)
    lying = pin.SE3ToXYZQUAT(pin.SE3(pin.exp3(np.array([math.pi / 2, 0.0, 0.0])), np.zeros(3)))
    kin.update_jacobians(lying)
    with pytest.raises(ConstraintError, match="coin-rolling-disk: the disk lies flat"):
        constraint.velocity_terms(kin, lying, 0.0)


# -- the recording ---------------------------------------------------------------------------------------------
def test_recording_draws_the_disk_where_it_rolls(run, tmp_path):
    """The recording holds a cylinder of radius 0.3 m and length 2 cm (the URDF visual), and its last frame
    puts the disk's centre at the closed-form point (R sin 5, R (1 - cos 5), r) within 1e-6 m."""
    scene = pinstab.load_scene("rolling-disk")
    recording = write_recording(ConstrainedModel(scene), run, tmp_path / "disk.html", fps=10.0)
    page = recording.path.read_text()
    start = page.index("var commands = [")
    listing = page[start : page.index("];", start)]
    commands = [umsgpack.unpackb(base64.b64decode(text)) for text in re.findall(r'"([A-Za-z0-9+/=]+)"', listing)]
    shapes = {c["path"]: c["object"]["geometries"][0] for c in commands if c["type"] == "set_object"}
    (path,) = [p for p, shape in shapes.items() if shape["type"] == "CylinderGeometry"]
    assert shapes[path]["radiusTop"] == pytest.approx(RADIUS, abs=1e-12)
    assert shapes[path]["height"] == pytest.approx(0.02, abs=1e-12)
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    (track,) = [
        t
        for item in animation["animations"]
        if item["path"] == path
        for t in item["clip"]["tracks"]
        if t["name"] == ".position"
    ]
    assert len(track["keys"]) == recording.frames == 51
    angle = HEADING_RATE * DURATION
    expected = [CIRCLE * math.sin(angle), CIRCLE * (1 - math.cos(angle)), RADIUS]
    assert np.abs(np.array(track["keys"][-1]["value"]) - expected).max() < 1e-6


# -- bad input -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        ({"frame": "wheel"}, r"contact 'floor'\.frame: unknown frame 'wheel'; valid frames: world, .*disk"),
        ({"radius": 0.0}, r"contact 'floor'\.radius must be > 0, got 0\.0"),
        ({"radius": "-30 mm"}, r"contact 'floor'\.radius must be > 0, got '-30 mm'"),
        ({"radius": "30 deg"}, r"contact 'floor'\.radius: unit 'deg' is not a unit of length"),
        ({"radius": None}, r"contact 'floor': 'radius' is required"),
        ({"axis": [0.0, 0.0, 0.0]}, r"contact 'floor'\.axis must be a non-zero vector"),
        ({"normal": [0.0, 0.0, 0.0]}, r"contact 'floor'\.normal must be a non-zero vector"),
        ({"axis": [0.0, 1.0]}, r"contact 'floor'\.axis must be a list of 3 numbers"),
        ({"spin": 1.0}, r"contact 'floor': unknown key 'spin'; valid keys: .*radius"),
        ({"axis": [0.0, 0.0, 1.0]}, r"contact 'floor': the disk lies flat on the plane"),
    ],
)
def test_bad_disk_input_names_the_item(changes, pattern):
    entry = {"name": "floor", "kind": "rolling-disk", "frame": "disk", "axis": [0, 1, 0], "radius": RADIUS, **changes}
    entry = {key: value for key, value in entry.items() if value is not None}
    data = {"robot": {"urdf": str(ROBOTS / "urdf" / "rolling-disk.urdf")}, "contacts": [entry]}
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(data)

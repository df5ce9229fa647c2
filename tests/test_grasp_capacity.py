"""What a grasp carries, on the exact round cones, against closed forms (the antipodal pinch: squeeze
m g / (2 mu), largest load 2 mu F, first slipping tilt), against a second method (linear programs on
inscribed and circumscribed pyramids of 512 sides bracket the squeeze), and against the dynamics (a
grasp-hold capped at the squeeze holds just below the predicted tilt and loses the grasp just above it)."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog

from conftest import ROBOTS
from pinstab import assemble
from pinstab.errors import GraspLostError
from pinstab.grasp import GraspContact, grasp_map
from pinstab.grasp.capacity import Weight, first_slip_tilt, grasp_capacity
from pinstab.grasp.holding import least_squeeze
from pinstab.grasp.report import analyse_scene_grasps, tilt_at_first_slip
from pinstab.scene import scene_from_dict
from pinstab.system import build_system

G = 9.81
HALF_WIDTH = 0.05  # [m]


def pinch(mu: float) -> list[GraspContact]:
    """Two point contacts at -+x on a block, normals along +-x (into the block), gravity along -z (tangent)."""
    left = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    right = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
    return [
        GraspContact("left", "point-friction", np.array([-HALF_WIDTH, 0.0, 0.0]), left, mu),
        GraspContact("right", "point-friction", np.array([HALF_WIDTH, 0.0, 0.0]), right, mu),
    ]


def block(mass: float) -> Weight:
    return Weight(mass, np.zeros(3), np.array([0.0, 0.0, -G]), np.eye(3))


@pytest.mark.parametrize(("mu", "mass"), [(0.5, 1.0), (0.8, 0.1), (1.3, 20.0)])
def test_pinch_needs_m_g_over_2_mu_and_carries_2_mu_f(mu, mass):
    """Closed form: holds iff 2 mu F >= m g; squeeze needed m g / (2 mu), largest load 2 mu F (1e-9 rel)."""
    contacts = pinch(mu)
    capacity = grasp_capacity(grasp_map(contacts), contacts, block(mass), 3.0, {})
    assert capacity.squeeze_needed == pytest.approx(mass * G / (2 * mu), rel=1e-9)
    assert capacity.largest_load == pytest.approx(2 * mu * 3.0, rel=1e-9)
    assert capacity.load == pytest.approx(mass * G, rel=1e-15)


def test_pinch_tilted_across_its_axis_slips_at_the_closed_form_tilt():
    """Tilted by theta about y (across the fingers' axis) the weight gets a normal part m g sin(theta), which
    the far finger's extra normal force carries; the moment balance about y splits the tangential part
    m g cos(theta) equally, so the near finger needs mu f_n >= m g cos(theta) / 2: the least squeeze is
    m g (cos(theta) / (2 mu) + sin(theta)). With mu = 0.5 it peaks at sqrt(2) m g; at F = 1.05 m g the first
    slip is at 45 deg - acos(1.05 / sqrt(2)) (1e-5 deg). About x (the fingers' axis) gravity stays
    tangential: it holds at every tilt."""
    mu, mass, squeeze = 0.5, 1.0, 1.05 * G
    contacts = pinch(mu)
    matrix = grasp_map(contacts)
    expected = 45.0 - math.degrees(math.acos(1.05 / math.sqrt(2.0)))
    for sense in (1.0, -1.0):
        tilt = first_slip_tilt(matrix, contacts, block(mass), np.array([0.0, sense, 0.0]), squeeze)
        assert tilt == pytest.approx(expected, abs=1e-5)
    assert math.isinf(first_slip_tilt(matrix, contacts, block(mass), np.array([1.0, 0.0, 0.0]), squeeze))
    for theta in np.radians([10.0, 40.0, 70.0]):
        need = least_squeeze(matrix, block(mass).load(theta, np.array([0.0, 1.0, 0.0])), contacts).squeeze
        closed = mass * G * (math.cos(theta) / (2 * mu) + math.sin(theta))
        assert need == pytest.approx(closed, rel=1e-9)


@pytest.mark.parametrize("mu", [0.3, 0.5, 1.0])
def test_tilted_pinch_needs_the_closed_form_squeeze_at_every_degree(mu):
    """The least squeeze m g (cos(theta) / (2 mu) + sin(theta)) of the pinch tilted about y, every degree from 0
    to 89 (1e-9 rel). Regression: SLSQP's step relaxes its constraints where their linearization is inconsistent,
    f_n >= 0 among them; an iterate then reached the mirror cone (f_n < 0, mu^2 f_n^2 >= |f_t|^2 holds there too)
    and the squeeze came out high: the inscribed pyramids' start's, up to 1 / cos(pi / 16) - 1 = 2 % (SciPy 1.15: mu 1
    at 21 deg, 1.1 %; 1.17: mu 0.5 at 10 deg, 1.7 %), or where SLSQP stopped on its way back (1.17: mu 1 at 80 deg)."""
    contacts = pinch(mu)
    matrix = grasp_map(contacts)
    for theta in np.radians(np.arange(90.0)):
        need = least_squeeze(matrix, block(1.0).load(theta, np.array([0.0, 1.0, 0.0])), contacts).squeeze
        assert need == pytest.approx(G * (math.cos(theta) / (2 * mu) + math.sin(theta)), rel=1e-9), math.degrees(theta)


def pyramid_squeeze(matrix: np.ndarray, contacts: list[GraspContact], load: np.ndarray, sides: int, widen: float):
    """The least largest normal force on pyramids of ``sides`` sides inscribed in the cones of widen * mu
    (point contacts), by a linear program written here: variables (f per contact, s)."""
    count = 3 * len(contacts)
    rows = []
    for k, contact in enumerate(contacts):
        for angle in 2 * np.pi * np.arange(sides) / sides:
            row = np.zeros(count + 1)  # cos a f_x + sin a f_y - mu' cos(pi/sides) f_z <= 0
            row[3 * k : 3 * k + 3] = [math.cos(angle), math.sin(angle), -widen * contact.mu * math.cos(math.pi / sides)]
            rows.append(row)
        row = np.zeros(count + 1)
        row[3 * k + 2], row[-1] = 1.0, -1.0  # f_z <= s
        rows.append(row)
    cost = np.zeros(count + 1)
    cost[-1] = 1.0
    result = linprog(
        cost,
        A_ub=np.array(rows),
        b_ub=np.zeros(len(rows)),
        A_eq=np.hstack([matrix, np.zeros((6, 1))]),
        b_eq=load,
        bounds=[(None, None)] * count + [(0, None)],
    )
    assert result.status == 0
    return float(result.x[-1])


def sphere_contacts(directions: list[list[float]], mu: float) -> list[GraspContact]:
    found = []
    for k, outward in enumerate(directions):
        normal = -np.asarray(outward, float) / np.linalg.norm(outward)
        helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
        x = np.cross(helper, normal)
        x /= np.linalg.norm(x)
        rotation = np.column_stack([x, np.cross(normal, x), normal])
        found.append(GraspContact(f"c{k}", "point-friction", -0.035 * normal, rotation, mu))
    return found


THREE = [[math.cos(a), math.sin(a), -0.3] for a in 2 * np.pi * np.arange(3) / 3]
FOUR = [[1.0, 0.2, 0.1], [-0.3, 1.0, -0.2], [-1.0, -0.1, 0.3], [0.2, -1.0, -0.4]]


@pytest.mark.parametrize("directions", [THREE, FOUR], ids=["three", "four"])
@pytest.mark.parametrize("tilt", [0.0, 35.0, 120.0])
def test_sphere_squeeze_lies_between_the_inscribed_and_circumscribed_pyramids(directions, tilt):
    """A 0.1 kg sphere on 3 or 4 fingers (mu 0.6): the exact squeeze lies between the 512-sided pyramids'
    (inscribed: an upper bound, circumscribed: a lower bound; within 1e-4 of each other)."""
    contacts = sphere_contacts(directions, 0.6)
    matrix = grasp_map(contacts)
    load = block(0.1).load(math.radians(tilt), np.array([1.0, 0.0, 0.0]))
    exact = least_squeeze(matrix, load, contacts).squeeze
    inscribed = pyramid_squeeze(matrix, contacts, load, 512, 1.0)
    circumscribed = pyramid_squeeze(matrix, contacts, load, 512, 1.0 / math.cos(math.pi / 512))
    assert circumscribed * (1 - 1e-9) <= exact <= inscribed * (1 + 1e-9)
    assert inscribed / circumscribed - 1 < 1e-4


def allegro(**hold) -> dict:
    """allegro-sphere without its push, the grasp-hold's keys updated by ``hold``."""
    data = tomllib.loads((ROBOTS / "allegro-sphere.toml").read_text())
    data["forces"] = [f for f in data["forces"] if f["name"] != "push"]
    data["forces"][0].update(hold)
    return data


SQUEEZE = 0.56  # [N] just above the ball's untilted need (0.557 N): a tilt about -x slips within degrees


@pytest.fixture(scope="module")
def predicted() -> float:
    return tilt_at_first_slip(scene_from_dict(allegro(), base_dir=ROBOTS), np.array([-1.0, 0.0, 0.0]), SQUEEZE)


def start_dynamics(tilt_deg: float):
    """The dynamics at the assembled start of allegro-sphere with the hand tilted by ``tilt_deg`` about -x
    (gravity turned the other way), held by a grasp-hold pressing at most SQUEEZE."""
    data = allegro(squeeze=SQUEEZE, max_squeeze=SQUEEZE)
    data["gravity"] = (pin.exp3(math.radians(tilt_deg) * np.array([1.0, 0.0, 0.0])) @ [0.0, 0.0, -G]).tolist()
    scene = scene_from_dict(data, base_dir=ROBOTS)
    system = build_system(scene, "baumgarte", "dense")
    start = assemble(system.model, scene.q0, scene.v0)
    return system.dynamics(start.q, start.v, 0.0)


def test_the_dynamics_lets_go_at_the_predicted_tilt(predicted):
    """A grasp-hold capped at the squeeze: 0.01 deg before the predicted tilt every contact holds (the ball
    at rest, accelerations <= 1e-8), 0.01 deg after it the run loses the grasp naming the contacts."""
    assert 0.5 < predicted < 5.0
    evaluation = start_dynamics(predicted - 0.01)
    assert np.abs(evaluation.acceleration).max() < 1e-8
    with pytest.raises(GraspLostError) as info:
        start_dynamics(predicted + 0.01)
    assert set(info.value.contacts) <= {"index", "middle", "ring", "thumb"} and info.value.margin < 0


def test_the_report_gives_squeeze_load_and_tilts():
    scene = scene_from_dict(allegro(), base_dir=ROBOTS)
    capacity = analyse_scene_grasps(scene, squeeze=SQUEEZE)["ball"].capacity
    assert capacity.load == pytest.approx(0.1 * G)
    assert capacity.largest_load == pytest.approx(capacity.load * SQUEEZE / capacity.squeeze_needed, rel=1e-12)
    assert set(capacity.tilts) == {"+x", "-x", "+y", "-y"}

"""Hand-object collision checks (pinstab.contact.collisions): overlaps and contacts on edges, against closed forms
of a sphere fingertip over a box."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from pinstab import simulate
from pinstab.cli import main
from pinstab.contact.collisions import EDGE_ANGLE, EDGE_TOLERANCE, PENETRATION_TOLERANCE, normal_turn
from pinstab.errors import EdgeContactWarning, PenetrationWarning
from pinstab.scene import scene_from_dict

RADIUS = 0.01  # [m] the fingertip sphere
HALF = 0.02  # [m] half the box's side: its top face is at z = HALF, its edge x = HALF, z = HALF
INERTIA = '<inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/>'
GANTRY = f"""<?xml version="1.0"?>
<robot name="gantry">
  <link name="base"/>
  <link name="carriage"><inertial><mass value="0.1"/>{INERTIA}</inertial></link>
  <link name="tip">
    <inertial><mass value="0.1"/>{INERTIA}</inertial>
    <collision><geometry><sphere radius="{RADIUS}"/></geometry></collision>
  </link>
  <joint name="x" type="prismatic">
    <parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="10"/>
  </joint>
  <joint name="z" type="prismatic">
    <parent link="carriage"/><child link="tip"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="10"/>
  </joint>
</robot>
"""


def gantry_over_box(x: float, z: float, contact: bool = False, vz: float = 0.0) -> dict:
    """Scene content: a sphere fingertip (radius 10 mm, centre at (x, 0, z) [m]) on two prismatic joints over a
    40 mm cube centred at the origin; with ``contact``, a grasp contact of the fingertip on the cube."""
    data = {
        "gravity": [0.0, 0.0, 0.0],
        "robot": {"urdf_text": GANTRY},
        "objects": [{"name": "box", "shape": "box", "size": [2 * HALF] * 3, "mass": 0.1, "position": [0, 0, 0]}],
        "initial": {"q": {"x": x, "z": z}, "v": {"z": vz}},
    }
    if contact:
        data["contacts"] = [
            {"name": "press", "kind": "grasp-contact", "finger": "tip", "object": "box", "radius": RADIUS, "mu": 0.5}
        ]
    return data


def loaded(data: dict):
    """(the scene, the warnings its loading gave)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scene_from_dict(data)
    return scene, [w.message for w in caught]


def test_a_fingertip_1_mm_inside_the_object_loads_with_a_warning_naming_the_pair_and_depth():
    scene, caught = loaded(gantry_over_box(0.0, HALF + RADIUS - 1e-3))
    assert len(caught) == 1 and isinstance(caught[0], PenetrationWarning)
    assert "link 'tip'" in str(caught[0]) and "object 'box'" in str(caught[0])
    assert "interpenetrate by 1.000 mm at the start" in str(caught[0])


@pytest.mark.parametrize("x", [0.0, 0.012])
@pytest.mark.parametrize("depth", [-2e-3, -1e-5, 3e-5, 1e-3, 4e-3])
def test_the_depth_is_the_sphere_box_overlap(x, depth):
    """Closed form: over the top face the overlap is RADIUS - (z - HALF) [m] (0 when apart)."""
    scene, _ = loaded(gantry_over_box(x, HALF + RADIUS - depth))
    depths = scene.collisions.depths(scene.q0)
    assert depths == pytest.approx([max(depth, 0.0)], abs=1e-9)
    reported = [o.depth for o in scene.collisions.overlaps(scene.q0)]
    assert reported == pytest.approx([depth] if depth > PENETRATION_TOLERANCE else [], abs=1e-9)


def test_an_overlap_within_the_tolerance_gives_no_warning():
    _, caught = loaded(gantry_over_box(0.0, HALF + RADIUS - 0.5 * PENETRATION_TOLERANCE))
    assert caught == []


def test_an_overlap_reached_during_a_run_is_a_warning_with_its_depth_and_time():
    """The fingertip moves down at 0.1 m/s (no force, nothing holds it) from 5 mm above touching: after 0.1 s it
    is 5 mm deep, at the run's end."""
    scene, caught = loaded(gantry_over_box(0.0, HALF + RADIUS + 5e-3, vz=-0.1))
    assert caught == []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate(scene, method="none", duration=0.1, dt=1e-3)
    messages = [str(w.message) for w in caught if isinstance(w.message, PenetrationWarning)]
    assert len(messages) == 1
    assert "interpenetrate by 5.000 mm during the run (deepest at t = 0.1 s; 0.000 mm at the start" in messages[0]


def test_the_finger_body_of_a_contact_is_not_checked_against_its_object():
    scene, caught = loaded(gantry_over_box(0.0, HALF + RADIUS + 3e-3, contact=True))
    assert scene.collisions.names == []  # the tip's only shape is the contact's body's
    assert caught == []


@pytest.mark.parametrize("inside", [5e-5, 2e-4, 5e-3])
def test_the_normal_turns_at_an_edge_as_its_closed_form(inside):
    """A contact ``inside`` [m] from the box's edge on its top face: the probe reaching EDGE_TOLERANCE across the
    edge sees the edge, its normal turned by atan((EDGE_TOLERANCE - inside) / EDGE_TOLERANCE); none beyond."""
    scene, _ = loaded(gantry_over_box(HALF - inside, HALF + RADIUS + 3e-3))
    item = scene.objects[0]
    turn = normal_turn(item, item.placement, np.array([HALF - inside, 0.0, HALF]), np.array([0.0, 0.0, -1.0]))
    expected = math.atan(max(EDGE_TOLERANCE - inside, 0.0) / EDGE_TOLERANCE)
    assert turn == pytest.approx(expected, abs=1e-7)


@pytest.mark.parametrize(
    ("x", "on_edge"),
    [(HALF + 5e-3, True), (HALF - 5e-5, True), (HALF - 5e-4, False), (0.0, False)],
)
def test_a_grasp_contact_on_an_edge_is_a_warning_naming_it(x, on_edge):
    """The loader brings the fingertip down onto the box: beyond the edge (x > HALF) it touches the edge itself;
    over the face it touches the face at x, |x - HALF| from the edge."""
    scene, caught = loaded(gantry_over_box(x, HALF + RADIUS + 3e-3, contact=True))
    edges = [str(w) for w in caught if isinstance(w, EdgeContactWarning)]
    assert len(edges) == on_edge
    if on_edge:
        assert "contact 'press' sits on an edge or a vertex of object 'box'" in edges[0]


def test_a_contact_on_a_sphere_is_on_no_edge():
    """A sphere of radius R turns the probes' normals by about EDGE_TOLERANCE / R only."""
    data = gantry_over_box(0.0, 0.08, contact=True)
    data["objects"] = [{"name": "box", "shape": "sphere", "radius": 0.03, "mass": 0.1, "position": [0, 0, 0]}]
    scene, caught = loaded(data)
    assert not [w for w in caught if isinstance(w, EdgeContactWarning)]
    item = scene.objects[0]
    turn = normal_turn(item, item.placement, np.array([0.0, 0.0, 0.03]), np.array([0.0, 0.0, -1.0]))
    assert turn == pytest.approx(math.atan(EDGE_TOLERANCE / (0.03 + EDGE_TOLERANCE)), rel=1e-6)
    assert turn < EDGE_ANGLE


def test_check_prints_the_warning_and_lists_the_overlap(tmp_path, capsys):
    (tmp_path / "gantry.urdf").write_text(GANTRY)
    (tmp_path / "inside.toml").write_text(
        'gravity = [0.0, 0.0, 0.0]\n[robot]\nurdf = "gantry.urdf"\n'
        '[[objects]]\nname = "box"\nshape = "box"\nsize = [0.04, 0.04, 0.04]\nmass = 0.1\n'
        f"[initial]\nq = {{ x = 0.0, z = {HALF + RADIUS - 1e-3} }}\n"
    )
    assert main(["check", str(tmp_path / "inside.toml"), "--json"]) == 0
    out, err = capsys.readouterr()
    assert "pinstab check: warning: scene inside: link 'tip'" in err and "by 1.000 mm at the start" in err
    (overlap,) = json.loads(out)["overlaps"]
    assert overlap["link"] == "tip" and overlap["object"] == "box"
    assert overlap["depth_mm"] == pytest.approx(1.0, abs=1e-6)

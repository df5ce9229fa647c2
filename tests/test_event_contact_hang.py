"""A contact on a long lever and its impacts: the solver's answer polished onto the impact law.

The long fuzzer's scene (HYPOTHESIS_PROFILE=long): a 0.01 kg cylinder (radius 1 cm) on three plane contacts, one of
them 1 m out (within ten scene sizes), thrown spinning. Its Delassus number (some 1e7 m/s per N s) beside the rim
contacts' (some 1e2) left ADMM's impact answer, accepted to 1e-6 of the velocity scale, approaching its plane at
2e-8 m/s after an impact with e = 0: not touching, its gap closed again at once, 1300 impacts in 1e-8 s of
simulated time and no end (stopped by SIGTERM after 60 s).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from fuzzing import cli, contact_gaps, mechanical_energy, toml_document

from pinstab.contact.modes import Mode
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import ModeDynamics
from pinstab.solvers.impacts import impact
from pinstab.solvers.ncp import NcpSolver
from pinstab.trajectory import Trajectory

LEVER = {  # the fuzzer's reproducer (/tmp/f2/hang_event.toml)
    "gravity": [0.0, 0.0, -9.81],
    "robot": {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"},
    "objects": [
        {
            "name": "crate",
            "shape": "cylinder",
            "radius": 0.01,
            "length": 0.02,
            "mass": 0.01,
            "position": [0.0, 0.0, 0.010194575268748708],
        }
    ],
    "contacts": [
        {
            "name": "c0",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [0.010603714426527942, -0.0009905820208363592, -0.01],
            "restitution": 0.8532225864254366,
        },
        {
            "name": "c1",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [-0.004048461045998576, 0.008632093666488738, -0.009805424731251292],
            "restitution": 1.1754943508222875e-38,
        },
        {
            "name": "c2",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [-1.0, -0.008112043297607941, -0.01],
            "mu": 0.0,
            "restitution": 0.0,
        },
    ],
    "initial": {
        "v": {
            "crate": [1.0, 0.24859405967056714, 0.00019457526874870797, -1.0, -0.3333333333333333, 0.02069683681639778]
        }
    },
}
DURATION = 0.02  # [s] past the impacts at t = 0.0064 s where the run hung, and the next ones (0.014 to 0.02 s)


def _scene_file(tmp_path, scene: dict) -> str:
    path = tmp_path / "lever.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    return str(path)


def test_lever_scene_runs_out_of_its_planes_without_creating_energy(tmp_path) -> None:
    source = _scene_file(tmp_path, LEVER)
    saved = tmp_path / "run.npz"
    outcome = cli(["run", source, "--contacts", "event", "--duration", str(DURATION), "--save", str(saved), "--quiet"])
    assert outcome.code == 0, outcome.message
    trajectory = Trajectory.load(saved)
    assert trajectory.t[-1] == pytest.approx(DURATION)
    scene = load_scene(source)
    gaps = contact_gaps(scene, trajectory.q)
    assert gaps.min() >= -1e-6  # the fuzzer's GAP_TOLERANCE: no point through its plane
    energy = mechanical_energy(scene, trajectory.q, trajectory.v)
    assert np.max(energy - energy[0]) <= 1e-5 * (1.0 + energy[0])  # the fuzzer's event tolerance
    assert energy[-1] < energy[0]  # an impact of e = 0.85 and plastic ones took some


@pytest.mark.parametrize("contacts", ["stepping", "held"])
def test_lever_scene_ends_on_the_other_treatments(tmp_path, contacts: str) -> None:
    """Time-stepping runs it; held contacts refuse it by name (c2 frictionless, pushed sideways at the start)."""
    outcome = cli(["run", _scene_file(tmp_path, LEVER), "--contacts", contacts, "--duration", str(DURATION), "--quiet"])
    assert outcome.code == (0 if contacts == "stepping" else 5), outcome.message
    if contacts == "held":
        assert "'c2'" in outcome.message and "mu = 0" in outcome.message


def test_impact_on_a_long_lever_leaves_its_contact_on_its_plane() -> None:
    """A plastic impact (e = 0) of the frictionless contact 1 m out alone, the body's centre 1 cm up: its normal
    velocity after it is 0 to rounding of its velocity before (the answer ADMM alone gave: 1.7e-8 m/s inwards), and
    its impulse is the single contact's closed form ``-u_n- / D`` (D its Delassus number)."""
    scene = copy.deepcopy(LEVER)
    scene["objects"][0]["position"] = [0.0, 0.0, 0.01]  # every rim point and the far one on the plane
    loaded = scene_from_dict(scene, "lever")
    geometries, system, q, _, _ = contact_system(loaded, loaded.q0, loaded.v0)
    dynamics = ModeDynamics(system.model, geometries)
    v = np.array([1.0, 0.2486, -0.5, -1.0, -0.333, 0.0207])  # c2 closing (the body's frame velocity)
    solution = dynamics.solve(q, v, 0.0, [Mode.SEPARATED] * 3)
    before = solution.contacts.velocities[2, 0]
    assert before < -0.1
    result = impact(dynamics, NcpSolver(9, 1e-12, 10_000), v, solution, {2: 0.0})
    after = solution.contacts.jacobian[6] @ result.velocity
    assert abs(after) <= 1e-12 * abs(before)
    delassus = solution.contacts.jacobian[6] @ solution.mobility[:, 6]
    assert result.impulses[2, 0] == pytest.approx(-before / delassus, rel=1e-9)
    assert np.all(result.impulses[:2] == 0.0)

"""Issue 34, fuzz failures of held contacts and object masses: held rows hold a sphere contact's touching point,
a tilted held start keeps no velocity into its plane, objects lighter than a microgram are refused by name, and a
singular mass matrix in the contact modes is a named SolverError."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from fuzzing import cli, contact_gaps, mechanical_energy, toml_document
from test_fuzz_tables import HELD_SINK

import pinstab
from pinstab.errors import SolverError
from pinstab.model import ConstrainedModel
from pinstab.scene import load_scene
from pinstab.solvers.contact_modes import ModeDynamics, plane_geometries
from pinstab.units import MIN_MASS

BALL_RADIUS = 0.05  # [m] bouncing-ball's ball (pinstab/generators.py)


def crate_scene(mass: float) -> dict:
    """A 1 m x 1 m x 0.2 m box of ``mass`` [kg] on one frictionless corner (it tips over)."""
    return {
        "gravity": [0.0, 0.0, -9.81],
        "robot": {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"},
        "objects": [{"name": "crate", "shape": "box", "size": [1.0, 1.0, 0.2], "mass": mass, "position": [0, 0, 0.1]}],
        "contacts": [{"name": "c0", "kind": "plane-contact", "frame_a": "crate", "offset_a": [0.5, 0.5, -0.1]}],
    }


def test_held_ball_rests_on_its_touching_point():
    """bouncing-ball held: the assembly puts the ball on the plane with its centre one radius above it (it held
    the centre on the plane, half the ball below), and the rows keep it there."""
    trajectory = pinstab.simulate("bouncing-ball", contacts="held", duration=0.05)
    assert np.allclose(trajectory.q[:, 2], BALL_RADIUS, atol=1e-9)


def test_held_sphere_with_friction_is_refused_by_name():
    outcome = cli(["run", "sphere-spin", "--contacts", "held", "--duration", "0.05", "--quiet"])
    assert outcome.code == 2 and "ground" in outcome.message and "radius" in outcome.message, outcome


@pytest.mark.parametrize("height", [1e-3, 1e-5])
def test_tilted_held_start_keeps_no_velocity_into_the_plane(tmp_path, height):
    """HELD_SINK with c2 ``height`` [m] above the plane: the assembly closes it, the projection then stops the
    1 m/s into the plane (every gap stays >= -1e-12 m, the energy at its start, the throw's kinetic energy lost)."""
    scene = copy.deepcopy(HELD_SINK)
    scene["contacts"][2]["offset_a"][2] = -0.45 + height
    path = tmp_path / "sink.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    loaded = load_scene(str(path))
    trajectory = pinstab.simulate(loaded, contacts="held", duration=0.12)
    assert contact_gaps(loaded, trajectory.q).min() >= -1e-12
    energy = mechanical_energy(loaded, trajectory.q, trajectory.v)
    assert np.ptp(energy) <= 1e-9 * energy[0]
    assert energy[0] <= 60.0 * 9.81 * 0.45  # the declared start's potential energy: the throw's 30 J gone


@pytest.mark.parametrize("contacts", ["event", "stepping", "held"])
def test_an_object_of_the_least_mass_runs_as_a_heavy_one(tmp_path, contacts):
    """A microgram crate (MIN_MASS) tips over as a 1 kg one (the motion does not depend on the mass)."""
    ends = []
    for mass in (MIN_MASS, 1.0):
        path = tmp_path / f"crate-{mass}.toml"
        path.write_text(toml_document(crate_scene(mass)), encoding="utf-8")
        trajectory = pinstab.simulate(str(path), contacts=contacts, duration=0.12)
        ends.append(trajectory.q[-1])
    assert np.allclose(ends[0], ends[1], atol=1e-9)


@pytest.mark.parametrize("mass", [MIN_MASS * 0.999, 1e-12, 5e-324])
def test_an_object_lighter_than_a_microgram_is_refused(tmp_path, mass):
    path = tmp_path / "crate.toml"
    path.write_text(toml_document(crate_scene(mass)), encoding="utf-8")
    outcome = cli(["run", str(path), "--duration", "0.05", "--quiet"])
    assert outcome.code == 2 and "object 'crate'.mass" in outcome.message and "1e-09" in outcome.message, outcome


def test_a_density_below_a_microgram_is_refused(tmp_path):
    scene = crate_scene(1.0)
    del scene["objects"][0]["mass"]
    scene["objects"][0]["density"] = 1e-9  # 0.2 m^3: 2e-10 kg
    path = tmp_path / "crate.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    outcome = cli(["check", str(path)])
    assert outcome.code == 2 and "object 'crate'.mass = 2e-10 kg" in outcome.message, outcome


def test_a_singular_mass_matrix_in_the_contact_modes_is_named(monkeypatch):
    scene = load_scene("bouncing-ball")
    model = ConstrainedModel(scene)
    dynamics = ModeDynamics(model, plane_geometries(scene.constraints))
    terms = model.dynamics_terms
    monkeypatch.setattr(model, "dynamics_terms", lambda q, v, t: terms(q, v, t)._replace(mass_matrix=np.zeros((6, 6))))
    with pytest.raises(SolverError, match=r"contacts ground at t = 0\.25 s: the mass matrix is singular"):
        dynamics.solve(scene.q0, np.zeros(6), 0.25)

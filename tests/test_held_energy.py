"""Energy of held contacts and of impacts (issue 34): a held contact that starts separating is refused (its row
would push the rising point back, creating energy), a frictionless held sphere keeps the closed form of sliding
on a plane, and an event-driven impact at several contacts never creates kinetic energy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from fuzzing import cli, mechanical_energy, toml_document

import pinstab.solvers.impacts as impacts
from pinstab.generators import incline
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import Mode, ModeDynamics
from pinstab.solvers.ncp import NcpSolver

STAND = {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"}
OFFSET = (0.000885, -0.0002)  # [m] the spinning ball's contact point, off its centre (tests/test_fuzz_tables.py)
SPIN = (-0.2081233807319005, -1.0, 0.3333333333333333)  # [rad/s] its spin, body axes = world axes at the start


def ball(offset: tuple[float, float], twist: list[float], radius: float = 0.0, height: float = 0.0) -> dict:
    """A 0.056 kg ball of radius 0.01 m whose one frictionless plane contact is the body point ``offset`` (x, y)
    [m] of its centre's height (a sphere of ``radius`` [m] about it), the centre ``height`` [m] above the plane
    (the contact touching: no assembly step), moving at ``twist`` (v, w; body axes)."""
    return {
        "gravity": [0.0, 0.0, -9.81],
        "robot": STAND,
        "objects": [{"name": "crate", "shape": "sphere", "radius": 0.01, "mass": 0.056, "position": [-1, 0, height]}],
        "contacts": [
            {"name": "c0", "kind": "plane-contact", "frame_a": "crate", "offset_a": [*offset, 0.0], "radius": radius}
        ],
        "initial": {"v": {"crate": twist}},
    }


def run_cli(scene: dict, folder: Path, contacts: str = "held"):
    path = folder / "scene.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    return cli(["run", str(path), "--contacts", contacts, "--duration", "0.12", "--json", "--quiet"])


def test_spinning_point_contact_separating_is_refused_at_its_speed(tmp_path: Path) -> None:
    """The fuzzer's spinning ball (SPINNING_ON_A_POINT) with its point on the plane: the spin lifts the point at
    u_n = w_x r_y - w_y r_x (the closed form of (w x r) . z); held, its row pushed the rising point back (+1.87e-5 J,
    3.3e-4 of the start): refused, naming the contact and that speed, before any step."""
    rate = SPIN[0] * OFFSET[1] - SPIN[1] * OFFSET[0]
    outcome = run_cli(ball(OFFSET, [-1.0, 1.0, 0.0, *SPIN]), tmp_path)
    assert outcome.code == 2, outcome
    assert "contact c0 starts separating" in outcome.message
    assert f"at {rate:.6g} m/s" in outcome.message
    assert "contacts='event'" in outcome.message
    assert not outcome.out.strip()


def test_check_refuses_the_separating_start_its_held_run_refuses(tmp_path: Path) -> None:
    """Nine contacts held (the scene asks for it: ``[run] contacts = "held"``) on an arc of the spinning ball's points
    around OFFSET: ``check`` refuses the start as ``run`` does (it exited 0), with the run's message, naming the contact
    separating at the closed-form speed of c0."""
    scene = ball(OFFSET, [-1.0, 1.0, 0.0, *SPIN])
    radius, heading = float(np.hypot(*OFFSET)), float(np.arctan2(OFFSET[1], OFFSET[0]))
    points = [(radius * np.cos(heading + a), radius * np.sin(heading + a)) for a in np.linspace(0.0, 0.4, 9)]
    scene["contacts"] = [
        {"name": f"c{k}", "kind": "plane-contact", "frame_a": "crate", "offset_a": [float(x), float(y), 0.0]}
        for k, (x, y) in enumerate(points)
    ]
    scene["run"] = {"contacts": "held"}
    path = tmp_path / "scene.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    checked = cli(["check", str(path)])
    ran = cli(["run", str(path), "--duration", "0.01", "--quiet"])
    rate = SPIN[0] * OFFSET[1] - SPIN[1] * OFFSET[0]
    assert checked.code == ran.code == 2, (checked, ran)
    assert (
        checked.message == ran.message and f"contact c0 starts separating from its plane at {rate:.6g}" in ran.message
    )


def test_sphere_contact_off_its_centre_spinning_is_refused(tmp_path: Path) -> None:
    """The CI job's case (contacts='held'): a sphere contact of radius 0.5 m centred 1 mm off a 0.5 m ball's centre,
    spun at w = (-1, 0, -1) rad/s: energy rose by 0.00189 J from 26.2061 J. Its centre rises at w_x r_y = 0.001
    m/s: refused."""
    scene = {
        "gravity": [0.0, 0.0, -9.81],
        "robot": STAND,
        "objects": [{"name": "crate", "shape": "sphere", "radius": 0.5, "density": 10.0, "position": [0, 0, 0.5]}],
        "contacts": [
            {"name": "c0", "kind": "plane-contact", "frame_a": "crate", "offset_a": [0, -0.001, 0], "radius": 0.5}
        ],
        "initial": {"v": {"crate": [0, 0, 0, -1, 0, -1]}},
    }
    outcome = run_cli(scene, tmp_path)
    assert outcome.code == 2, outcome
    assert "contact c0 starts separating from its plane at 0.001 m/s" in outcome.message
    assert run_cli(scene, tmp_path, "event").code == 0  # event-driven contacts let it open


@pytest.mark.parametrize(("speed", "refused"), [(impacts.REST_SPEED, False), (2 * impacts.REST_SPEED, True)])
def test_separating_speed_at_the_rest_speed_runs(speed: float, refused: bool) -> None:
    """A contact at the ball's centre rising at REST_SPEED (the boundary, at rest) runs: its row's work stays below
    weight x REST_SPEED x duration (6.6e-8 J; measured 2.0e-8 J); twice that speed is refused."""
    scene = scene_from_dict(ball((0.0, 0.0), [0.0, 0.0, speed, 0.0, 0.0, 0.0]), "rising")
    if refused:
        with pytest.raises(Exception, match="contact c0 starts separating"):
            simulate(scene, contacts="held", duration=0.12)
        return
    run = simulate(scene, contacts="held", duration=0.12)
    energy = mechanical_energy(scene, run.q, run.v)
    assert float(np.max(energy - energy[0])) <= 0.056 * 9.81 * impacts.REST_SPEED * 0.12


def test_frictionless_held_sphere_slides_as_the_closed_form() -> None:
    """A frictionless sphere (contact radius = its radius, at its centre) sliding at (-1, 1) m/s and spinning: on
    held rows, its centre moves along the plane at constant velocity at its radius' height, its spin constant (the
    sphere's inertia is isotropic), its energy constant (rk4 at dt = 1e-3 s: to 1e-9)."""
    velocity, spin, duration = np.array([-1.0, 1.0, 0.0]), np.array(SPIN), 0.12
    scene = scene_from_dict(ball((0.0, 0.0), [*velocity, *spin], radius=0.01, height=0.01), "sliding")
    run = simulate(scene, contacts="held", duration=duration)
    data = scene.model.createData()
    pin.forwardKinematics(scene.model, data, run.q[-1], run.v[-1])
    moved = data.oMi[1].translation - np.array([-1.0, 0.0, 0.01])
    motion = pin.getVelocity(scene.model, data, 1, pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(moved, velocity * duration, rtol=0, atol=1e-9)  # rk4: 2e-11 m
    np.testing.assert_allclose(motion.linear, velocity, rtol=0, atol=1e-9)
    np.testing.assert_allclose(motion.angular, spin, rtol=0, atol=1e-9)
    energy = mechanical_energy(scene, run.q, run.v)
    assert float(np.max(np.abs(energy - energy[0]))) <= 1e-9 * energy[0]


def box_impacts():
    """The incline's 1 kg cube flat on the level plane, its four frictionless corners touching: its dynamics, the
    NCP solver of event-driven impacts, its configuration and kinetic energy [J] at a velocity."""
    data = incline(theta=0.0, mu=0.3)
    for contact in data["contacts"]:
        contact.pop("mu")
    scene = scene_from_dict(data, "box")
    geometries, system, q, _, _ = contact_system(scene, scene.q0, scene.v0)
    dynamics = ModeDynamics(system.model, geometries)
    mass = system.model.mass_matrix(q)
    return dynamics, NcpSolver(3 * len(geometries), 1e-12, 10_000), q, lambda v: 0.5 * v @ mass @ v


def test_simultaneous_impacts_never_create_energy() -> None:
    """The cube hit spinning on its four corners at once, two with e = 1, two with e = 0: at the twist
    (0.7, -0.28, -0.15, -2.09, -1.06, 1.85) (corner velocities -0.2015, 0.0075, -0.3075, -0.0985 m/s) Newton's law
    adds 0.12 % of the kinetic energy (checked: the test can fail); the impact adds none beyond ENERGY_SLACK, and
    no corner is left approaching. The same for 40 more twists drawn with a fixed seed."""
    dynamics, solver, q, kinetic = box_impacts()
    restitutions = {0: 0.0, 1: 0.0, 2: 1.0, 3: 1.0}
    named = np.array([0.7, -0.28, -0.15, -2.09, -1.06, 1.85])
    for k, v in enumerate([named, *np.random.default_rng(0).normal(size=(40, 6))]):
        solution = dynamics.solve(q, v, 0.0, [Mode.SEPARATED] * 4)
        if k == 0:
            newton = impacts._scaled_impact(dynamics, solver, v, solution, restitutions, 1.0)
            assert kinetic(newton.velocity) - kinetic(v) > 1e-3 * kinetic(v)
        result = impacts.impact(dynamics, solver, v, solution, restitutions)
        assert kinetic(result.velocity) - kinetic(v) <= 1e-9 * kinetic(v)
        normal = (solution.contacts.jacobian @ result.velocity)[0::3]
        assert np.all(normal >= -1e-9)


def test_single_elastic_impact_is_newtons() -> None:
    """One frictionless corner with e = 1 hit at u_n- < 0: the impact is Newton's exactly, u_n+ = -u_n-, the
    kinetic energy kept (the clamp not engaged)."""
    dynamics, solver, q, kinetic = box_impacts()
    v = np.array([0.3, -0.2, -1.0, 0.4, -0.7, 0.5])
    solution = dynamics.solve(q, v, 0.0, [Mode.SEPARATED] * 4)
    before = solution.contacts.velocities[0, 0]
    assert before < 0
    result = impacts.impact(dynamics, solver, v, solution, {0: 1.0})
    after = (solution.contacts.jacobian @ result.velocity)[0]
    assert abs(after + before) <= 1e-9 * abs(before)
    assert abs(kinetic(result.velocity) - kinetic(v)) <= 1e-9 * kinetic(v)

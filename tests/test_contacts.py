"""Row kinds with contacts: a 1 kg box on four point contacts. Sticking contacts with friction (cone
rows) against statics and Pinocchio 4.1's own constraint solver (ADMM with Coulomb cones);
frictionless contacts (unilateral rows) against closed forms; refusals."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROBOTS
from pinstab import ConstrainedModel, ContactInfeasibleError, SolverError, assemble, load_scene, simulate
from pinstab.bench.admm_peer import admm_contact_forces
from pinstab.cli import main
from pinstab.scene import scene_from_dict
from pinstab.system import build_system

MASS, GRAVITY, MU = 1.0, 9.81, 0.5
CORNERS = [(sx * 0.1, sy * 0.05, -0.025) for sx in (1, -1) for sy in (1, -1)]


def box_scene(push=(1.0, 0.0, 0.0), mu: float | None = MU, height: float = 0.0):
    """The box resting on z = 0 on its four bottom corners, pushed at ``height`` [m] above its centre."""
    friction = {} if mu is None else {"mu": mu}
    return scene_from_dict(
        {
            "robot": {"urdf": str(ROBOTS / "urdf" / "box.urdf"), "free_flyer": True},
            "gravity": [0.0, 0.0, -GRAVITY],
            "contacts": [
                {"name": f"c{i}", "kind": "plane-contact", "frame_a": "box", "offset_a": list(corner), **friction}
                for i, corner in enumerate(CORNERS)
            ],
            "forces": [
                {
                    "name": "push",
                    "kind": "external-force",
                    "frame": "box",
                    "offset": [0, 0, height],
                    "force": list(push),
                }
            ],
            "initial": {"q": {"root_joint": [0.0, 0.0, 0.025, 0.0, 0.0, 0.0, 1.0]}},
        },
        name="box",
    )


def contact_forces(scene, method="baumgarte", solver="proxsuite"):
    """(world-axes contact forces on the box (4, 3) [N], accelerations) at the assembled start."""
    system = build_system(scene, method, solver)
    model = system.model
    start = assemble(model, scene.q0, scene.v0)
    evaluation = system.dynamics(start.q, start.v, 0.0)
    forces = []
    for constraint in model.constraints.constraints:
        rows = model.constraints.slices[constraint.name]
        forces.append(constraint.selection.T @ evaluation.multipliers[rows])
    return np.array(forces), evaluation.acceleration, start


@pytest.mark.parametrize("height", [0.0, 0.02])
def test_sticking_box_forces_balance_and_match_pinocchio_admm(height):
    """A 1 N push (inside the cone: 1 N < mu m g = 4.9 N): the normal forces carry m g to 1e-9 N,
    the friction forces the push, every force is inside its cone, the box does not accelerate, and
    Pinocchio's ADMM (tolerance 1e-12) finds the same forces to 1e-9 N (the distribution over the four
    corners is statically indeterminate; both take the smallest one)."""
    scene = box_scene(height=height)
    forces, acceleration, start = contact_forces(scene)
    np.testing.assert_allclose(forces[:, 2].sum(), MASS * GRAVITY, rtol=0, atol=1e-9)
    np.testing.assert_allclose(forces[:, :2].sum(axis=0), [-1.0, 0.0], rtol=0, atol=1e-9)
    assert np.all(np.hypot(forces[:, 0], forces[:, 1]) <= MU * forces[:, 2])
    assert np.abs(acceleration).max() < 1e-9
    # a push above the centre tips the load forward: the front corners (+x) carry more
    front, back = forces[:2, 2].sum(), forces[2:, 2].sum()
    assert front - back == pytest.approx(2 * 1.0 * (0.025 + height) / 0.2, abs=1e-9)
    model = ConstrainedModel(scene)
    model.kin.update(start.q, start.v)
    tau = model.applied_force(start.v, 0.0)
    np.testing.assert_allclose(admm_contact_forces(scene, start.q, start.v, tau), forces, rtol=0, atol=1e-9)


def test_sticking_box_stays_put_over_a_run():
    traj = simulate(box_scene(), method="baumgarte", dt=2e-3, duration=0.5, contacts="held")
    assert np.abs(traj.q - traj.q[0]).max() < 1e-9
    assert traj.position_drift.max() < 1e-12
    assert traj.info.row_kinds == {f"c{i}": "cone" for i in range(4)}
    normals = traj.multipliers[:, 0::3]
    np.testing.assert_allclose(normals.sum(axis=1), MASS * GRAVITY, atol=1e-9)


def test_push_outside_the_cone_names_the_contacts(capsys, tmp_path):
    """6 N > mu m g = 4.905 N: sticking contacts cannot hold; the error names them and the ratio."""
    with pytest.raises(ContactInfeasibleError, match=r"contact 'c[23]' needs \|f_t\|/f_n = 0\.722 > mu = 0\.5") as info:
        contact_forces(box_scene(push=(6.0, 0.0, 0.0)))
    assert sorted(info.value.contacts) == ["c0", "c1", "c2", "c3"]
    # the same through the CLI with held contacts: exit 5 (contacts with no solution), one-paragraph message
    bundled = (ROBOTS / "box-push.toml").read_text()
    path = tmp_path / "box.toml"
    path.write_text(
        bundled.replace('force = ["1 N", 0.0, 0.0]', 'force = ["6 N", 0.0, 0.0]').replace(
            'urdf = "urdf/box.urdf"', f'urdf = "{ROBOTS / "urdf" / "box.urdf"}"'
        )
    )
    assert main(["run", str(path), "--duration", "0.01", "--contacts", "held", "--quiet"]) == 5
    err = capsys.readouterr().err
    assert "sticking contacts cannot hold" in err and "front-left" in err and "Traceback" not in err


def test_bundled_box_scene_is_the_one_tested_here():
    """``box-push`` (robots/box-push.toml) gives the forces of the box checked above."""
    bundled, _, _ = contact_forces(load_scene("box-push"))
    np.testing.assert_allclose(bundled, contact_forces(box_scene())[0], atol=1e-12)


def test_frictionless_contacts_let_the_box_slide_and_lift():
    """Unilateral rows: no friction, so a 1 N push accelerates the box at F / m while the normal forces
    still carry m g; a 15 N lift (> m g) opens every contact (forces 0) and a_z = (15 - m g) / m."""
    forces, acceleration, _ = contact_forces(box_scene(mu=None))
    assert forces.shape == (4, 3) and np.allclose(forces[:, :2], 0.0)
    np.testing.assert_allclose(forces[:, 2].sum(), MASS * GRAVITY, atol=1e-9)
    assert np.all(forces[:, 2] >= 0)
    np.testing.assert_allclose(acceleration[:3], [1.0 / MASS, 0.0, 0.0], atol=1e-9)
    forces, acceleration, _ = contact_forces(box_scene(push=(0.0, 0.0, 15.0), mu=None))
    assert np.abs(forces).max() < 1e-9
    np.testing.assert_allclose(acceleration[:3], [0.0, 0.0, (15.0 - MASS * GRAVITY) / MASS], atol=1e-9)


@pytest.mark.parametrize("method", ["baumgarte", "projection", "post"])
def test_frictionless_box_lifts_off_as_a_free_body(method):
    """A 15 N lift at the centre: the contacts open and stay open (no method pulls the box back to
    the table), and the height follows z0 + a t^2 / 2 with a = (15 - m g) / m."""
    traj = simulate(box_scene(push=(0.0, 0.0, 15.0), mu=None), method=method, dt=1e-3, duration=0.2, contacts="held")
    expected = 0.025 + 0.5 * (15.0 - MASS * GRAVITY) / MASS * traj.t**2
    np.testing.assert_allclose(traj.q[:, 2], expected, rtol=0, atol=1e-9)
    assert np.abs(traj.multipliers[:-1]).max() < 1e-9
    assert traj.position_drift.max() == 0.0  # open unilateral rows are no violation


@pytest.mark.parametrize("solver", ["dense", "pinocchio"])
def test_solvers_without_inequalities_refuse_naming_those_that_have_them(solver):
    with pytest.raises(
        SolverError, match=r"does not take cone rows \(constraints c0, c1, c2, c3\); solvers that do: proxsuite"
    ):
        simulate(box_scene(), solver=solver, duration=0.01, contacts="held")

"""Integrators on the Lie group: a free-flying body with a hinged arm (SE(3) root)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import DATA
from pinstab import PinstabError, build_system, simulate
from pinstab.scene import scene_from_dict


def floating_scene(data_dir):
    return scene_from_dict(
        {
            "robot": {"urdf": str(data_dir / "body.urdf"), "free_flyer": True},
            "gravity": [0.0, 0.0, 0.0],
            "initial": {"v": {"root_joint": [0.3, -0.1, 0.2, 1.0, 4.0, 0.5], "hinge": -2.0}},
        }
    )


def world_momentum(scene, q, v):
    """Spatial momentum about the world origin [kg m/s, kg m^2/s], from Pinocchio's CCRBA."""
    data = scene.model.createData()
    centroidal = pin.computeCentroidalMomentum(scene.model, data, q, v)
    return pin.SE3(np.eye(3), data.com[0]).act(centroidal).vector


def test_momentum_and_energy_are_conserved(data_dir):
    scene = floating_scene(data_dir)
    traj = simulate(scene, method="none", integrator="rk4", dt=1e-3, duration=2.0)
    start, end = world_momentum(scene, traj.q[0], traj.v[0]), world_momentum(scene, traj.q[-1], traj.v[-1])
    np.testing.assert_allclose(end, start, atol=1e-9)
    assert np.ptp(traj.energy) < 1e-9


@pytest.mark.parametrize(("integrator", "order"), [("heun", 2), ("rk4", 4)])
def test_runge_kutta_keeps_its_order_on_se3(data_dir, integrator, order):
    """Self-convergence: e(dt) / e(dt/2) = 2^order with e the distance to a run at dt/8."""
    scene = floating_scene(data_dir)
    finals = {}
    for dt in (8e-3, 4e-3, 1e-3):
        traj = simulate(scene, method="none", integrator=integrator, dt=dt, duration=0.4)
        finals[dt] = traj.q[-1]
    errors = [np.linalg.norm(pin.difference(scene.model, finals[1e-3], finals[dt])) for dt in (8e-3, 4e-3)]
    measured = np.log2(errors[0] / errors[1])
    assert abs(measured - order) < 0.35, f"{integrator}: observed order {measured:.2f}"


def test_unknown_integrator_lists_the_valid_ones():
    with pytest.raises(
        PinstabError,
        match="unknown integrator 'rk5'; valid integrators: dop853, dopri5, esdirk4, euler, heun, implicit-euler, "
        "implicit-midpoint, rk4, semi-implicit-euler",
    ):
        simulate("fourbar", integrator="rk5", duration=0.01)


def test_unknown_method_and_solver_list_the_valid_ones():
    with pytest.raises(PinstabError, match="valid methods: baumgarte, mukharlyamov, none, pinocchio, post, projection"):
        simulate("fourbar", method="gear", duration=0.01)
    with pytest.raises(PinstabError, match="valid solvers: dense, extended, pinocchio, proxsuite"):
        simulate("fourbar", solver="mumps", duration=0.01)
    with pytest.raises(
        PinstabError,
        match="method 'projection' takes no option 'kp'.*applies to methods baumgarte, mukharlyamov, pinocchio",
    ):
        build_system(scene_from_dict({"robot": {"urdf": str(DATA / "body.urdf")}}), "projection", None, kp=1.0)

"""User-defined holonomic and Pfaffian constraints against closed forms.

* Planar pendulum as a free point mass with phi = x^2 + y^2 - l^2 [MLS ex. 6.1]. With
  x = l sin(theta), y = -l cos(theta), the reaction is grad(phi) lambda = 2 lambda (x, y), and the
  radial equation m l thetadot^2 = T - m g cos(theta) with tension T = -2 lambda l gives
  lambda = -m (l thetadot^2 + g cos(theta)) / (2 l); energy gives
  thetadot^2 = thetadot0^2 + 2 g (cos(theta) - cos(theta0)) / l, hence
  lambda(theta) = -m (l thetadot0^2 + 3 g cos(theta) - 2 g cos(theta0)) / (2 l).
* Knife edge (nonholonomic): -sin(th) xdot + cos(th) ydot = 0 with no forces: theta turns at the
  constant rate w, the speed s along the heading is constant, so x = x0 + s/w (sin(th) - sin(th0)),
  y = y0 - s/w (cos(th) - cos(th0)), and the lateral reaction is the centripetal force m s w.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import pendulum_scene
from pinstab import PfaffianConstraint, simulate
from pinstab.scene import scene_from_dict

MASS, LENGTH, GRAVITY = 2.0, 0.8, 9.81
PENDULUM_START = {"q": {"x": LENGTH * np.sin(0.9), "y": -LENGTH * np.cos(0.9)}, "v": {"x": 0.5}}


@pytest.mark.parametrize("method", ["baumgarte", "projection"])
def test_pendulum_multiplier_matches_closed_form(method):
    traj = simulate(
        pendulum_scene(LENGTH, GRAVITY, PENDULUM_START), method=method, integrator="rk4", dt=1e-3, duration=2.0
    )
    theta = np.arctan2(traj.q[:, 0], -traj.q[:, 1])
    x, y = traj.q[0]
    vx, vy = traj.v[0]
    theta_rate0 = (x * vy - y * vx) / LENGTH**2
    expected = (
        -MASS * (LENGTH * theta_rate0**2 + 3 * GRAVITY * np.cos(theta) - 2 * GRAVITY * np.cos(theta[0])) / (2 * LENGTH)
    )
    multiplier = traj.multipliers_of("rod")[:, 0]
    # the carriage's 1e-9 kg and rk4 error at dt = 1e-3 keep the match well inside 1e-6 N
    np.testing.assert_allclose(multiplier, expected, atol=1e-6)
    assert np.ptp(multiplier) > 1.0  # the tension really varies along the swing


def knife_edge_scene(data_dir):
    scene = scene_from_dict(
        {
            "robot": {"urdf": str(data_dir / "knife_edge.urdf")},
            "gravity": [0.0, 0.0, -9.81],
            "initial": {"q": {"x": 0.1, "y": -0.2, "theta": 0.3}, "v": {"x": 1.0, "y": 0.7, "theta": 1.5}},
        },
        name="knife-edge",
    )
    scene.add_constraint(
        PfaffianConstraint(
            "blade",
            1,
            matrix=lambda q, t: np.array([[-np.sin(q[2]), np.cos(q[2]), 0.0]]),
            drift=lambda q, v, t: np.array([-v[2] * (np.cos(q[2]) * v[0] + np.sin(q[2]) * v[1])]),
            nv=3,
        )
    )
    return scene


def test_knife_edge_follows_its_circle(data_dir):
    traj = simulate(knife_edge_scene(data_dir), method="baumgarte", integrator="rk4", dt=1e-3, duration=3.0)
    x0, y0, th0 = traj.q[0]
    vx0, vy0, w = traj.v[0]
    speed = np.cos(th0) * vx0 + np.sin(th0) * vy0
    th = th0 + w * traj.t
    np.testing.assert_allclose(traj.q[:, 2], th, atol=1e-9)
    np.testing.assert_allclose(traj.q[:, 0], x0 + speed / w * (np.sin(th) - np.sin(th0)), atol=1e-8)
    np.testing.assert_allclose(traj.q[:, 1], y0 - speed / w * (np.cos(th) - np.cos(th0)), atol=1e-8)
    # reaction along the blade normal n = (-sin, cos): its magnitude is the centripetal force m s w
    np.testing.assert_allclose(traj.multipliers_of("blade")[:, 0], 3.0 * speed * w, rtol=1e-7)
    assert traj.velocity_drift.max() < 1e-10

"""The IFToMM N-four-bar against its minimal model, through its singular configurations.

All cranks stay parallel (every loop is a parallelogram), so with the crank angle th measured from
the vertical: kinetic energy 1/2 I th'^2 with I = (N+1) m L^2 / 3 + N m L^2 (cranks rotate about
their pins, couplers translate), potential V = m g L cos(th) ((N+1)/2 + N), hence
th'' = m g L ((N+1)/2 + N) sin(th) / I. Starting upright at th' = -1 rad/s, the cranks pass
th = -pi/2, -3pi/2, ... where all links are aligned and G loses rank.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pinstab import load_scene, simulate

N, MASS, LENGTH, GRAVITY = 5, 1.0, 1.0, 9.81


def parallelogram_angle(times):
    inertia = (N + 1) * MASS * LENGTH**2 / 3 + N * MASS * LENGTH**2
    torque = MASS * GRAVITY * LENGTH * ((N + 1) / 2 + N)
    solution = solve_ivp(
        lambda t, y: [y[1], torque * np.sin(y[0]) / inertia],
        (0, times[-1]),
        [0.0, -1.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=times,
    )
    return solution.y[0]


@pytest.mark.parametrize(
    ("method", "solver"), [("baumgarte", "proxsuite"), ("projection", "proxsuite"), ("pinocchio", "pinocchio")]
)
def test_cranks_follow_the_parallelogram_pendulum(method, solver):
    scene = load_scene("nfourbar", N=N)
    traj = simulate(scene, method=method, solver=solver, dt=1e-3, duration=2.5)
    expected = parallelogram_angle(traj.t)
    assert expected.min() < -3 * np.pi / 2  # at least two singular crossings
    cranks = [scene.model.joints[scene.model.getJointId(f"crank{k}_joint")].idx_q for k in range(N + 1)]
    for index in cranks:
        np.testing.assert_allclose(traj.q[:, index], expected, atol=1e-7)
    assert traj.position_drift.max() < 1e-9

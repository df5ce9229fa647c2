"""Rules the compiled core and Python share, computed once in C++: an external force's J^T w (cpp/grasp_forces.cpp
add_wrench) against Pinocchio's own frame Jacobian, and the servo solve up to the controls (cpp/servo_kernel.cpp
ServoParts) against the equations it solves."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab.actuation import Actuation
from pinstab.forces.external_force import ExternalForce
from pinstab.kernels import least_norm, servo_parts, wrench_force
from pinstab.kinematics import Kinematics
from pinstab.servo import ServoSolver


def test_external_force_is_pinocchios_jacobian_transpose():
    """tau = J^T w with J from pin.computeFrameJacobian in LOCAL_WORLD_ALIGNED, to 1e-12, for frames along the arm."""
    model = pin.buildSampleModelManipulator()
    rng = np.random.default_rng(7)
    kin = Kinematics(model)
    for _ in range(3):
        q = pin.randomConfiguration(model)
        v = rng.normal(size=model.nv)
        kin.update(q, v)
        reference = model.createData()
        for frame in range(1, model.nframes, 3):
            wrench = rng.normal(size=6) * [10.0, 20.0, 5.0, 1.0, 2.0, 0.5]
            jacobian = pin.computeFrameJacobian(model, reference, q, frame, pin.LOCAL_WORLD_ALIGNED)
            element = ExternalForce("push", frame, wrench[:3], wrench[3:])
            np.testing.assert_allclose(
                element.generalized_force(kin, v, 0.0), jacobian.T @ wrench, rtol=0, atol=1e-12, err_msg=f"{frame}"
            )


def test_wrench_force_refuses_a_frame_outside_the_model():
    model = pin.buildSampleModelManipulator()
    data = model.createData()
    with pytest.raises(ValueError, match="no frame"):
        wrench_force(model, data, model.nframes, np.zeros(6))


def random_problem(nv: int, real: int, prescribed: int, controls: int, seed: int) -> tuple:
    rng = np.random.default_rng(seed)
    root = rng.normal(size=(nv, nv))
    mass = root @ root.T + nv * np.eye(nv)
    return (
        mass,
        rng.normal(size=nv),
        rng.normal(size=(real, nv)),
        rng.normal(size=(prescribed, nv)),
        rng.normal(size=(nv, controls)),
        rng.normal(size=real),
        rng.normal(size=prescribed),
    )


@pytest.mark.parametrize("real", [0, 2, 3])
def test_servo_parts_solve_the_servo_equations(real):
    """With u = least_norm(D, demand): M a - G^T lambda - B u = f, G a = rhs_G, S a = rhs_S to 1e-12 (relative), and
    a, lambda equal the closed form through the explicit M^-1 and (G M^-1 G^T)^-1 to 1e-11."""
    mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs = random_problem(7, real, 2, 3, seed=real)
    parts = servo_parts(mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs)
    controls = least_norm(parts.decoupling, parts.demand)
    a, reactions = parts.finish(controls)
    scale = np.abs(force).max() + np.abs(a).max()
    np.testing.assert_allclose(mass @ a - rows.T @ reactions - actuation @ controls, force, atol=1e-12 * scale)
    np.testing.assert_allclose(rows @ a, real_rhs, atol=1e-12 * scale)
    np.testing.assert_allclose(prescribed @ a, prescribed_rhs, atol=1e-12 * scale)
    inverse = np.linalg.inv(mass)
    gram = np.linalg.inv(rows @ inverse @ rows.T) if real else np.zeros((0, 0))
    allowed = inverse - inverse @ rows.T @ gram @ rows @ inverse
    np.testing.assert_allclose(parts.moved, allowed @ actuation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(parts.decoupling, prescribed @ allowed @ actuation, rtol=0, atol=1e-12)
    pushed = force + actuation @ controls
    expected = gram @ (real_rhs - rows @ inverse @ pushed)
    np.testing.assert_allclose(reactions, expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a, inverse @ (pushed + rows.T @ expected), rtol=0, atol=1e-11)


def test_servo_parts_drop_a_dependent_real_row():
    """A real row repeated: (G M^-1 G^T)^+ (numpy's pinv rule) gives the same motion as the row once."""
    mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs = random_problem(6, 2, 1, 2, seed=11)
    twice = np.vstack([rows, rows[:1]])
    once = servo_parts(mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs)
    doubled = servo_parts(mass, force, twice, prescribed, actuation, np.append(real_rhs, real_rhs[0]), prescribed_rhs)
    np.testing.assert_allclose(doubled.moved, once.moved, rtol=0, atol=1e-10)
    np.testing.assert_allclose(doubled.base, once.base, rtol=0, atol=1e-10)


def test_servo_parts_reactions_are_the_least_norm_ones_of_the_shared_pseudo_inverse():
    """Real rows with a dependent one (the third the sum of the first two, rhs consistent): the servo's reactions at
    u = 0 are numpy's pinv(G M^-1 G^T, rcond=1e-12) (rhs_G - G M^-1 f) to 1e-12 relative, the least-norm reactions of
    the Delassus pseudo-inverse the core solve takes too (cpp/kkt_solve.hpp DelassusPseudoInverse), and they meet
    M a - G^T lambda = f, G a = rhs_G."""
    mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs = random_problem(6, 2, 1, 2, seed=3)
    rows = np.vstack([rows, rows[0] + rows[1]])
    real_rhs = np.append(real_rhs, real_rhs[0] + real_rhs[1])
    parts = servo_parts(mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs)
    spread = np.linalg.solve(mass, rows.T)
    expected = np.linalg.pinv(rows @ spread, rcond=1e-12) @ (real_rhs - rows @ np.linalg.solve(mass, force))
    scale = np.abs(expected).max()
    np.testing.assert_allclose(parts.base_multipliers, expected, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(mass @ parts.base - rows.T @ parts.base_multipliers, force, atol=1e-12 * scale)
    np.testing.assert_allclose(rows @ parts.base, real_rhs, atol=1e-12 * (1 + np.abs(real_rhs).max()))


def test_servo_solver_takes_the_qp_within_limits():
    """Limits that the least-norm controls break: the ServoSolver's QP controls stay within them and the solution
    still meets M a - G^T lambda - B u = f, G a = rhs_G, S a = rhs_S (the compiled parts' finish)."""
    mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs = random_problem(6, 1, 1, 3, seed=5)
    parts = servo_parts(mass, force, rows, prescribed, actuation, real_rhs, prescribed_rhs)
    least = least_norm(parts.decoupling, parts.demand)
    smallest = abs(parts.demand[0]) / np.abs(parts.decoupling).sum()  # the least max |u_i| with D u = demand
    assert smallest < np.abs(least).max()
    bound = 0.5 * (smallest + np.abs(least).max())
    limits = Actuation(actuation, ("u0", "u1", "u2"), np.full(3, -bound), np.full(3, bound))
    solver = ServoSolver(np.array([False, True]), ("real", "servo"), limits)
    jacobian = np.vstack([rows, prescribed])
    rhs = np.concatenate([real_rhs, prescribed_rhs])
    solution = solver.solve(mass, force, jacobian, rhs, (0.0, np.zeros(6), np.zeros(6)))
    assert np.all(np.abs(solution.controls) <= bound * (1 + 1e-9))
    a, reactions = solution.acceleration, solution.multipliers[:1]
    residual = mass @ a - rows.T @ reactions - actuation @ solution.controls - force
    np.testing.assert_allclose(residual, 0.0, atol=1e-9)
    np.testing.assert_allclose(jacobian @ a, rhs, atol=1e-8)

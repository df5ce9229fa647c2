"""TargetTrajectory.evaluate runs the compiled form in C++ (cpp/targets.cpp, one bound object per trajectory): each
built-in kind against its closed form and SciPy's own spline derivatives; a kind without a compiled form overrides
evaluate in Python, and a joint relation on it goes through the compiled relation row with its values."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.interpolate import CubicSpline

from pinstab.constraints.joint_relation import JointRelation
from pinstab.constraints.targets import TargetContext, TargetTrajectory, read_trajectory
from pinstab.errors import SceneError
from pinstab.kinematics import Kinematics

POINT = TargetContext(3, "coordinate", np.zeros(3))
SCALAR = TargetContext(1, "coordinate", np.array([0.4]))


def evaluate(table: dict, context: TargetContext, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return read_trajectory(table, context, "target").evaluate(t)


def test_evaluate_is_one_compiled_object_per_trajectory():
    """The bound evaluator is built once (cached) and gives all components at once, arrays of ``size``."""
    trajectory = read_trajectory({"kind": "sinusoid", "amplitude": [0.1, 0.2, 0.3], "omega": 2.0}, POINT, "t")
    first = trajectory.evaluate(0.3)
    assert trajectory.compiled_target is trajectory.compiled_target
    assert all(part.shape == (3,) for part in first)


def test_polynomial_against_its_closed_form():
    """x = c0 + c1 t + c2 t^2 + c3 t^3 per component, its two derivatives, to 1e-12 relative."""
    coefficients = np.array([[0.1, -0.2, 0.3], [1.5, 0.0, -2.0], [-0.7, 0.25, 0.0], [0.05, -0.3, 0.125]])
    trajectory = read_trajectory({"kind": "polynomial", "coefficients": coefficients.tolist()}, POINT, "p")
    for t in [-1.3, 0.0, 0.7, 2.9]:
        powers = np.array([1.0, t, t * t, t**3])
        x, v, a = trajectory.evaluate(t)
        np.testing.assert_allclose(x, powers @ coefficients, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(v, np.array([0.0, 1.0, 2 * t, 3 * t * t]) @ coefficients, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(a, np.array([0.0, 0.0, 2.0, 6 * t]) @ coefficients, rtol=1e-12, atol=1e-14)


def test_sinusoid_against_its_closed_form():
    table = {"kind": "sinusoid", "amplitude": 0.3, "omega": 2.5, "phase": 0.4, "offset": -0.2}
    for t in [0.0, 0.37, 1.9, 12.0]:
        x, v, a = evaluate(table, SCALAR, t)
        angle = 2.5 * t + 0.4
        np.testing.assert_allclose(
            [x[0], v[0], a[0]],
            [-0.2 + 0.3 * np.sin(angle), 0.75 * np.cos(angle), -1.875 * np.sin(angle)],
            rtol=0,
            atol=1e-14,
        )


def test_minimum_jerk_against_the_quintic_and_held_outside():
    """x = x0 + dx (10 s^3 - 15 s^4 + 6 s^5), s = (t - start) / T, with dx/dt and d2x/dt2 of the quintic, to 1e-12;
    x0 with zero derivatives before the move, x0 + dx after it."""
    start, duration, origin, goal = 0.5, 1.5, 0.2, -0.7
    table = {"kind": "minimum-jerk", "from": origin, "to": goal, "start": start, "duration": duration}
    change = goal - origin
    for s in [0.0, 0.1, 0.33, 0.5, 0.8, 1.0]:
        x, v, a = evaluate(table, SCALAR, start + s * duration)
        expected = [
            origin + change * (10 * s**3 - 15 * s**4 + 6 * s**5),
            change * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration,
            change * (60 * s - 180 * s**2 + 120 * s**3) / duration**2,
        ]
        np.testing.assert_allclose([x[0], v[0], a[0]], expected, rtol=0, atol=1e-12, err_msg=f"s = {s}")
    for t, held in [(-3.0, origin), (0.4999, origin), (2.0001, goal), (50.0, goal)]:
        x, v, a = evaluate(table, SCALAR, t)
        np.testing.assert_allclose([x[0], v[0], a[0]], [held, 0.0, 0.0], rtol=0, atol=1e-14, err_msg=f"t = {t}")


@pytest.mark.parametrize("ends", ["clamped", "natural"])
def test_spline_against_scipy_and_held_outside(ends):
    """Inside the waypoints: SciPy's CubicSpline and its own first and second derivatives, to 1e-12; outside: the
    end values with zero derivatives."""
    times, values = [0.3, 1.0, 1.4, 2.2], [0.0, 0.5, -0.1, 0.2]
    table = {"kind": "cubic-spline", "times": times, "values": values, "ends": ends}
    reference = CubicSpline(times, values, bc_type=ends)
    for t in [0.3, 0.45, 0.99, 1.0, 1.2, 1.9, 2.2]:
        x, v, a = evaluate(table, SCALAR, t)
        expected = [reference(t), reference(t, 1), reference(t, 2)]
        np.testing.assert_allclose([x[0], v[0], a[0]], expected, rtol=0, atol=1e-12, err_msg=f"t = {t}")
    for t, held in [(0.0, values[0]), (0.2999, values[0]), (2.2001, values[-1]), (9.0, values[-1])]:
        x, v, a = evaluate(table, SCALAR, t)
        np.testing.assert_allclose([x[0], v[0], a[0]], [held, 0.0, 0.0], rtol=0, atol=1e-12, err_msg=f"t = {t}")


class Ramp(TargetTrajectory):
    """A user's kind without a compiled form: x = 0.3 + 0.2 t^3 /3 (a Python evaluate)."""

    size = 1

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.array([0.3 + 0.2 * t**3 / 3]), np.array([0.2 * t * t]), np.array([0.4 * t])


class Forgotten(TargetTrajectory):
    """A kind with neither a compiled form nor an evaluate."""

    size = 1


def test_a_kind_without_a_compiled_form_evaluates_in_python_and_its_relation_row_in_cpp():
    """The relation row on Ramp (its Python values handed to the compiled row): phi = 2 q1 - q0 - c(t), G = (-1, 2),
    g_t = -c'(t), gamma0 = -c''(t), exactly (the same arithmetic as the compiled row on the polynomial it is)."""
    model = pin.buildSampleModelManipulator()
    kin = Kinematics(model)
    relation = JointRelation("ramp", np.array([-1.0, 2.0]), np.array([0, 1]), np.array([0, 1]), Ramp())
    assert relation.compiled_rows() is None
    q = np.linspace(0.1, 0.6, model.nq)
    v = np.linspace(-0.2, 0.3, model.nv)
    kin.update(q, v)
    for t in [0.0, 0.7, 1.3]:
        value, rate, curvature = (float(x[0]) for x in Ramp().evaluate(t))
        assert relation.residual(kin, q, t)[0] == pytest.approx(2 * q[1] - q[0] - value, abs=1e-15)
        terms = relation.velocity_terms(kin, q, t)
        expected = np.zeros((1, model.nv))
        expected[0, :2] = [-1.0, 2.0]
        np.testing.assert_array_equal(terms.jacobian, expected)
        assert terms.time_term[0] == -rate
        assert relation.drift(kin, q, v, t)[0] == -curvature


def test_a_kind_with_neither_is_named():
    with pytest.raises(SceneError, match="Forgotten.*no compiled form.*evaluate"):
        Forgotten().evaluate(0.0)

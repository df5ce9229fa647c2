"""The servo decision rules shared by the compiled servo kernel (cpp/servo_kernel.cpp) and the general solve
(pinstab.servo.ServoSolver), each written once in C++: D's sign change since the last usable evaluation
(servo_realizability) and the controls' bounds (controls_within, which refuses NaN). Both paths are driven through the
same states of the double pendulum with the coupling joint1 + 0.55 joint2 = 0 realized by the elbow, whose
decoupling D = S M^-1 B vanishes at q2* (tests/test_servo.py's singular_elbow_angle) and changes sign there."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_servo import singular_elbow_angle

from pinstab import Actuation, load_scene
from pinstab.constraints.joint_relation import JointRelation
from pinstab.constraints.targets import TargetContext, read_trajectory
from pinstab.errors import ServoInfeasibleError
from pinstab.kernels import controls_within
from pinstab.paths.servo import ServoDynamics
from pinstab.servo import RANK_TOLERANCE, ServoSolver

ROW = np.array([1.0, 0.55])  # S
PUSH = np.array([0.0, 1.0])  # B: the elbow
STILL = np.zeros(2)


def _actuation(bound: float = np.inf) -> Actuation:
    return Actuation(PUSH[:, None], ("joint2",), np.array([-bound]), np.array([bound]))


def _paths(bound: float = np.inf) -> tuple[ServoDynamics, ServoSolver]:
    """The compiled kernel and the general solve of the coupling (held at 0, no corrector) under |u| <= bound [N m]."""
    model = load_scene("double-pendulum-servo").model
    trajectory = read_trajectory(
        {"kind": "polynomial", "coefficients": [0.0]}, TargetContext(1, "coordinate", np.zeros(1)), "coupling"
    )
    relation = JointRelation("coupling", ROW, np.array([0, 1]), np.array([0, 1]), trajectory)
    kernel = ServoDynamics(model, [relation], _actuation(bound), 0.0, 0.0, RANK_TOLERANCE)
    return kernel, ServoSolver(np.array([True]), ("coupling",), _actuation(bound))


def _dynamics(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M [kg m^2], f = -h [N m]) at rest at q, from Pinocchio."""
    model = load_scene("double-pendulum-servo").model
    data = model.createData()
    mass = pin.crba(model, data, q)
    return np.triu(mass) + np.triu(mass, 1).T, -pin.nonLinearEffects(model, data, q, STILL)


def _general(solver: ServoSolver, q: np.ndarray, t: float, force: np.ndarray | None = None) -> np.ndarray:
    mass, free = _dynamics(q)
    free = free if force is None else force
    return solver.solve(mass, free, ROW[None, :], np.zeros(1), (t, q, STILL)).acceleration


def _sides() -> tuple[np.ndarray, np.ndarray, float]:
    """(q before q2*, q beyond it, sign of D = S M^-1 B before it, from numpy's solve)."""
    q2 = singular_elbow_angle()
    before, beyond = np.array([0.0, q2 - 0.3]), np.array([0.0, q2 + 0.3])
    signs = [np.sign(ROW @ np.linalg.solve(_dynamics(q)[0], PUSH)) for q in (before, beyond)]
    assert signs[0] == -signs[1] != 0.0  # the scene's D changes sign between the two states
    return before, beyond, float(signs[0])


def test_a_sign_change_is_refused_by_both_paths_and_not_remembered():
    """Beyond q2* after a usable evaluation before it: the kernel refuses the evaluation and keeps the earlier
    (time, sign); the general solve, following the kernel, raises naming the earlier time. The refused state is no
    reference: back before q2* both paths solve again, the same accelerations to 1e-12 (relative)."""
    before, beyond, sign = _sides()
    kernel, solver = _paths()
    kernel.acceleration(before, STILL, np.zeros(2), 0.1)
    assert not kernel.unusable and kernel.last_sign == (0.1, sign)
    kernel.acceleration(beyond, STILL, np.zeros(2), 0.2)
    assert kernel.unusable and kernel.last_sign == (0.1, sign)
    solver.follow(kernel.last_sign)
    with pytest.raises(ServoInfeasibleError, match=r"its determinant changed sign since t = 0\.1 s") as info:
        _general(solver, beyond, 0.2)
    assert info.value.time == 0.2 and info.value.constraints == ["coupling"]
    compiled = kernel.acceleration(before, STILL, np.zeros(2), 0.3)
    assert not kernel.unusable and kernel.last_sign == (0.3, sign)
    np.testing.assert_allclose(_general(solver, before, 0.3), compiled, rtol=1e-12)


def test_a_control_beyond_its_bound_is_refused_by_both_paths():
    """Before q2* the coupling needs u = -S M^-1 f / (S M^-1 B) (numpy); bounded by half of |u| the kernel refuses
    the evaluation and the general solve raises naming the control and its bound; bounded by twice |u| both solve."""
    before, _, _ = _sides()
    mass, free = _dynamics(before)
    needed = -(ROW @ np.linalg.solve(mass, free)) / (ROW @ np.linalg.solve(mass, PUSH))
    kernel, solver = _paths(0.5 * abs(needed))
    kernel.acceleration(before, STILL, np.zeros(2), 0.0)
    assert kernel.unusable
    with pytest.raises(ServoInfeasibleError, match=r"within the control limits: it needs joint2 = -?\d"):
        _general(solver, before, 0.0)
    kernel, solver = _paths(2.0 * abs(needed))
    compiled = kernel.acceleration(before, STILL, np.zeros(2), 0.0)
    assert not kernel.unusable
    np.testing.assert_allclose(_general(solver, before, 0.0), compiled, rtol=1e-12)


def test_a_nan_control_is_refused_by_both_paths():
    """A NaN applied force makes the least-norm control NaN: unbounded, the kernel refuses the evaluation and the
    general solve raises naming the control (before: NaN controls and accelerations returned)."""
    before, _, _ = _sides()
    kernel, solver = _paths()
    kernel.acceleration(before, STILL, np.array([np.nan, 0.0]), 0.0)
    assert kernel.unusable
    with pytest.raises(ServoInfeasibleError, match=r"by finite controls: it needs joint2 = nan"):
        _general(solver, before, 0.0, force=np.array([np.nan, 0.0]))


@pytest.mark.parametrize(
    ("controls", "within"),
    [
        ([0.0, -2.0], True),
        ([2.0, 1e300], True),
        ([2.0 + 1e-15, 0.0], False),
        ([0.0, -np.inf], False),
        ([np.nan, 0.0], False),
        ([0.0, np.nan], False),
    ],
)
def test_controls_within_is_the_closed_box_and_refuses_nan(controls, within):
    """[-2, 2] x [-2, inf]: its boundary is inside, beyond it by an ulp is not, nor is NaN, with a bound or without."""
    assert controls_within(np.array(controls), np.array([-2.0, -2.0]), np.array([2.0, np.inf])) is within

"""The explicit schemes' steps, compiled (``cpp/stepping.cpp``, ``cpp/adaptive.cpp``) and called by the Python loops
with a Python evaluation per stage: each step against its closed form on a linear oscillator (the scheme's stability
polynomial of h A), a step on the group of a free flyer against Pinocchio's integrate and dDifference applied by hand,
the stages' indices and times, and the evaluation's exceptions reaching the caller unchanged."""

from __future__ import annotations

import gc
import math
import weakref
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import PinstabError
from pinstab.integration.schemes import INTEGRATORS, ExplicitRungeKutta
from pinstab.kernels import RungeKutta, SchemeStep
from pinstab.stability.regions import stability_polynomial

OMEGA, DAMPING = 3.0, 0.4  # a = -OMEGA^2 q - DAMPING v, coordinate by coordinate


def _oscillator(q, v, t, stage):
    return -(OMEGA**2) * q - DAMPING * v


def _system(acceleration=_oscillator, model=None):
    """What an integrator reads of a system: its acceleration and its model's group."""
    group = SimpleNamespace(euclidean=True) if model is None else SimpleNamespace(euclidean=False, model=model)
    return SimpleNamespace(acceleration=acceleration, model=group)


POLYNOMIALS = {
    "euler": (1.0, 1.0),
    "heun": (1.0, 1.0, 0.5),
    "rk4": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24),
}


@pytest.mark.parametrize("name", [*POLYNOMIALS, "dopri5", "dop853"])
def test_step_is_the_stability_polynomial_of_h_a(name):
    """On y' = A y (the damped oscillator, 3 coordinates) one step is p(h A) y: Euler 1 + z, Heun 1 + z + z^2 / 2, RK4
    the degree-4 Taylor polynomial, the tableaus b^T a^(k-1) 1 (the registry's, in rational arithmetic); to 1e-14
    relative."""
    stepper = INTEGRATORS.build(name, _system())
    coefficients = POLYNOMIALS.get(name) or stability_polynomial(stepper.coupling, stepper.weights)
    h = 0.05
    a = np.array([[0.0, 1.0], [-(OMEGA**2), -DAMPING]])
    amplification = sum(c * np.linalg.matrix_power(h * a, k) for k, c in enumerate(coefficients))
    q, v = np.array([0.3, -1.2, 2.0]), np.array([0.7, 0.1, -0.5])
    q1, v1 = stepper.step(q, v, 1.5, h)
    expected = amplification @ np.vstack((q, v))
    np.testing.assert_allclose(q1, expected[0], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(v1, expected[1], rtol=1e-14, atol=1e-15)


def test_semi_implicit_euler_moves_velocity_first():
    """v+ = v + h a(q, v), q+ = q + h v+, to the last bit (the same two operations)."""
    stepper = INTEGRATORS.build("semi-implicit-euler", _system())
    q, v, h = np.array([0.3, -1.2]), np.array([0.7, 0.1]), 0.01
    q1, v1 = stepper.step(q, v, 0.0, h)
    v_expected = v + h * _oscillator(q, v, 0.0, 0)
    np.testing.assert_array_equal(v1, v_expected)
    np.testing.assert_array_equal(q1, q + h * v_expected)


def _free_flyer() -> pin.Model:
    model = pin.Model()
    model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "body")
    model.addJoint(1, pin.JointModelRevoluteUnaligned(np.array([0.0, 0.6, 0.8])), pin.SE3.Identity(), "arm")
    return model


def test_heun_on_the_group_of_a_free_flyer():
    """Heun on a free flyer with a revolute arm: q+ = q (+) h/2 (v + dDifference(q, q2) v2) with q2 = q (+) h v,
    v2 = v + h a1, by Pinocchio's functions in NumPy, to 1e-14 (the stage slope carried to the start's tangent
    space); the evaluation sees the stages' configurations on the group (unit quaternions)."""
    model = _free_flyer()
    rng = np.random.default_rng(5)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    v = rng.normal(size=model.nv)
    seen = []

    def acceleration(q_, v_, t, stage):
        seen.append(np.linalg.norm(q_[3:7]))
        return np.sin(q_[: model.nv]) - 0.3 * v_ + t

    stepper = INTEGRATORS.build("heun", _system(acceleration, model))
    h, t = 0.02, 0.4
    q1, v1 = stepper.step(q, v, t, h)
    a1 = acceleration(q, v, t, 0)
    q2, v2 = pin.integrate(model, q, h * v), v + h * a1
    a2 = acceleration(q2, v2, t + h, 1)
    slope = pin.dDifference(model, q, q2, pin.ArgumentPosition.ARG1) @ v2
    np.testing.assert_allclose(q1, pin.integrate(model, q, 0.5 * h * (v + slope)), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(v1, v + 0.5 * h * (a1 + a2), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(seen, 1.0, rtol=1e-14)


@pytest.mark.parametrize("name", ["rk4", "dop853"])
def test_stages_get_their_index_and_node(name):
    """Stage i is evaluated at t + c_i h with its index (RK4: 0, 1/2, 1/2, 1; DOP853: its nodes), and with ``end``
    the new point once more as stage 0."""
    calls = []

    def acceleration(q, v, t, stage):
        calls.append((stage, t))
        return -q

    stepper = INTEGRATORS.build(name, _system(acceleration))
    t, h = 2.0, 0.125
    stepper.step(np.ones(2), np.zeros(2), t, h)
    assert calls == [(i, t + c * h) for i, c in enumerate(stepper.nodes)]
    if isinstance(stepper, ExplicitRungeKutta):
        calls.clear()
        _, _, slopes, end = stepper.attempt(np.ones(2), np.zeros(2), t, h, first=np.full(2, -1.0), end=True)
        assert calls == [(i, t + c * h) for i, c in enumerate(stepper.nodes)][1:] + [(0, t + h)]
        assert slopes.shape == (stepper.stages, 4) and end.shape == (4,)


class Refused(PinstabError):
    """Raised by an evaluation."""


@pytest.mark.parametrize("name", ["euler", "heun", "rk4", "dopri5"])
def test_an_exception_in_a_stage_reaches_the_caller_unchanged(name):
    """A PinstabError raised by the evaluation at the last stage propagates through the compiled step: the same
    object, its traceback through the callback."""
    raised = Refused("no solve at this stage")
    stepper = INTEGRATORS.build(name, _system())
    last = stepper.stages - 1

    def acceleration(q, v, t, stage):
        if stage == last:
            raise raised
        return -q

    stepper.system.acceleration = acceleration
    with pytest.raises(Refused) as caught:
        stepper.step(np.ones(2), np.zeros(2), 0.0, 0.1)
    assert caught.value is raised
    assert caught.traceback[-1].name == "acceleration"


def test_an_acceleration_of_another_size_or_a_state_of_mixed_sizes_is_refused():
    """An evaluation returning nv + 1 entries, or q and v of different sizes, raise ValueError (no step of
    garbage)."""
    with pytest.raises(ValueError, match="entries"):
        SchemeStep(3, None).step(lambda q, v, t, stage: np.zeros(3), np.zeros(2), np.zeros(2), 0.0, 0.1)
    with pytest.raises(ValueError, match="sizes"):
        SchemeStep(0, None).step(_oscillator, np.zeros(2), np.zeros(3), 0.0, 0.1)
    with pytest.raises(ValueError):
        SchemeStep(4, None)
    with pytest.raises(ValueError, match="sizes"):
        RungeKutta(np.zeros(1), np.zeros((1, 1)), np.ones(1), _free_flyer()).attempt(
            _oscillator, np.zeros(6), np.zeros(7), 0.0, 0.1
        )


def test_the_step_keeps_no_reference_to_the_evaluation():
    """The compiled step holds the callable only during the call: an evaluation object (and what it refers to, e.g.
    its system) is freed once its last Python reference goes, with no garbage collection (no cycle through C++)."""

    class Evaluation:
        def __call__(self, q, v, t, stage):
            return -q

    evaluation = Evaluation()
    gone = weakref.ref(evaluation)
    stepper = INTEGRATORS.build("rk4", _system(evaluation))
    stepper.step(np.ones(2), np.zeros(2), 0.0, 0.1)
    del evaluation
    stepper.system.acceleration = None
    gc.disable()
    try:
        assert gone() is None
    finally:
        gc.enable()
    assert math.isfinite(stepper.nodes[-1])

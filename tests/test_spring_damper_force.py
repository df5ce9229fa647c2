"""The spring-damper's law is the compiled core's (``cpp/spring_damper.cpp``): its spring part against minus the
gradient of its energy by finite differences, its damping part against the closed form from Pinocchio's own frame
velocities, a point coinciding with the other refused, and a run with it on the core path (nothing in Python) against
the same run with the element evaluated in Python."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pinstab.paths.core
from conftest import coupler_spring, fourbar_dict
from pinstab import simulate
from pinstab.errors import SceneError
from pinstab.forces import SpringDamper
from pinstab.kernels import CoreKernel
from pinstab.kinematics import LWA, Kinematics
from pinstab.scene import scene_from_dict

STEP = 1e-6  # [rad] central differences: error ~ STEP^2 |V'''| + rounding |V| / STEP, ~1e-10 here


def _arm() -> tuple[pin.Model, int, int]:
    """Pinocchio's sample manipulator (six revolute joints, 3-D) with a point frame on its second link and one on its
    fifth, off their joint axes: both points move, in every direction."""
    model = pin.buildSampleModelManipulator()
    frames = []
    for joint, offset in ((2, [0.05, 0.1, 0.02]), (5, [0.08, -0.04, 0.11])):
        placement = pin.SE3(np.eye(3), np.array(offset))
        frames.append(model.addFrame(pin.Frame(f"point{joint}", joint, 0, placement, pin.FrameType.OP_FRAME)))
    return model, frames[0], frames[1]


def _state(model: pin.Model, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.5, 1.5, model.nv), rng.standard_normal(model.nv)


@pytest.mark.parametrize("world", [False, True], ids=["two-frames", "frame-to-world"])
def test_spring_part_is_minus_the_energy_gradient(world):
    """Damping zero: tau = -dV/dq, V = k (L - L0)^2 / 2, by central differences at three random states, to 1e-7 of
    |tau| (the differences' error is ~1e-10); the rate and the velocity play no part."""
    model, frame_a, frame_b = _arm()
    spring = SpringDamper("s", frame_a, None if world else frame_b, np.array([0.3, -0.2, 0.4]), 120.0, 0.0, 0.15)
    kin = Kinematics(model)
    for seed in range(3):
        q, v = _state(model, seed)
        kin.update_jacobians(q)
        force = spring.generalized_force(kin, v, 0.0)
        gradient = np.zeros(model.nv)
        for j in range(model.nv):
            energies = []
            for sign in (1.0, -1.0):
                kin.update_jacobians(q + sign * STEP * np.eye(model.nv)[j])
                energies.append(spring.potential_energy(kin))
            gradient[j] = (energies[0] - energies[1]) / (2 * STEP)
        assert np.abs(force).max() > 1.0  # a real force (the spring is stretched by tenths of a metre)
        np.testing.assert_allclose(force, -gradient, rtol=0, atol=1e-7 * np.abs(force).max())


def test_damping_part_is_the_closed_form():
    """Stiffness zero: dL/dt = u . (pdot_a - pdot_b) and tau . v = -c (dL/dt)^2 from Pinocchio's frame velocities
    (forwardKinematics with v, not the Jacobians the law uses), and tau = (J_a - J_b)^T F, F = -c dL/dt u, from
    computeFrameJacobian: 1e-12 relative."""
    model, frame_a, frame_b = _arm()
    damping = 3.5
    spring = SpringDamper("d", frame_a, frame_b, np.zeros(3), 0.0, damping, 0.2)
    kin = Kinematics(model)
    data = model.createData()
    for seed in range(3):
        q, v = _state(model, seed)
        kin.update_jacobians(q)
        length, rate, force = spring.terms(kin, v)
        pin.forwardKinematics(model, data, q, v)
        pin.updateFramePlacements(model, data)
        difference = data.oMf[frame_a].translation - data.oMf[frame_b].translation
        direction = difference / np.linalg.norm(difference)
        velocity = (
            pin.getFrameVelocity(model, data, frame_a, LWA).linear
            - pin.getFrameVelocity(model, data, frame_b, LWA).linear
        )
        expected_rate = float(direction @ velocity)
        assert abs(expected_rate) > 0.05
        assert length == pytest.approx(np.linalg.norm(difference), rel=1e-15)
        assert rate == pytest.approx(expected_rate, rel=1e-12)
        assert spring.power(kin, v, 0.0) == pytest.approx(-damping * expected_rate**2, rel=1e-12)
        assert float(force @ v) == pytest.approx(-damping * expected_rate**2, rel=1e-12)
        jacobian = (
            pin.computeFrameJacobian(model, data, q, frame_a, LWA)[:3]
            - pin.computeFrameJacobian(model, data, q, frame_b, LWA)[:3]
        )
        expected = jacobian.T @ (-damping * expected_rate * direction)
        np.testing.assert_allclose(force, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_coinciding_points_are_refused_unless_the_law_needs_no_direction():
    """Point a on the world point b (L = 0): with a rest length or damping the force's direction is not defined and
    the element refuses, naming itself and what would do, and the core kernel does not use the evaluation (the general
    path's, the element's, says why); a zero-rest-length spring without damping gives -k (p_a - p_b) = 0 there
    (exactly), in the kernel too (its acceleration M^-1 (-h) as Pinocchio's ABA's, to 1e-12)."""
    model, frame_a, _ = _arm()
    kin = Kinematics(model)
    q, v = _state(model, 0)
    kin.update_jacobians(q)
    anchor = kin.placement(frame_a).translation.copy()
    for stiffness, damping, rest in ((10.0, 0.0, 0.1), (10.0, 1.0, 0.0)):
        spring = SpringDamper("coil", frame_a, None, anchor, stiffness, damping, rest)
        with pytest.raises(
            SceneError, match=r"spring-damper 'coil': its points coincide .*rest_length = 0 and damping = 0"
        ):
            spring.generalized_force(kin, v, 0.0)
        assert spring.potential_energy(kin) == pytest.approx(0.5 * stiffness * rest**2, rel=1e-15)
        kernel = _kernel(model, spring)
        assert not kernel.acceleration(q, v, np.zeros(model.nv))[1]
        assert kernel.status_counts == {"spring-damper without a direction": 1}
    zero_rest = SpringDamper("coil", frame_a, None, anchor, 10.0, 0.0, 0.0)
    np.testing.assert_array_equal(zero_rest.generalized_force(kin, v, 0.0), np.zeros(model.nv))
    acceleration, usable = _kernel(model, zero_rest).acceleration(q, v, np.zeros(model.nv))
    assert usable
    expected = pin.aba(model, model.createData(), q, v, np.zeros(model.nv))
    np.testing.assert_allclose(acceleration, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def _kernel(model: pin.Model, spring: SpringDamper) -> CoreKernel:
    """A core kernel of no rows with the spring as its one force element."""
    settings = {"direct_pivot": 1e-12, "cutoff": 1e-12, "accepted": 1e-8, "margin_slack": 0.0}
    return CoreKernel(model, [], [spring.compiled_form({})], 0.0, np.zeros(0), False, settings)


def _fourbar_with_spring() -> object:
    return scene_from_dict(fourbar_dict(forces=[coupler_spring(40.0, 1.5, 0.3)]))


def test_a_run_on_the_core_computes_it_compiled_and_as_python_did(monkeypatch):
    """The four-bar with a stretched, damped coupler spring, 0.3 s of RK4 at 1 ms under Mukharlyamov's term (the
    core path: Pinocchio's solve takes Baumgarte's only): the spring is the kernel's (the path's reason names nothing
    evaluated in Python), and the trajectory equals the same run with the element evaluated in Python at every stage
    (CORE_FORCE_KINDS without it) to 1e-12."""
    options = dict(method="mukharlyamov", integrator="rk4", dt=1e-3, duration=0.3)
    compiled = simulate(_fourbar_with_spring(), **options)
    assert compiled.info.path == "core"
    assert "Python" not in compiled.info.path_reason
    monkeypatch.setattr(pinstab.paths.core, "CORE_FORCE_KINDS", ("joint-spring", "hold", "wrench"))
    in_python = simulate(_fourbar_with_spring(), **options)
    assert in_python.info.path == "core"
    assert in_python.info.path_reason.endswith("force(s) spring evaluated in Python")
    assert np.ptp(compiled.q[:, 0]) > 0.1  # the crank turns
    np.testing.assert_allclose(compiled.q, in_python.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.v, in_python.v, rtol=0, atol=1e-12)

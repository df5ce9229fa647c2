"""The frame form of joint-spring on the core rows (pinstab/forces/joint_spring.py: a prismatic block of
cpp/core_rows.cpp): its stiffness force against a central difference of its potential energy, and its damping force
against a central difference of its coordinate along the motion, with side b a body or the world."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_sdf import FRAME_SPRINGS, _spring_scene

from pinstab.kinematics import Kinematics

H = 1e-6  # central-difference step [rad, m]
SIDES = {"body": {"frame_b": "a"}, "world": {"offset_b": [0.1, -0.2, 0.3], "rpy_b": [0.2, 0.1, -0.3]}}


@pytest.mark.parametrize("side", SIDES)
@pytest.mark.parametrize("extra", FRAME_SPRINGS, ids=lambda e: e["motion"])
def test_frame_spring_is_its_energy_gradient_and_damps_its_rate(extra, side):
    """At 3 random states: Q(q, 0) = -dV/dq (central differences over pin.integrate, 1e-6) to 1e-6 N, and
    Q(q, v) - Q(q, 0) = -c (ds/dt) ds/dq with ds/dt and ds/dq by differences of the coordinate s, to 1e-6."""
    stiffness, damping = 40.0, 3.0
    entry = {"name": "s", "kind": "joint-spring", "frame_a": "b", **SIDES[side], **extra}
    entry.update(stiffness=stiffness, reference=0.05, damping=damping)
    scene = _spring_scene(entry)
    model, (spring,) = scene.model, scene.forces
    nv, kin = model.nv, Kinematics(model)
    rng = np.random.default_rng(17)

    def at(q: np.ndarray, what: str) -> float:
        kin.update(q, np.zeros(nv))
        return spring.potential_energy(kin) if what == "energy" else spring.coordinate(kin)[0]

    def difference(q: np.ndarray, step: np.ndarray, what: str) -> float:
        return (at(pin.integrate(model, q, H * step), what) - at(pin.integrate(model, q, -H * step), what)) / (2 * H)

    for _ in range(3):
        q = pin.integrate(model, pin.neutral(model), 0.5 * rng.standard_normal(nv))
        v = rng.standard_normal(nv)
        gradient = np.array([difference(q, e, "energy") for e in np.eye(nv)])
        slope = np.array([difference(q, e, "coordinate") for e in np.eye(nv)])
        kin.update(q, np.zeros(nv))
        static = spring.generalized_force(kin, np.zeros(nv), 0.0)
        assert np.abs(static).max() > 1e-2  # the spring is stretched: the check has a force to compare
        np.testing.assert_allclose(static, -gradient, rtol=0, atol=1e-6)
        kin.update(q, v)
        damping_force = spring.generalized_force(kin, v, 0.0) - static
        rate = difference(q, v, "coordinate")
        np.testing.assert_allclose(damping_force, -damping * rate * slope, rtol=0, atol=1e-6)

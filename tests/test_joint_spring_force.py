"""A joint spring's force in joint form is the core kernel's (cpp/core_kernel.cpp add_joint_springs): against the
closed form of its law."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pinstab.forces.joint_spring import JointSpring


def test_joint_form_is_the_closed_form():
    """-k (q - q_ref) - c qdot on a 1-DOF joint's coordinate, -c v on each coordinate of a ball (damping only), zero
    elsewhere, to 1e-15 relative; indices outside the state are refused."""
    q, v = np.array([0.3, 0.1, 0.2, 0.3, 0.9, -0.4]), np.array([1.5, -2.0, 0.5, 0.25, 3.0])
    hinge = JointSpring("hinge", 40.0, 0.1, 2.0, np.array([4]), q_index=5)
    expected = np.zeros(5)
    expected[4] = -40.0 * (-0.4 - 0.1) - 2.0 * 3.0
    np.testing.assert_allclose(hinge.generalized_force(SimpleNamespace(q=q), v, 0.0), expected, rtol=1e-15, atol=0)
    ball = JointSpring("ball", 0.0, 0.0, 0.5, np.array([1, 2, 3]))
    expected = np.zeros(5)
    expected[1:4] = -0.5 * v[1:4]
    np.testing.assert_allclose(ball.generalized_force(SimpleNamespace(q=q), v, 0.0), expected, rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match="outside q, v"):
        hinge.generalized_force(SimpleNamespace(q=q[:3]), v, 0.0)

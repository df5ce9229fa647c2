"""A joint torque's table is the compiled core's target (``cpp/targets.cpp``; the core kernel adds it,
``cpp/core_kernel.cpp`` add_joint_torques): against linear interpolation (NumPy's), and a run with the torques in the
kernel against the same run with them evaluated in Python."""

from __future__ import annotations

import numpy as np

import pinstab.paths.core
from pinstab import load_scene, simulate
from pinstab.forces import JointTorque


def test_table_is_linear_interpolation_held_at_its_ends():
    """At the table's times, between them and beyond both ends (held), and a constant (one point): NumPy's np.interp
    to 1e-15 of the largest torque."""
    times, values = np.array([0.0, 0.4, 1.0, 2.5, 3.0]), np.array([0.3, -1.2, 2.0, 2.0, -0.7])
    table = JointTorque("table", 1, 3, times, values)
    instants = np.concatenate([times, np.linspace(-1.0, 4.0, 101), [np.nextafter(2.5, 0.0), np.nextafter(3.0, 4.0)]])
    torques = np.array([table.torque(t) for t in instants])
    np.testing.assert_allclose(torques, np.interp(instants, times, values), rtol=0, atol=1e-15 * 2.0)
    force = table.generalized_force(None, np.zeros(3), 0.7)
    np.testing.assert_array_equal(force, [0.0, np.interp(0.7, times, values), 0.0])
    constant = JointTorque("constant", 0, 1, np.zeros(1), np.array([0.25]))
    assert [constant.torque(t) for t in (-3.0, 0.0, 7.5)] == [0.25, 0.25, 0.25]


def test_a_run_on_the_core_adds_them_compiled_and_as_python_did(monkeypatch):
    """finger-rolling (three joint torques, one a table, on the core path), 0.2 s: the torques are the kernel's (the
    path's reason names only its rolling rows as evaluated in Python), and the trajectory equals the same run with
    them evaluated in Python at every stage (CORE_FORCE_KINDS without them) to 1e-12."""
    compiled = simulate(load_scene("finger-rolling"), duration=0.2)
    assert compiled.info.path == "core"
    assert compiled.info.path_reason.endswith("constraint(s) tip, tip/rolling evaluated in Python")
    kinds = tuple(kind for kind in pinstab.paths.core.CORE_FORCE_KINDS if kind != "joint-torque")
    monkeypatch.setattr(pinstab.paths.core, "CORE_FORCE_KINDS", kinds)
    in_python = simulate(load_scene("finger-rolling"), duration=0.2)
    assert in_python.info.path_reason.endswith("force(s) sweep, upper, lower evaluated in Python")
    assert np.ptp(compiled.q[:, 0]) > 1e-3  # the sweep moves the base joint
    np.testing.assert_allclose(compiled.q, in_python.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.v, in_python.v, rtol=0, atol=1e-12)

"""Force elements: spring force is minus the gradient of its energy; work-energy balances."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import coupler_spring, fourbar_dict, random_configuration
from pinstab import load_scene, simulate
from pinstab.forces import JointTorque
from pinstab.kinematics import Kinematics
from pinstab.scene import scene_from_dict


def spring_scene(stiffness=40.0, damping=0.0, rest=0.3):
    return scene_from_dict(fourbar_dict(forces=[coupler_spring(stiffness, damping, rest)]))


def test_spring_force_is_minus_energy_gradient():
    scene = spring_scene()
    spring = scene.forces[0]
    kin = Kinematics(scene.model)
    q = random_configuration(scene.model, np.random.default_rng(7))
    kin.update(q, np.zeros(scene.model.nv))
    force = spring.generalized_force(kin, np.zeros(scene.model.nv), 0.0)
    gradient = np.zeros(scene.model.nv)
    h = 1e-6
    for j in range(scene.model.nv):
        energies = []
        for sign in (1, -1):
            dq = np.zeros(scene.model.nv)
            dq[j] = sign * h
            kin.update_positions(pin.integrate(scene.model, q, dq))
            energies.append(spring.potential_energy(kin))
        gradient[j] = (energies[0] - energies[1]) / (2 * h)
    np.testing.assert_allclose(force, -gradient, atol=1e-7)


def test_energy_with_spring_is_conserved():
    traj = simulate(spring_scene(), method="projection", integrator="rk4", dt=1e-3, duration=2.0)
    assert np.ptp(traj.energy) < 1e-7 * abs(traj.energy[0]) + 1e-8


def test_damper_only_dissipates():
    traj = simulate(spring_scene(damping=2.0), method="projection", integrator="rk4", dt=1e-3, duration=2.0)
    assert traj.energy[-1] < traj.energy[0] - 0.1
    assert np.diff(traj.energy).max() < 1e-9


def test_constant_torque_work_equals_energy_gain():
    """slider-crank with its motor but no load: E(t) - E(0) = tau (theta(t) - theta(0))."""
    scene = load_scene("slider-crank")
    scene.forces[:] = [f for f in scene.forces if f.name == "motor"]
    traj = simulate(scene, method="projection", integrator="rk4", dt=1e-3, duration=2.0)
    work = 0.2 * (traj.q[:, 0] - traj.q[0, 0])
    assert np.ptp(work) > 0.3  # the motor does real work (0.57 J)
    np.testing.assert_allclose(traj.energy - traj.energy[0], work, atol=1e-7)


def test_torque_table_interpolates_and_holds_its_ends():
    torque = JointTorque("table", 0, 1, np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0, -1.0]))
    assert [torque.torque(t) for t in (-1.0, 0.5, 1.5, 3.0)] == pytest.approx([0.0, 1.0, 0.5, -1.0])

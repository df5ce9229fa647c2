"""Bricard's mechanism (IFToMM A04) against its geometry computed here with numpy, not pinstab.

The loop: joints 1-6 at P0..P5 on the unit cube's hexagonal path with axes y, z, x, y, z, x (the ground
is the sixth link). A joint turned by t moves what follows it by the rotation about its axis through its
point, so bar k's placement is the product g1(q1) ... gk(qk) (product of exponentials from the zero
configuration, where every URDF joint frame has the world's orientation), and the loop is closed when
g1 ... g5 is a rotation about joint 6's axis. Along the motion: q1 = q3 = q5 = th,
q2 = q4 = q6 = ph with sin ph = -sin th / (1 + sin th) (th in [0, pi]); the relation is checked here on the
geometry before the run is checked against it. The kinetic energy of the one-parameter motion is computed
from the bars' velocities along th (central differences), the potential from their centres.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinstab import load_scene, simulate
from pinstab.cli import main
from pinstab.system import NATIVE_MU, REDUNDANT_MU, build_system

JOINTS = np.array([(0, 0, 0), (1, 0, 0), (1, -1, 0), (1, -1, 1), (0, -1, 1), (0, 0, 1)], dtype=float)
AXES = np.eye(3)[[1, 2, 0, 1, 2, 0]]
MASS, GRAVITY = 1.0, 9.81
AXIAL, TRANSVERSE = MASS * 2 * 0.1**2 / 12, MASS * (1 + 0.1**2) / 12  # 1 m bars of 0.1 m square section
DURATION = 10.0


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def placements(angles) -> list[tuple[np.ndarray, np.ndarray]]:
    """(R, p) of bars 1..len(angles): a point x of bar k at the zero configuration is at R x + p."""
    rot, pos, out = np.eye(3), np.zeros(3), []
    for point, axis, angle in zip(JOINTS, AXES, angles, strict=False):
        step = rotation(axis, angle)
        rot, pos = rot @ step, rot @ (point - step @ point) + pos
        out.append((rot, pos))
    return out


def loop_residual(q) -> float:
    """How far bar 5 is from a rotation about joint 6's axis [m]: the gaps at the hinge and 1 m along it."""
    rot, pos = placements(q)[-1]
    hinge, along = JOINTS[5], JOINTS[5] + AXES[5]
    return max(np.linalg.norm(rot @ hinge + pos - hinge), np.linalg.norm(rot @ along + pos - along))


def joint6(q) -> float:
    """The sixth joint's angle [rad]: the ground turned by it about x closes the loop."""
    rot = placements(q)[-1][0]
    return float(-np.arctan2(rot[2, 1], rot[1, 1]))


def closed_form(theta):
    """The loop's joint angles at th = q1 (0 <= th <= pi)."""
    phi = np.arcsin(-np.sin(theta) / (1 + np.sin(theta)))
    return np.array([theta, phi, theta, phi, theta])


def energies(theta: float, rate: float, h: float = 1e-5) -> tuple[float, float]:
    """Kinetic and potential energy [J] of the loop at q1 = th, dq1/dt = rate."""
    now, ahead, behind = (placements(closed_form(t)) for t in (theta, theta + h, theta - h))
    kinetic = potential = 0.0
    for k, ((rot, pos), (rot_a, pos_a), (rot_b, pos_b)) in enumerate(zip(now, ahead, behind, strict=True)):
        centre = (JOINTS[k] + JOINTS[k + 1]) / 2
        along = JOINTS[k + 1] - JOINTS[k]
        inertia = np.diag(np.where(along != 0, AXIAL, TRANSVERSE))
        velocity = ((rot_a - rot_b) @ centre + pos_a - pos_b) / (2 * h) * rate
        spin = (rot_a - rot_b) / (2 * h) @ rot.T * rate
        omega = np.array([spin[2, 1], spin[0, 2], spin[1, 0]])
        body_omega = rot.T @ omega
        kinetic += 0.5 * MASS * velocity @ velocity + 0.5 * body_omega @ inertia @ body_omega
        potential += MASS * GRAVITY * (rot @ centre + pos)[1]
    return kinetic, potential


@pytest.fixture(scope="module")
def run():
    return simulate(load_scene("bricard"), duration=DURATION)


def test_the_closed_form_closes_the_loop():
    for theta in np.linspace(0, np.pi, 61):
        q = closed_form(theta)
        assert loop_residual(q) < 1e-14
        assert joint6(q) == pytest.approx(q[1], abs=1e-14)


def test_check_reports_one_mobility_and_the_redundant_rows(capsys):
    assert main(["check", "bricard", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    scene = load_scene("bricard")
    # the two point closures' Jacobian at the start, by central differences of the numpy geometry
    hinge, along = JOINTS[5], JOINTS[5] + AXES[5]

    def rows(q):
        rot, pos = placements(q)[-1]
        return np.concatenate([rot @ hinge + pos - hinge, rot @ along + pos - along])

    h = 1e-6
    jacobian = np.column_stack([(rows(scene.q0 + h * e) - rows(scene.q0 - h * e)) / (2 * h) for e in np.eye(5)])
    singular = np.linalg.svd(jacobian, compute_uv=False)
    rank = int(np.sum(singular > 1e-6 * singular[0]))
    assert singular[rank - 1] > 0.5 and (rank == len(singular) or singular[rank] < 1e-8)  # a clear gap
    assert (result["nv"], result["rows"], result["rank"]) == (5, 6, rank) == (5, 6, 4)
    assert result["mobility"] == result["nv"] - rank == 1
    assert result["redundant"] == result["rows"] - rank == 2
    assert result["assembly_residual"] == 0.0


def test_ten_seconds_under_gravity_conserve_energy_and_the_loop(run):
    energy = run.energy
    assert run.info.path == "native"
    assert np.max(np.abs(energy - energy[0])) / abs(energy[0]) < 1e-8  # measured 3.5e-12
    assert run.position_drift.max() < 1e-10  # measured 6e-12 m
    theta = run.q[:, 0]
    assert theta.min() > -1e-9 and theta.max() > np.pi - 1e-4  # swings to the mirror configuration
    assert max(loop_residual(q) for q in run.q[::10]) < 1e-10


def test_the_run_follows_the_closed_form_and_the_minimal_model(run):
    theta = np.clip(run.q[:, 0], 0.0, np.pi)
    np.testing.assert_allclose(run.q, np.array([closed_form(t) for t in theta]), atol=1e-9)
    start = sum(energies(0.0, 0.0))  # at rest in the cube configuration: -3 m g = -29.43 J
    kinetic = []
    for index in range(0, len(run.t), 50):
        sample = energies(theta[index], run.v[index, 0])
        assert sum(sample) == pytest.approx(start, abs=1e-8)  # measured 2e-10 J (the differences' error)
        kinetic.append(sample[0])
    assert max(kinetic) > 4.0  # measured 4.55 J: the loop really moves


def test_redundant_rows_raise_the_native_regularization():
    """Independent rows keep Pinocchio's mu at 1e-12; the loop's redundant ones take 1e-8 of the largest
    eigenvalue of G M^-1 G^T (9.86 at the start), against rounding in the singular Delassus matrix."""
    fourbar = load_scene("fourbar")
    assert build_system(fourbar).native_mu(fourbar.q0) == NATIVE_MU
    scene = load_scene("bricard")
    assert build_system(scene).native_mu(scene.q0) == pytest.approx(REDUNDANT_MU * 9.8624, rel=1e-4)

"""Every closure kind's Jacobian and drift term against central finite differences through pin.integrate."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS, random_configuration
from pinstab import ConstraintError, HolonomicConstraint, PfaffianConstraint
from pinstab.kinematics import Kinematics
from pinstab.scene import scene_from_dict

STEP = 1e-6
# central differences: truncation O(h^2) ~ 1e-12 relative, rounding ~ eps/h ~ 1e-10
TOLERANCE = 1e-7

CLOSURES = [
    {
        "name": "pt",
        "kind": "point",
        "frame_a": "forearm0",
        "offset_a": [0.31, 0.02, -0.01],
        "frame_b": "forearm1",
        "offset_b": [0.1, 0.0, 0.03],
    },
    {
        "name": "pt-world",
        "kind": "point",
        "frame_a": "platform2",
        "offset_a": [0.01, 0.02, 0.03],
        "offset_b": [0.1, -0.2, -0.4],
    },
    {
        "name": "planar",
        "kind": "planar-point",
        "plane": [0.2, -0.3, 1.0],
        "frame_a": "arm1",
        "offset_a": [0.1, 0.05, 0.0],
        "frame_b": "forearm2",
        "offset_b": [0.2, 0.0, 0.0],
    },
    {"name": "planar-world", "kind": "planar-point", "plane": "xz", "frame_a": "forearm1", "offset_b": [0.0, 0.1, 0.0]},
    {
        "name": "weld",
        "kind": "weld",
        "frame_a": "platform0",
        "offset_a": [0.02, 0.0, 0.01],
        "rpy_a": [0.1, -0.2, 0.3],
        "frame_b": "forearm2",
        "offset_b": [0.4, 0.01, 0.0],
        "rpy_b": [0.5, 0.4, -0.3],
    },
    {
        "name": "weld-world",
        "kind": "weld",
        "frame_a": "platform1",
        "rpy_b": [0.3, 0.2, 0.1],
        "offset_b": [0.0, 0.0, -0.4],
    },
    {
        "name": "hinge",
        "kind": "revolute",
        "axis": [0.3, -0.2, 0.9],
        "frame_a": "forearm0",
        "offset_a": [0.05, 0.01, 0.0],
        "rpy_a": [0.2, 0.1, -0.4],
        "frame_b": "platform2",
        "offset_b": [0.1, 0.0, 0.02],
    },
    {"name": "hinge-world", "kind": "revolute", "axis": [1.0, 0.0, 0.0], "frame_a": "arm2", "rpy_b": [0.1, 0.0, 0.2]},
    {
        "name": "slide",
        "kind": "prismatic",
        "axis": [0.0, 0.6, 0.8],
        "frame_a": "arm0",
        "offset_a": [0.2, 0.0, 0.01],
        "frame_b": "forearm1",
        "offset_b": [0.3, 0.02, 0.0],
        "rpy_b": [-0.3, 0.2, 0.5],
    },
    {
        "name": "slide-world",
        "kind": "prismatic",
        "axis": [0.0, 0.0, 1.0],
        "frame_a": "platform0",
        "offset_b": [0.1, 0, 0],
    },
]


@pytest.fixture(scope="module")
def scene():
    data = {"robot": {"urdf": str(ROBOTS / "urdf" / "delta.urdf")}, "closures": CLOSURES}
    return scene_from_dict(data, name="closure-zoo")


def _jacobian_and_residual(scene, kin, q):
    cs = scene.constraint_set
    kin.update_jacobians(q)
    return cs.residual(kin, q, 0.0), cs.velocity_terms(kin, q, 0.0)[0]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jacobian_matches_finite_differences(scene, seed):
    rng = np.random.default_rng(seed)
    model = scene.model
    kin = Kinematics(model)
    q = random_configuration(model, rng)
    _, jac = _jacobian_and_residual(scene, kin, q)
    fd = np.zeros_like(jac)
    for j in range(model.nv):
        dq = np.zeros(model.nv)
        dq[j] = STEP
        plus, _ = _jacobian_and_residual(scene, kin, pin.integrate(model, q, dq))
        minus, _ = _jacobian_and_residual(scene, kin, pin.integrate(model, q, -dq))
        fd[:, j] = (plus - minus) / (2 * STEP)
    for name, rows in scene.constraint_set.slices.items():
        np.testing.assert_allclose(jac[rows], fd[rows], atol=TOLERANCE, err_msg=f"Jacobian of {name}")


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_drift_term_matches_finite_differences(scene, seed):
    """gamma0 = d/dt (G(q(t)) v) along q(t) = q (+) t v at zero joint acceleration."""
    rng = np.random.default_rng(seed)
    model = scene.model
    kin = Kinematics(model)
    cs = scene.constraint_set
    q = random_configuration(model, rng)
    v = rng.standard_normal(model.nv)
    kin.update(q, v)
    drift = cs.drift(kin, q, v, 0.0)
    _, jac_plus = _jacobian_and_residual(scene, kin, pin.integrate(model, q, STEP * v))
    _, jac_minus = _jacobian_and_residual(scene, kin, pin.integrate(model, q, -STEP * v))
    fd = (jac_plus @ v - jac_minus @ v) / (2 * STEP)
    for name, rows in cs.slices.items():
        np.testing.assert_allclose(drift[rows], fd[rows], atol=10 * TOLERANCE, err_msg=f"drift of {name}")


def test_residual_vanishes_when_frames_coincide(scene):
    """A weld of a frame to the world placement it currently has has zero residual."""
    model = scene.model
    kin = Kinematics(model)
    q = pin.neutral(model)
    kin.update_positions(q)
    target = kin.placement(model.getFrameId("platform1", pin.FrameType.BODY))
    rpy = pin.rpy.matrixToRpy(target.rotation)
    data = {
        "robot": {"urdf": str(ROBOTS / "urdf" / "delta.urdf")},
        "closures": [
            {
                "name": "w",
                "kind": "weld",
                "frame_a": "platform1",
                "offset_b": list(target.translation),
                "rpy_b": list(rpy),
            }
        ],
    }
    welded = scene_from_dict(data)
    kin2 = Kinematics(welded.model)
    kin2.update_positions(q)
    assert np.abs(welded.constraint_set.residual(kin2, q, 0.0)).max() < 1e-12


def test_user_callable_with_wrong_shape_names_the_constraint(scene):
    bad = HolonomicConstraint(
        "bad-rows", 2, lambda q, t: np.zeros(3), lambda q, t: np.zeros((2, 15)), lambda q, v, t: np.zeros(2), nv=15
    )
    kin = Kinematics(scene.model)
    with pytest.raises(ConstraintError, match="bad-rows.*residual.*shape"):
        bad.residual(kin, pin.neutral(scene.model), 0.0)
    nan = PfaffianConstraint("nan-rows", 1, lambda q, t: np.full((1, 15), np.nan), lambda q, v, t: np.zeros(1), nv=15)
    with pytest.raises(ConstraintError, match="nan-rows.*non-finite"):
        nan.velocity_terms(kin, pin.neutral(scene.model), 0.0)

"""The short run's set-up (issue 35): what the banded path no longer builds or computes at the start gives the answers
the eager computations gave: Pinocchio's constraint models and the native mu at first use, the generic rank from the
banded kernel's conditioning, the planar check of every closure at once, the joints' supports as bit sets."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab import build_system, load_scene
from pinstab.constraints import FrameClosure
from pinstab.integration.passages import Conditioning
from pinstab.kinematics import frame_jacobian
from pinstab.paths.banded import joint_supports
from pinstab.paths.native import PLANAR_TOLERANCE, NativeDynamics, non_planar_closure
from pinstab.scene import scene_from_dict

KP, KD = 100.0, 20.0  # [1/s^2], [1/s]


def _closures(scene) -> list[FrameClosure]:
    return [c for c in scene.constraints if isinstance(c, FrameClosure)]


def test_the_banded_path_builds_pinocchios_constraint_models_at_a_fallback_only():
    """Bound on the banded path, the native solve has neither constraint models nor mu until an evaluation falls back
    to it; then mu is the eager choice at the start configuration (native_mu) and the accelerations equal those of a
    solve built eagerly with it, to the bit."""
    scene = load_scene("nfourbar", N=8)
    system = build_system(scene, kp=KP, kd=KD)
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "banded"
    assert "_pinocchio" not in vars(system.native)
    calls = []
    native_mu = system.native_mu
    system.native_mu = lambda q: calls.append(q.copy()) or native_mu(q)
    rng = np.random.default_rng(2)
    q = pin.integrate(scene.model, scene.q0, 0.05 * rng.normal(size=scene.model.nv))
    v, tau = rng.normal(size=scene.model.nv), rng.normal(size=scene.model.nv)
    got = system.native.acceleration(q, v, tau).copy()
    assert len(calls) == 1 and np.array_equal(calls[0], scene.q0)
    eager = NativeDynamics(scene.model, _closures(scene), KP, KD, mu=native_mu(scene.q0))
    assert len(eager.models) == len(_closures(scene))  # built now, as the constructor did before
    assert system.native.settings.mu == eager.settings.mu
    assert np.array_equal(got, eager.acceleration(q, v, tau))
    system.native.acceleration(q, v, tau)
    assert len(calls) == 1  # once


def test_gains_set_before_the_models_exist_reach_pinocchios_corrector():
    """set_gains before the first solve: the models built later carry the new gains (the solve equals one
    constructed with them, to the bit); an attribute changed by hand does not reach the corrector."""
    scene = load_scene("fourbar")
    rng = np.random.default_rng(4)
    q = pin.integrate(scene.model, scene.q0, 0.1 * rng.normal(size=scene.model.nv))
    v, tau = rng.normal(size=scene.model.nv), np.zeros(scene.model.nv)
    late = NativeDynamics(scene.model, _closures(scene), 1.0, 2.0)
    late.set_gains(KP, KD)
    late.kp = 55.0  # what the check expects only
    direct = NativeDynamics(scene.model, _closures(scene), KP, KD)
    assert np.array_equal(late.acceleration(q, v, tau), direct.acceleration(q, v, tau))


def test_the_generic_rank_from_the_kernel_equals_the_svds_and_its_value_is_the_first_sample():
    """With the banded kernel's sigma_r / sigma_1 the rank at the start is the SVD's (all rows, N-four-bar), and the
    first sample at the start configuration returns the kernel's value there without a second evaluation."""
    scene = load_scene("nfourbar", N=10)
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    calls = []
    relative = system.banded.relative_singular_value

    def counted(q: np.ndarray, rank: int) -> float:
        calls.append(rank)
        return relative(q, rank)

    compiled = Conditioning(system.model, scene.q0, counted, system.banded.jacobian)
    svd = Conditioning(system.model, scene.q0)
    assert compiled.rank == svd.rank == system.model.constraints.rows
    assert calls == [compiled.rank]
    first = compiled.relative(scene.q0.copy(), 0.0)
    assert calls == [compiled.rank]
    assert first == pytest.approx(svd.relative(scene.q0, 0.0), rel=1e-10)
    q = scene.q0 + 0.01
    assert compiled.relative(q, 0.0) == pytest.approx(svd.relative(q, 0.0), rel=1e-10)
    assert calls == [compiled.rank, compiled.rank]


def _non_planar_reference(model: pin.Model, data: pin.Data, closures: list[FrameClosure], q: np.ndarray) -> str | None:
    """The check closure by closure, from Pinocchio's frame Jacobians."""
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    for closure in closures:
        if closure.kind != "planar-point":
            continue
        jac = frame_jacobian(model, data, closure.frame_a)[:3]
        if closure.frame_b is not None:
            jac = jac - frame_jacobian(model, data, closure.frame_b)[:3]
        if np.abs(np.cross(closure.selection[0], closure.selection[1]) @ jac).max() > PLANAR_TOLERANCE:
            return closure.name
    return None


@pytest.mark.parametrize("plane", [None, "xy", "xz", "yz"])
def test_the_planar_check_of_every_closure_at_once_equals_pinocchios_frame_jacobians(plane):
    """Planar mechanisms (N-four-bar, slider-crank, fivebar, at random configurations) pass; a planar-point closure on
    the delta (spatial) is named where the closure-by-closure check from Pinocchio's frame Jacobians names it (in the
    xy plane: at every configuration)."""
    rng = np.random.default_rng(9)
    if plane is None:
        scenes = [load_scene("nfourbar", N=12), load_scene("slider-crank"), load_scene("fivebar")]
    else:
        delta = load_scene("delta")
        closure = {"name": "odd", "kind": "planar-point", "plane": plane, "frame_a": "forearm0"}
        scenes = [scene_from_dict({"robot": {"urdf": str(delta.urdf_path)}, "closures": [closure]})]
    for scene in scenes:
        model, data = scene.model, scene.model.createData()
        for trial in range(5):
            q = scene.q0 if trial == 0 else pin.integrate(model, scene.q0, rng.normal(size=model.nv))
            expected = _non_planar_reference(model, data, _closures(scene), q)
            assert non_planar_closure(model, data, _closures(scene), q) == expected
            if plane in (None, "xy"):
                assert expected == (None if plane is None else "odd")


@pytest.mark.parametrize("name", ["nfourbar", "cassie-legs", "delta", "fourbar"])
def test_the_joints_supports_are_pinocchios(name):
    """joint_supports marks exactly the velocity indices of the joints Pinocchio lists as supporting each joint."""
    model = load_scene(name).model
    supports = joint_supports(model)
    assert supports.shape == (model.njoints, model.nv) and supports.dtype == bool
    for joint in range(model.njoints):
        expected = np.zeros(model.nv, dtype=bool)
        for ancestor in model.supports[joint]:
            if ancestor:
                start = model.joints[ancestor].idx_v
                expected[start : start + model.joints[ancestor].nv] = True
        assert np.array_equal(supports[joint], expected), model.names[joint]

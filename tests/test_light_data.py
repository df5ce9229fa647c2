"""pinstab's Pinocchio ``Data`` without the second-order derivative tensors (issue 35, item 5;
``pinstab.memory.new_data``, ``cpp/light_data.cpp``): every member a Python ``pin.Data`` exposes equals that of
Pinocchio's constructor, and every pass pinstab runs gives bitwise the same results in it."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab import load_scene
from pinstab.constraints import FrameClosure
from pinstab.kinematics import LWA
from pinstab.memory import new_data
from pinstab.paths.native import NativeDynamics

SCENES = ["fourbar", "cassie-legs", "allegro-sphere", "homing", "nfourbar"]
# default-constructed by Pinocchio's constructor as by the light one (no values to compare); contact_chol: its
# deprecated alias
UNSET = {"constraint_chol", "contact_chol"}


def _plain(value):
    """A member as arrays, numbers and lists (Motion, Force, SE3, Inertia and joint data by their numbers)."""
    if isinstance(value, np.ndarray | int | float | bool | str):
        return value
    for name in ("homogeneous", "vector"):
        if hasattr(value, name):
            return np.asarray(getattr(value, name))
    if isinstance(value, pin.Inertia):
        return value.matrix()
    if hasattr(value, "joint_q"):  # a joint's data
        return [_plain(getattr(value, name)) for name in ("joint_q", "joint_v", "S", "M", "v", "c", "U", "Dinv")]
    return [_plain(item) for item in value]


def _same(a, b) -> bool:
    """Equal to the last bit, NaN equal to NaN (Pinocchio leaves some joint velocities NaN until a pass)."""
    if isinstance(a, list) or isinstance(b, list):
        return isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(map(_same, a, b))
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "fc":
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a.shape == b.shape and np.array_equal(a, b)


@pytest.mark.parametrize("name", SCENES)
def test_every_member_equals_pinocchios_constructor(name):
    model = load_scene(name).model
    light, full = new_data(model), pin.Data(model)
    members = [m for m in dir(full) if not m.startswith("_") and m not in UNSET and not callable(getattr(full, m))]
    assert len(members) > 90
    differing = [m for m in members if not _same(_plain(getattr(light, m)), _plain(getattr(full, m)))]
    assert differing == []


def test_a_differing_member_is_seen():
    """The comparison is not blind: one entry changed in one member is found."""
    model = load_scene("fourbar").model
    light, full = new_data(model), pin.Data(model)
    light.oMi[1] = pin.SE3(np.eye(3), np.array([0.0, 0.0, 1e-300]))
    assert not _same(_plain(light.oMi), _plain(full.oMi))
    assert _same(_plain(light.nvSubtree), _plain(full.nvSubtree))


@pytest.mark.parametrize("name", SCENES)
def test_pinstabs_passes_are_bitwise_those_of_pinocchios_data(name):
    scene = load_scene(name)
    model = scene.model
    rng = np.random.default_rng(7)
    q = pin.integrate(model, scene.q0, 0.3 * rng.standard_normal(model.nv))
    v, tau = rng.standard_normal(model.nv), rng.standard_normal(model.nv)
    results = []
    for data in (new_data(model), pin.Data(model)):
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        frames = [pin.getFrameJacobian(model, data, f, LWA) for f in range(model.nframes)]
        drifts = [pin.getFrameClassicalAcceleration(model, data, f, LWA).vector for f in range(model.nframes)]
        passes = [data.M.copy(), data.nle.copy(), data.g.copy(), *frames, *drifts]
        passes.append(pin.crba(model, data, q, pin.Convention.WORLD).copy())
        passes.append(pin.nonLinearEffects(model, data, q, v).copy())
        passes.append(pin.computeGeneralizedGravity(model, data, q).copy())
        energies = pin.computeKineticEnergy(model, data, q, v), pin.computePotentialEnergy(model, data, q)
        passes.append(np.array(energies))
        closures = [c for c in scene.constraints if isinstance(c, FrameClosure) and c.kind in ("point", "planar-point")]
        if closures:
            native = NativeDynamics(model, closures, 100.0, 20.0, data=data)
            passes += [native.acceleration(q, v, tau), native.multipliers()]
        results.append(passes)
    assert len(results[0]) == len(results[1])
    assert all(map(_same, *results))

"""``block_rate`` (``cpp/core_rows.cpp``): each compiled row kind's velocity residual g = G v + g_t, formed without G,
against ``block_jacobian(...) @ v + time_term`` at random states of scenes that hold every kind: points and
planar points (fourbar), welds (delta, dual-panda-box), revolute, prismatic and relation rows (cassie), moving targets
of relations (homing), fingertip contacts without rotation rows (allegro-sphere, trifinger-cube: point friction) and
with them (allegro-box: soft fingers), and closures
on the world (a zoo of every closure kind on the delta's links)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab import load_scene
from pinstab.errors import PenetrationWarning
from pinstab.kernels import RowBlock, block_drift, block_jacobian, block_rate, block_residual
from pinstab.scene import scene_from_dict

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
SCENES = ["fourbar", "delta", "dual-panda-box", "cassie", "homing", "allegro-sphere", "trifinger-cube", "allegro-box"]
RELATIVE = 1e-13  # of the block's largest sum_j |G_ij v_j| + |g_t,i| (a row may cancel sides' speeds of that size)
ZOO = [  # every frame closure kind, on a second frame and on the world
    {"name": "planar-world", "kind": "planar-point", "plane": [0.2, 0.3, 0.9], "frame_a": "forearm1"},
    {"name": "weld-world", "kind": "weld", "frame_a": "platform1", "rpy_b": [0.3, 0.2, 0.1]},
    {"name": "hinge", "kind": "revolute", "axis": [0.3, -0.2, 0.9], "frame_a": "forearm0", "frame_b": "platform2"},
    {"name": "hinge-world", "kind": "revolute", "axis": [1.0, 0.0, 0.0], "frame_a": "arm2", "rpy_b": [0.1, 0.0, 0.2]},
    {"name": "slide", "kind": "prismatic", "axis": [0.0, 0.6, 0.8], "frame_a": "arm0", "frame_b": "forearm1",
     "offset_b": [0.3, 0.02, 0.0], "rpy_b": [-0.3, 0.2, 0.5]},
    {"name": "slide-world", "kind": "prismatic", "axis": [0.0, 0.0, 1.0], "frame_a": "platform0",
     "offset_b": [0.1, 0, 0]},
]  # fmt: skip


def _scene(name: str):
    if name == "zoo":
        return scene_from_dict({"robot": {"urdf": str(ROBOTS / "urdf" / "delta.urdf")}, "closures": ZOO}, name="zoo")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PenetrationWarning)  # allegro-box's start: the rows hold anywhere
        return load_scene(name)


def _compare(model: pin.Model, blocks: list[tuple[str, RowBlock]], seed: int) -> None:
    """At a random state and time: every block's rate equals its Jacobian's product with v plus its time term."""
    rng = np.random.default_rng(seed)
    q = pin.integrate(model, pin.neutral(model), 0.5 * rng.standard_normal(model.nv))
    v, t = 2.0 * rng.standard_normal(model.nv), float(rng.uniform(0.0, 3.0))
    data = model.createData()
    pin.forwardKinematics(model, data, q, v)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    for name, block in blocks:
        jacobian, time_term = block_jacobian(model, data, block, t)
        rate = block_rate(model, data, block, v, t)
        size = np.abs(jacobian) @ np.abs(v) + np.abs(time_term)
        assert np.abs(rate - (jacobian @ v + time_term)).max() <= RELATIVE * size.max(), name
        assert np.abs(jacobian @ v).max() > 1e-3, name  # the rows move: not a comparison of zeros


@pytest.mark.parametrize("name", [*SCENES, "zoo"])
def test_block_rate_is_the_jacobians_product_with_v_plus_the_time_term(name):
    """Every compiled block of the scene, at four random states and times (see :func:`_compare`)."""
    scene = _scene(name)
    blocks = [(c.name, c.compiled_rows()) for c in scene.constraints if c.compiled_rows() is not None]
    assert blocks
    for seed in range(4):
        _compare(scene.model, blocks, seed)


def test_the_scenes_hold_every_compiled_row_kind():
    """The comparison above covers every kind: frame closures, joint rows, relations and both fingertip forms."""
    kinds = {c.kind for name in [*SCENES, "zoo"] for c in _scene(name).constraints if c.compiled_rows() is not None}
    assert {"point", "planar-point", "weld", "revolute", "prismatic", "joint-relation"} <= kinds, kinds
    rotation_rows = {c.angular for name in SCENES for c in _scene(name).constraints if c.kind == "grasp-contact"}
    assert rotation_rows == {False, True}


def test_every_compiled_quantity_refuses_a_python_block():
    """A python block's rows are Python's: its compiled residual, Jacobian, rate and drift (cpp/core_rows.cpp's one
    dispatch on the kind) refuse it (ValueError) instead of a wrong number."""
    model = load_scene("fourbar").model
    block = RowBlock(6, -1, -1, np.eye(4), np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int32), np.zeros(0, np.int32))
    data = model.createData()
    zero = np.zeros(model.nv)
    for quantity in (
        lambda: block_rate(model, data, block, zero, 0.0),
        lambda: block_residual(model, data, block, pin.neutral(model), 0.0),
        lambda: block_jacobian(model, data, block, 0.0),
        lambda: block_drift(model, data, block, 0.0),
    ):
        with pytest.raises(ValueError, match="python"):
            quantity()

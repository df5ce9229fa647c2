"""MJCF models read by pinstab beside MuJoCo's own compilation and run of the same file (tests/test_mjcf_*.py):
the static quantities of each joint (anchor, axis, the spatial inertia of the bodies it carries) and trajectories
(contacts off, MuJoCo's RK4 at a small step). Models of hinge and slide joints only: the two libraries'
coordinates are then the same numbers (MuJoCo's qpos = Pinocchio's q)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab import simulate
from pinstab.scene import Scene, scene_from_dict

mujoco = pytest.importorskip("mujoco")

STATIC_TOL = 1e-12  # [m, rad, kg, kg m, kg m^2]: the same compiled quantities, two libraries' rounding


def written(folder: Path, name: str, text: str) -> Path:
    """The MJCF file ``name`` of ``text`` written in ``folder``."""
    path = folder / name
    path.write_text(text)
    return path


def scene_of(path: Path, **robot) -> Scene:
    """pinstab's scene of the MJCF file ``path`` (gravity MuJoCo's default, -9.81 m/s^2 along z)."""
    return scene_from_dict({"robot": {"mjcf": path.name, **robot}}, base_dir=path.parent)


def twins(path: Path, **robot) -> tuple[Scene, object]:
    """pinstab's scene of the MJCF file ``path`` (:func:`scene_of`) and MuJoCo's compiled model of it."""
    return scene_of(path, **robot), mujoco.MjModel.from_xml_path(str(path))


def joint_quantities(scene: Scene, q: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Each joint of pinstab's model at ``q`` (hinges and slides): (anchor [m], unit axis, the 6x6 world spatial
    inertia of the bodies it carries [kg, kg m, kg m^2]) by joint name."""
    model = scene.model
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    pin.computeJointJacobians(model, data, q)
    out = {}
    for joint in range(1, model.njoints):
        column = pin.getJointJacobian(model, data, joint, pin.ReferenceFrame.WORLD)[:, model.joints[joint].idx_v]
        inertia = data.oMi[joint].act(model.inertias[joint]).matrix()
        axis = column[3:] if np.any(column[3:]) else column[:3]  # a hinge's turn, else a slide's direction
        out[model.names[joint]] = (data.oMi[joint].translation.copy(), axis.copy(), inertia)
    return out


def mujoco_quantities(model, q: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The same of MuJoCo's compiled ``model`` at qpos ``q``: ``xanchor`` (a slide's moved by its slide), ``xaxis``,
    and the inertias of the bodies (``body_mass``, ``body_ipos``, ``body_iquat``, ``body_inertia``) whose nearest
    jointed body (itself or an ancestor) has that joint, summed in the world frame."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    out = {}
    for joint in range(model.njnt):
        name = model.joint(joint).name
        total = pin.Inertia.Zero()
        for body in range(1, model.nbody):
            carrier = body
            while model.body_jntnum[carrier] == 0:
                carrier = model.body_parentid[carrier]
            if carrier != model.jnt_bodyid[joint]:
                continue
            w, x, y, z = model.body_iquat[body]
            principal = pin.Inertia(
                model.body_mass[body],
                np.zeros(3),
                pin.Quaternion(w, x, y, z).matrix()
                @ np.diag(model.body_inertia[body])
                @ pin.Quaternion(w, x, y, z).matrix().T,
            )
            local = pin.SE3(np.eye(3), model.body_ipos[body]).act(principal)
            world = pin.SE3(data.xmat[body].reshape(3, 3), data.xpos[body]).act(local)
            total = total + world
        anchor = data.xanchor[joint].copy()  # a slide's: before its own slide (Pinocchio's joint frame: after it)
        if model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_SLIDE:
            address = model.jnt_qposadr[joint]
            anchor += data.xaxis[joint] * (q[address] - model.qpos0[address])
        out[name] = (anchor, data.xaxis[joint].copy(), total.matrix())
    return out


def assert_same_joints(scene: Scene, model, q: np.ndarray) -> None:
    """pinstab's joints and MuJoCo's at ``q`` (the same names, anchors, axes, inertias) to :data:`STATIC_TOL`."""
    ours, theirs = joint_quantities(scene, q), mujoco_quantities(model, q)
    assert sorted(ours) == sorted(theirs)
    for name, (anchor, axis, inertia) in theirs.items():
        np.testing.assert_allclose(ours[name][0], anchor, atol=STATIC_TOL, err_msg=f"anchor of {name}")
        np.testing.assert_allclose(ours[name][1], axis, atol=STATIC_TOL, err_msg=f"axis of {name}")
        np.testing.assert_allclose(ours[name][2], inertia, atol=STATIC_TOL, err_msg=f"inertia of {name}")


def mujoco_run(
    model, qpos: np.ndarray, qvel: np.ndarray, duration: float, every: int, ctrl: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's run of ``model`` (its own options: RK4, its timestep, contacts off) from (qpos, qvel) with the
    actuators' controls ``ctrl`` (default 0): the times [s] and qpos every ``every`` steps."""
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    if ctrl is not None:
        data.ctrl[:] = ctrl
    steps = round(duration / model.opt.timestep)
    times, positions = [0.0], [data.qpos.copy()]
    for step in range(1, steps + 1):
        mujoco.mj_step(model, data)
        if step % every == 0:
            times.append(data.time)
            positions.append(data.qpos.copy())
    return np.array(times), np.array(positions)


def largest_difference(scene: Scene, model, duration: float = 1.0, ctrl: np.ndarray | None = None, **run) -> float:
    """The largest |q_pinstab - qpos_MuJoCo| [rad or m] over ``duration`` [s] from the scene's start (MuJoCo started
    at the same state, its controls ``ctrl``), pinstab's run by dop853 at tight tolerances sampled where MuJoCo's
    is."""
    times, positions = mujoco_run(model, scene.q0, scene.v0, duration, every=100, ctrl=ctrl)
    trajectory = simulate(scene, duration=duration, dt=float(times[1] - times[0]), rtol=1e-11, atol=1e-11, **run)
    assert np.allclose(trajectory.t, times, atol=1e-12)
    return float(np.max(np.abs(trajectory.q - positions)))

"""MuJoCo as a peer (optional extra ``pinstab[bench]``): the scene's mechanism written as MJCF.

The kinematic tree of the (reduced) Pinocchio model becomes nested bodies with hinge/slide joints and
the same inertias; every ``point`` / ``planar-point`` closure becomes an equality ``connect`` between
two sites (MuJoCo's soft constraint, tuned by ``solref``); joint torques are applied through
``qfrc_applied`` and spring-dampers become spatial tendons with stiffness, damping and rest length.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from ..constraints import FrameClosure
from ..errors import PinstabError
from ..forces import JointTorque, SpringDamper
from ..scene import Scene

DEFAULT_SOLREF = (0.02, 1.0)  # MuJoCo's default: time constant 0.02 s, damping ratio 1
MUJOCO_SCHEMES = {
    "euler": "Euler",
    "semi-implicit-euler": "Euler",
    "implicitfast": "implicitfast",
    "implicit": "implicit",
    "rk4": "RK4",
}
JOINT_AXES = {"RX": (1, 0, 0), "RY": (0, 1, 0), "RZ": (0, 0, 1), "PX": (1, 0, 0), "PY": (0, 1, 0), "PZ": (0, 0, 1)}


def _vec(values) -> str:
    return " ".join(f"{float(x):.17g}" for x in values)


def _joint(model: pin.Model, index: int) -> tuple[str, tuple[float, ...]]:
    joint = model.joints[index]
    short = joint.shortname().removeprefix("JointModel")
    if short in JOINT_AXES:
        return ("hinge" if short[0] == "R" else "slide"), JOINT_AXES[short]
    if short in ("RevoluteUnaligned", "PrismaticUnaligned"):
        return ("hinge" if short.startswith("R") else "slide"), tuple(joint.axis)
    raise PinstabError(f"MuJoCo peer: joint {model.names[index]!r} ({short}) has no MJCF counterpart here")


def _site_for(
    model: pin.Model, frame_id: int | None, placement: pin.SE3, name: str, sites: dict[int, list[str]]
) -> None:
    """Attach a site for a frame point to the body of its parent joint (0: world)."""
    if frame_id is None:
        sites.setdefault(0, []).append(f'<site name="{name}" pos="{_vec(placement.translation)}"/>')
        return
    frame = model.frames[frame_id]
    sites.setdefault(frame.parentJoint, []).append(f'<site name="{name}" pos="{_vec(frame.placement.translation)}"/>')


def mjcf(scene: Scene, dt: float, integrator: str, solref: tuple[float, float]) -> str:
    """MJCF text of the scene (tree, inertias, closures as ``connect``, spring-dampers as tendons)."""
    model = scene.model
    sites: dict[int, list[str]] = {}
    equalities, tendons = [], []
    for constraint in scene.constraints:
        if not isinstance(constraint, FrameClosure) or constraint.kind not in ("point", "planar-point"):
            raise PinstabError(f"MuJoCo peer: constraint {constraint.name!r} is not a point closure")
        a, b = f"{constraint.name}/a", f"{constraint.name}/b"
        _site_for(model, constraint.frame_a, pin.SE3.Identity(), a, sites)
        _site_for(model, constraint.frame_b, constraint.world_placement_b, b, sites)
        equalities.append(f'<connect site1="{a}" site2="{b}" solref="{_vec(solref)}"/>')
    for element in scene.forces:
        if isinstance(element, SpringDamper):
            a, b = f"{element.name}/a", f"{element.name}/b"
            _site_for(model, element.frame_a, pin.SE3.Identity(), a, sites)
            _site_for(model, element.frame_b, pin.SE3(np.eye(3), element.world_point_b), b, sites)
            tendons.append(
                f'<spatial stiffness="{element.stiffness:.17g}" damping="{element.damping:.17g}" '
                f'springlength="{element.rest_length:.17g}"><site site="{a}"/><site site="{b}"/></spatial>'
            )
        elif not isinstance(element, JointTorque):
            raise PinstabError(f"MuJoCo peer: force element {element.name!r} has no MJCF counterpart here")

    def body(index: int) -> str:
        placement, inertia = model.jointPlacements[index], model.inertias[index]
        kind, axis = _joint(model, index)
        quaternion = pin.Quaternion(placement.rotation)
        matrix = inertia.inertia
        children = "".join(body(child) for child in range(1, model.njoints) if model.parents[child] == index)
        return (
            f'<body name="{model.names[index]}" pos="{_vec(placement.translation)}" '
            f'quat="{_vec((quaternion.w, quaternion.x, quaternion.y, quaternion.z))}">'
            f'<joint name="{model.names[index]}" type="{kind}" axis="{_vec(axis)}"/>'
            f'<inertial pos="{_vec(inertia.lever)}" mass="{inertia.mass:.17g}" fullinertia="'
            f'{_vec((matrix[0, 0], matrix[1, 1], matrix[2, 2], matrix[0, 1], matrix[0, 2], matrix[1, 2]))}"/>'
            + "".join(sites.get(index, []))
            + children
            + "</body>"
        )

    roots = "".join(body(j) for j in range(1, model.njoints) if model.parents[j] == 0)
    scheme = MUJOCO_SCHEMES.get(integrator)
    if scheme is None:
        raise PinstabError(
            f"MuJoCo peer: integrator {integrator!r} has no MuJoCo counterpart ({', '.join(MUJOCO_SCHEMES)})"
        )
    return (
        f'<mujoco model="{scene.name}"><option timestep="{dt:.17g}" gravity="{_vec(model.gravity.linear)}" '
        f'integrator="{scheme}"/><worldbody>{"".join(sites.get(0, []))}{roots}</worldbody>'
        f"<equality>{''.join(equalities)}</equality><tendon>{''.join(tendons)}</tendon></mujoco>"
    )


def run_mujoco(
    scene: Scene,
    q0: np.ndarray,
    v0: np.ndarray,
    dt: float,
    steps: int,
    integrator: str,
    solref: tuple[float, float],
    every: int = 1,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Simulate with MuJoCo from (q0, v0), keeping a sample every ``every`` steps; returns the q, v
    samples in Pinocchio's ordering and the CPU seconds of the loop. Without joint torques the steps
    between samples run inside MuJoCo (``mj_step(model, data, nstep)``), its fastest way.

    Raises:
        PinstabError: mujoco is not installed, the scene has no MJCF counterpart (:func:`mjcf`), or MuJoCo warned
            during the run (its first warning: a non-finite or huge state, which MuJoCo answers by resetting the
            state and going on, so the run would continue from another state).
    """
    try:
        import mujoco
    except ImportError:
        raise PinstabError("the MuJoCo peer needs mujoco: pip install 'pinstab[bench]'") from None
    model = scene.model
    mj_model = mujoco.MjModel.from_xml_string(mjcf(scene, dt, integrator, solref))
    mj_data = mujoco.MjData(mj_model)
    position = [mj_model.jnt_qposadr[mj_model.joint(model.names[j]).id] for j in range(1, model.njoints)]
    velocity = [mj_model.jnt_dofadr[mj_model.joint(model.names[j]).id] for j in range(1, model.njoints)]
    pin_q = [model.joints[j].idx_q for j in range(1, model.njoints)]
    pin_v = [model.joints[j].idx_v for j in range(1, model.njoints)]
    mj_data.qpos[position], mj_data.qvel[velocity] = q0[pin_q], v0[pin_v]
    torques = [element for element in scene.forces if isinstance(element, JointTorque)]
    samples = steps // every + 1
    qs, vs = np.empty((samples, model.nq)), np.empty((samples, model.nv))
    qs[0], vs[0] = q0, v0
    warnings: list[str] = []
    mujoco.set_mju_user_warning(warnings.append)  # MuJoCo's own handler prints and writes MUJOCO_LOG.TXT
    try:
        start = time.process_time()
        for k in range(1, samples):
            if torques:
                for _ in range(every):
                    for element in torques:
                        mj_data.qfrc_applied[velocity[pin_v.index(element.dof)]] = element.torque(mj_data.time)
                    mujoco.mj_step(mj_model, mj_data)
            else:
                mujoco.mj_step(mj_model, mj_data, every)
            qs[k, pin_q], vs[k, pin_v] = mj_data.qpos[position], mj_data.qvel[velocity]
        cpu = time.process_time() - start
    finally:
        mujoco.set_mju_user_warning(None)
    if warnings:  # a non-finite or huge state: MuJoCo resets it to the model's default and goes on
        raise PinstabError(f"MuJoCo's {integrator} at dt = {dt:g} s went unstable: {warnings[0]}")
    return qs, vs, cpu

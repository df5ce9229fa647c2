"""MuJoCo models of the closed-form contact scenes (``benchmarks/contacts``), with the settings MuJoCo
offers against creep: elliptic cones, ``impratio``, the noslip solver, the step and the contact
stiffness (``solref``'s time constant, ``solimp``).

Each scene is one free body (MuJoCo's free joint: linear velocity in world axes, angular in the body's),
the same masses and inertias as pinstab's, gravity as in pinstab's scene:

* incline: a 1 kg box of side 0.1 m on the plane z = 0 (MuJoCo's box-plane collision: its corners),
  gravity (g sin theta, 0, -g cos theta);
* sphere-spin: a 1 kg solid sphere on z = 0, thrown with v0 along x and backspin omega0;
* box-stack: 1 kg cubes of side 0.1 m stacked at rest on z = 0 (several free bodies, each its free joint);
* bouncing-ball: a 1 kg sphere of radius 0.05 m dropped from a gap h, frictionless (``condim`` 1), its
  restitution e set by solref's damping ratio ``zeta = -ln e / sqrt(pi^2 + ln^2 e)`` (a linear
  spring-damper's);
* pinch: a block of mass m and the inertia of a cube of side PINCH_BLOCK, its collision box that side
  across and BLOCK_LENGTH along z (the closed form's faces are planes: the fingers stay on them as it
  slides), and two PINCH_FINGER_MASS fingers on slide joints along x, each a sphere of radius FINGERTIP
  whose surface touches the block's face at its centre, pushed toward the block by ``qfrc_applied``;
  gravity -z.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import PinstabError
from .contact_scenes import BALL_RADIUS, GRAVITY, PINCH_BLOCK, PINCH_FINGER_MASS, ObjectSamples

BOX_SIDE = 0.1  # [m] incline's cube
FINGERTIP = 0.002  # [m] radius of the pinch's fingertip spheres
BLOCK_LENGTH = 10.0  # [m] the pinch block's faces along z: the fingers stay on them as it slides


@dataclass(frozen=True)
class MujocoSettings:
    """MuJoCo's options for a run.

    Attributes:
        dt: ``timestep`` [s]. impratio: the ratio of frictional to normal impedance [-].
        noslip_iterations: iterations of the noslip solver (0: off). cone: ``elliptic`` or ``pyramidal``.
        timeconst: solref's time constant [s] (None: 2 dt / zeta, zeta the damping ratio: the stiffest
            MuJoCo allows, 2 dt, keeps the contact's frequency 1 / (timeconst zeta) at 1 / (2 dt); below
            it a bouncing contact (zeta < 1) is unstable and gains energy).
        solimp: the impedance (dmin, dmax, width [m]).
        tolerance, iterations: the main solver's.
    """

    dt: float
    impratio: float = 1.0
    noslip_iterations: int = 0
    cone: str = "elliptic"
    timeconst: float | None = None
    solimp: tuple[float, float, float] = (0.9, 0.95, 0.001)
    tolerance: float = 1e-10
    iterations: int = 100

    def label(self) -> str:
        """A short description for tables."""
        text = f"{self.cone}, impratio {self.impratio:g}, dt {self.dt:g} s"
        if self.noslip_iterations:
            text += f", noslip {self.noslip_iterations}"
        if self.solimp != MujocoSettings.solimp:
            text += f", solimp {' '.join(f'{x:g}' for x in self.solimp)}"
        return text


@dataclass(frozen=True)
class MujocoScene:
    """MJCF text (without options), start and applied forces of a scene.

    Attributes:
        body: the worldbody's content. gravity: [m/s^2]. qvel0: the start's velocities (MuJoCo's order).
        qfrc: constant applied generalized forces [N]. damping_ratio: solref's (1: no bounce).
    """

    body: str
    gravity: tuple[float, float, float]
    qvel0: np.ndarray
    qfrc: np.ndarray
    damping_ratio: float = 1.0


def _v(values) -> str:
    return " ".join(f"{float(x):.17g}" for x in values)


def incline(theta: float, mu: float, v_down: float = 0.0, v_across: float = 0.0) -> MujocoScene:
    """The incline: a box on z = 0 under gravity tilted by ``theta`` [rad], friction ``mu``."""
    half = BOX_SIDE / 2
    body = (
        f'<geom type="plane" size="0 0 1" friction="{mu!r} 0 0"/>'
        f'<body pos="0 0 {half!r}"><freejoint/><geom type="box" size="{_v([half] * 3)}" mass="1" '
        f'friction="{mu!r} 0 0"/></body>'
    )
    gravity = (GRAVITY * math.sin(theta), 0.0, -GRAVITY * math.cos(theta))
    return MujocoScene(body, gravity, np.array([v_down, v_across, 0, 0, 0, 0.0]), np.zeros(6))


def box_stack(count: int, mu: float) -> MujocoScene:
    """box-stack: ``count`` 1 kg cubes of side BOX_SIDE stacked at rest on z = 0, friction ``mu`` (MuJoCo's box-plane
    and box-box collisions: four corners per face pair, as pinstab's contacts found from geometry)."""
    half = BOX_SIDE / 2
    body = f'<geom type="plane" size="0 0 1" friction="{mu!r} 0 0"/>' + "".join(
        f'<body pos="0 0 {half + k * BOX_SIDE!r}"><freejoint/><geom type="box" size="{_v([half] * 3)}" mass="1" '
        f'friction="{mu!r} 0 0"/></body>'
        for k in range(count)
    )
    return MujocoScene(body, (0.0, 0.0, -GRAVITY), np.zeros(6 * count), np.zeros(6 * count))


def sphere_spin(v0: float, omega0: float, mu: float, radius: float) -> MujocoScene:
    """sphere-spin: a 1 kg solid sphere of ``radius`` on z = 0 thrown at ``v0`` with backspin ``omega0``."""
    body = (
        f'<geom type="plane" size="0 0 1" friction="{mu!r} 0 0"/>'
        f'<body pos="0 0 {radius!r}"><freejoint/><geom type="sphere" size="{radius!r}" mass="1" '
        f'friction="{mu!r} 0 0"/></body>'
    )
    return MujocoScene(body, (0.0, 0.0, -GRAVITY), np.array([v0, 0, 0, 0, -omega0, 0.0]), np.zeros(6))


def restitution_damping(restitution: float) -> float:
    """The damping ratio [-] of a linear spring-damper whose bounce keeps ``restitution`` e of the
    speed: ``-ln e / sqrt(pi^2 + ln^2 e)`` (1 for e = 0)."""
    if restitution <= 0.0:
        return 1.0
    log = math.log(restitution)
    return -log / math.sqrt(math.pi**2 + log**2)


def bouncing_ball(height: float, restitution: float) -> MujocoScene:
    """bouncing-ball: a frictionless 1 kg sphere dropped from the gap ``height`` [m]."""
    body = (
        '<geom type="plane" size="0 0 1" condim="1"/>'
        f'<body pos="0 0 {BALL_RADIUS + height!r}"><freejoint/>'
        f'<geom type="sphere" size="{BALL_RADIUS!r}" mass="1" condim="1"/></body>'
    )
    return MujocoScene(body, (0.0, 0.0, -GRAVITY), np.zeros(6), np.zeros(6), restitution_damping(restitution))


def pinch(mu: float, squeeze: float, mass: float) -> MujocoScene:
    """pinch: the block held by two fingers pushed with ``squeeze`` [N] each, friction ``mu``."""
    half = PINCH_BLOCK / 2
    fingers = "".join(
        f'<body pos="{side * (half + FINGERTIP)!r} 0 0"><joint type="slide" axis="1 0 0"/>'
        f'<geom type="sphere" size="{FINGERTIP!r}" mass="{PINCH_FINGER_MASS!r}" friction="{mu!r} 0 0"/></body>'
        for side in (-1.0, 1.0)
    )
    inertia = mass * PINCH_BLOCK**2 / 6
    body = (
        f'<body><freejoint/><inertial pos="0 0 0" mass="{mass!r}" diaginertia="{_v([inertia] * 3)}"/>'
        f'<geom type="box" size="{half!r} {half!r} {BLOCK_LENGTH / 2!r}" friction="{mu!r} 0 0"/></body>{fingers}'
    )
    qfrc = np.zeros(8)
    qfrc[6], qfrc[7] = squeeze, -squeeze  # toward the block
    return MujocoScene(body, (0.0, 0.0, -GRAVITY), np.zeros(8), qfrc)


def mjcf(scene: MujocoScene, settings: MujocoSettings) -> str:
    """The MJCF text of ``scene`` with ``settings``."""
    timeconst = 2 * settings.dt / scene.damping_ratio if settings.timeconst is None else settings.timeconst
    return (
        f'<mujoco><option timestep="{settings.dt!r}" gravity="{_v(scene.gravity)}" cone="{settings.cone}" '
        f'impratio="{settings.impratio!r}" noslip_iterations="{settings.noslip_iterations}" '
        f'tolerance="{settings.tolerance!r}" iterations="{settings.iterations}"/>'
        f'<default><geom solref="{timeconst!r} {scene.damping_ratio!r}" solimp="{_v(settings.solimp)}"/></default>'
        f"<worldbody>{scene.body}</worldbody></mujoco>"
    )


def run_mujoco(
    scene: MujocoScene, settings: MujocoSettings, duration: float, every: int
) -> tuple[ObjectSamples, float]:
    """Step ``scene`` for ``duration`` [s], a sample of the free body every ``every`` steps (the steps
    between inside MuJoCo); returns the samples (world axes) and the CPU seconds of the loop.

    Raises:
        PinstabError: mujoco is not installed.
    """
    try:
        import mujoco
    except ImportError:
        raise PinstabError("the MuJoCo peer needs mujoco: pip install 'pinstab[bench]'") from None
    model = mujoco.MjModel.from_xml_string(mjcf(scene, settings))
    data = mujoco.MjData(model)
    data.qvel[:] = scene.qvel0
    data.qfrc_applied[:] = scene.qfrc
    samples = round(duration / settings.dt) // every + 1
    qpos, qvel = np.empty((samples, model.nq)), np.empty((samples, model.nv))
    qpos[0], qvel[0] = data.qpos, data.qvel
    began = time.process_time()
    for k in range(1, samples):
        mujoco.mj_step(model, data, every)
        qpos[k], qvel[k] = data.qpos, data.qvel
    cpu = time.process_time() - began
    angular = np.array(
        [pin.Quaternion(*q[3:7]).toRotationMatrix() @ w for q, w in zip(qpos, qvel[:, 3:6], strict=True)]
    )
    t = np.arange(samples) * every * settings.dt
    return ObjectSamples(t, qpos[:, :3].copy(), qvel[:, :3].copy(), angular), cpu

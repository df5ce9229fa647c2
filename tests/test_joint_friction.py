"""Dry joint friction (``joint-friction``, MJCF ``frictionloss``): stick and slip at events against closed forms (a
wheel spun down by its friction, a pendulum held or let slip) and against MuJoCo's run of the same MJCF file (its
friction soft: the difference measured, shrinking as MuJoCo's friction is made stiffer), and the modes that cannot take
it refusing it by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pinstab
from pinstab.errors import PinstabError, SceneError
from pinstab.scene import scene_from_dict
from pinstab.simulate import default_contacts

WHEEL_I, WHEEL_F, OMEGA0 = 0.02, 0.05, 3.0  # [kg m^2] about the axle, [N m], [rad/s]
MASS, COM, INERTIA, GRAVITY = 2.0, 0.5, 0.01, 9.81  # [kg], [m] below the hinge, [kg m^2] about the COM, [m/s^2]
THETA0 = 1.2  # [rad] the pendulum's start, at rest
HOLD = MASS * GRAVITY * COM * math.sin(THETA0)  # [N m] the torque that holds it there: 8.94 N m
HINGE_I = INERTIA + MASS * COM**2  # [kg m^2] about the hinge


def _robot(inertia: str, axis: str, com: float) -> str:
    return f"""<robot name="r"><link name="base"/>
  <link name="body"><inertial><origin xyz="0 0 {-com}"/><mass value="{MASS}"/><inertia {inertia}/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="body"/><axis xyz="{axis}"/>
    <limit lower="0" upper="0" effort="1" velocity="1"/></joint></robot>"""


def _scene(urdf: str, friction: float, q: float, v: float):
    entry = {"name": "hinge/frictionloss", "kind": "joint-friction", "joint": "hinge", "friction": friction}
    return scene_from_dict(
        {
            "robot": {"urdf_text": urdf},
            "gravity": [0.0, 0.0, -GRAVITY],
            "forces": [entry],
            "initial": {"q": {"hinge": q}, "v": {"hinge": v}},
        },
        name="friction",
    )


def _wheel():
    """A disc on a vertical axle (gravity along it: no torque), spun at OMEGA0, its friction WHEEL_F."""
    inertia = f'ixx="0.01" iyy="0.01" izz="{WHEEL_I}" ixy="0" ixz="0" iyz="0"'
    return _scene(_robot(inertia, "0 0 1", 0.0), WHEEL_F, 0.0, OMEGA0)


def _pendulum(friction: float):
    """A pendulum on a horizontal hinge from rest at THETA0, its friction ``friction``."""
    inertia = f'ixx="{INERTIA}" iyy="{INERTIA}" izz="{INERTIA}" ixy="0" ixz="0" iyz="0"'
    return _scene(_robot(inertia, "0 1 0", COM), friction, THETA0, 0.0)


def test_wheel_spins_down_and_stays():
    """The wheel decelerates at f/I (its velocity omega0 - f t / I at every sample to 1e-9 rad/s), stops at
    omega0 I / f (the event within 1e-9 s: measured 2.2e-13 s), its angle there omega0^2 I / (2 f), and stays:
    |v| = 0 and q unchanged to the last sample."""
    run = pinstab.simulate(_wheel(), duration=2.0, dt=0.01)
    assert run.info.path == "contact-events" and "joint friction" in run.info.path_reason
    stop = OMEGA0 * WHEEL_I / WHEEL_F  # 1.2 s
    stops = [e for e in run.info.contact_events if e["to"] == "sticking"]
    assert len(stops) == 1 and stops[0]["cause"] == "slip velocity reached zero at hinge/frictionloss"
    assert abs(stops[0]["t"] - stop) <= 1e-9
    t, v, q = run.t, run.v[:, 0], run.q[:, 0]
    slipping = t < stop - 1e-6
    np.testing.assert_allclose(v[slipping], OMEGA0 - WHEEL_F / WHEEL_I * t[slipping], rtol=0, atol=1e-9)
    assert np.all(v[~slipping] == 0.0)
    np.testing.assert_allclose(q[~slipping], OMEGA0**2 * WHEEL_I / (2 * WHEEL_F), rtol=0, atol=1e-9)
    assert np.all(q[~slipping] == q[-1])


def test_pendulum_held_by_its_friction():
    """A friction above m g l sin(theta0) holds the pendulum where it starts: q = theta0 and v = 0 exactly over 1 s,
    its friction torque m g l sin(theta0) (to 1e-9 N m) against gravity's."""
    run = pinstab.simulate(_pendulum(1.1 * HOLD), duration=1.0, dt=0.01)
    assert np.all(run.q[:, 0] == THETA0) and np.all(run.v[:, 0] == 0.0)
    (start,) = run.info.contact_events
    assert start["to"] == "sticking" and abs(start["force"][0] - HOLD) <= 1e-9


def test_pendulum_slips_with_the_closed_form_acceleration():
    """A friction below m g l sin(theta0) lets the pendulum slip from rest: the finite difference of the run's
    velocity over its first 1e-5 s is -(m g l sin(theta0) - f) / I (to 1e-6 rad/s^2), the friction's torque +f."""
    friction = 0.5 * HOLD
    h = 1e-5  # [s]
    run = pinstab.simulate(_pendulum(friction), duration=10 * h, dt=h)
    expected = -(HOLD - friction) / HINGE_I
    assert abs((run.v[1, 0] - run.v[0, 0]) / h - expected) <= 1e-6
    (start,) = run.info.contact_events
    assert start["to"] == "sliding" and start["force"][0] == pytest.approx(friction, abs=1e-12)


MJCF = """<mujoco>
 <option timestep="1e-4" integrator="RK4"><flag contact="disable"/></option>
 <worldbody><body name="rod"><joint name="hinge" type="hinge" axis="0 1 0" frictionloss="{friction}" {soft}/>
 <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="2"/></body></worldbody>
 <keyframe><key qpos="1.2"/></keyframe>
</mujoco>"""
STIFF = 'solreffriction="0.0005 1" solimpfriction="0.999 0.9999 0.001"'  # MuJoCo's friction made near-rigid


@pytest.mark.parametrize(
    ("friction", "default_tol", "stiff_tol"),
    [
        (0.5, 1.5e-2, 1e-3),  # slips, reverses at 0.636 s (measured 1.04e-2 rad; stiff 2.8e-4)
        (2.0, 3e-3, 1e-5),  # slips, then sticks at 0.645 s (measured 1.8e-3 rad; stiff 6.0e-7)
        (5.0, 3e-2, 1e-4),  # held from the start: MuJoCo's creep (measured 2.77e-2 rad; stiff 6.7e-6)
    ],
)
def test_mujoco_frictionloss(tmp_path, friction, default_tol, stiff_tol):
    """A pendulum with frictionloss read from MJCF against MuJoCo's run of the same file (RK4 at 1e-4 s, contacts
    off) over 1 s: with MuJoCo's default soft friction (solreffriction 0.02 1: a held joint creeps, a slip's friction
    ramps in near its reversal) within the measured difference and a margin; with MuJoCo's friction made near-rigid
    (solreffriction 0.0005, solimpfriction 0.999 0.9999) the difference shrinks to the stiff tolerance: what remains is
    the softness."""
    from mujoco_twin import largest_difference, twins, written

    differences = []
    for soft in ("", STIFF):
        path = written(tmp_path, "pendulum.xml", MJCF.format(friction=friction, soft=soft))
        scene, model = twins(path)
        assert [f.name for f in scene.forces] == ["hinge/frictionloss"]
        differences.append(largest_difference(scene, model))
    assert differences[0] <= default_tol and differences[1] <= stiff_tol
    assert differences[1] < differences[0] / 10


def test_modes_without_joint_friction_refuse_it(tmp_path):
    """A scene with joint friction defaults to event-driven contacts; time-stepping contacts refuse it, naming the
    friction, its joint and the mode that takes it; a non-positive friction and an MJCF frictionloss on a ball joint
    are refused by name."""
    scene = _wheel()
    assert default_contacts(scene) == "event"
    with pytest.raises(PinstabError, match=r"hinge/frictionloss \(joint hinge\).*contacts='event'"):
        pinstab.simulate(scene, duration=0.1, contacts="stepping")
    with pytest.raises(SceneError, match="friction must be > 0"):
        _pendulum(0.0)
    path = tmp_path / "free.xml"
    path.write_text(
        '<mujoco><worldbody><body name="b"><freejoint name="root"/><geom size="0.1"/>'
        '<body name="c"><joint name="ball" type="ball" frictionloss="0.1"/><geom size="0.1"/></body>'
        "</body></worldbody></mujoco>"
    )
    with pytest.raises(SceneError, match="joint 'ball'.*frictionloss=0.1 on a ball joint"):
        scene_from_dict({"robot": {"mjcf": path.name}}, base_dir=tmp_path)


SLIDER = """<robot name="slider"><link name="base"/>
  <link name="carriage"><inertial><mass value="0"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="block"><inertial><mass value="{mass}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
  </inertial></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="carriage"/><child link="block"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0" effort="1" velocity="1"/></joint></robot>"""
SLIDER_MU, SLIDER_F = 0.3, 1.0  # the floor's Coulomb coefficient [-], the x slide's dry friction [N]


def _slider(push: float, speed: float):
    """A 2 kg block on a floor (a plane contact with Coulomb friction SLIDER_MU) carried by an x slide with dry
    friction SLIDER_F, pushed along x by ``push`` [N], starting at ``speed`` [m/s]."""
    forces = [
        {"name": "x/friction", "kind": "joint-friction", "joint": "x", "friction": SLIDER_F},
        {"name": "push", "kind": "joint-torque", "joint": "x", "torque": push},
    ]
    return scene_from_dict(
        {
            "robot": {"urdf_text": SLIDER.format(mass=2.0)},
            "gravity": [0.0, 0.0, -GRAVITY],
            "contacts": [{"name": "floor", "kind": "plane-contact", "frame_a": "block", "mu": SLIDER_MU}],
            "forces": forces,
            "initial": {"v": {"x": speed}},
        },
        name="slider",
    )


def test_joint_friction_beside_a_contact():
    """The slide's dry friction and the floor's Coulomb friction resist together (contact and joint modes chosen
    together): a push above their sum f + mu m g accelerates the block at (push - f - mu m g) / m (to 1e-9 m/s^2), a
    push below it holds it (v = 0 exactly), and a block sent at 2 m/s stops at v0 m / (f + mu m g), both the joint and
    the contact sticking there (within 1e-9 s: measured 4.8e-13 s)."""
    resisting = SLIDER_F + SLIDER_MU * 2.0 * GRAVITY  # [N]: 6.886
    pushed = pinstab.simulate(_slider(resisting + 3.0, 0.0), duration=0.5, dt=0.01)
    np.testing.assert_allclose(pushed.v[:, 0], 1.5 * pushed.t, rtol=0, atol=1e-9)
    held = pinstab.simulate(_slider(resisting - 0.5, 0.0), duration=0.5, dt=0.01)
    assert np.all(held.v[:, 0] == 0.0)
    stopped = pinstab.simulate(_slider(0.0, 2.0), duration=1.0, dt=0.01)
    stop = 2.0 * 2.0 / resisting
    stops = [(e["contact"], e["t"]) for e in stopped.info.contact_events if e["to"] == "sticking"]
    assert [name for name, _ in stops] == ["x/friction", "floor"]
    assert all(abs(t - stop) <= 1e-9 for _, t in stops)
    assert np.all(stopped.v[stopped.t > stop, 0] == 0.0)

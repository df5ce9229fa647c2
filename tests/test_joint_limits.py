"""Joint limits as unilateral rows: the panda-anchor closed chain held inside its limits, a run without limits
unchanged, the active set against Pinocchio's JointLimitConstraintModel, and a pendulum against its closed form."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.special import ellipk, ellipkinc

import pinstab
from pinstab.cli import main
from pinstab.constraints.joint_limits import joint_limits
from pinstab.errors import JointLimitsWarning, SceneError
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict
from pinstab.solvers.contact_modes import ModeDynamics

MASS, COM, INERTIA, GRAVITY = 2.0, 0.5, 0.01, 9.81  # [kg], [m] below the hinge, [kg m^2] about the COM, [m/s^2]
LOWER, START = 0.4, 1.2  # [rad]: the pendulum falls from rest at START onto its lower limit
RAMP, TORQUE = (1.0, 2.0), 10.0  # [s], [N m]: a torque ramping from 0 to TORQUE pulls it off the limit


def _pendulum_urdf(lower: float, upper: float) -> str:
    return f"""<robot name="pendulum">
  <link name="base"/>
  <link name="rod">
    <inertial><origin xyz="0 0 {-COM}"/><mass value="{MASS}"/>
      <inertia ixx="{INERTIA}" iyy="{INERTIA}" izz="{INERTIA}" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 1 0"/>
    <limit lower="{lower}" upper="{upper}" effort="100" velocity="100"/></joint>
</robot>"""


def _pendulum(lower: float = LOWER, upper: float = 3.0):
    forces = [{"name": "pull", "kind": "joint-torque", "joint": "hinge", "table": [[RAMP[0], 0.0], [RAMP[1], TORQUE]]}]
    return scene_from_dict(
        {
            "robot": {"urdf_text": _pendulum_urdf(lower, upper)},
            "gravity": [0.0, 0.0, -GRAVITY],
            "forces": forces,
            "initial": {"q": {"hinge": START}},
        },
        name="pendulum",
    )


def _panda(duration: float):
    return pinstab.simulate("panda-anchor", duration=duration)


@pytest.fixture(scope="module")
def panda_run():
    return _panda(5.0)


def test_panda_anchor_stays_inside_its_limits(panda_run):
    """Over 5 s the default run reaches limits (event path) and no joint leaves its range by more than 1e-8 rad."""
    model = pinstab.load_scene("panda-anchor").model
    q = np.asarray(panda_run.q)
    beyond = max(np.max(model.lowerPositionLimit - q), np.max(q - model.upperPositionLimit))
    assert beyond <= 1e-8
    info = panda_run.info
    assert info.path == "contact-events" and "joint limits" in info.path_reason
    reached = {e["contact"] for e in info.contact_events if e["to"] == "closing"}
    assert {"panda_joint2 lower", "panda_joint6 upper", "panda_joint7 upper"} <= reached
    assert info.limits_active_s["panda_joint2 lower"] > 1.0
    assert panda_run.summary()["max_position_drift"] <= 1e-8  # the closure held through the impacts


def test_ignore_limits_is_the_run_of_a_model_without_limits(capsys):
    """limits=False (and --ignore-limits) is today's held run: the same as the run of the model whose limits are
    removed (lower = upper: no limit given), to 1e-12, and the CLI prints the same figures."""
    ignored = pinstab.simulate("panda-anchor", duration=1.0, limits=False)
    assert pinstab.simulate(_pendulum(-3.0, 3.0), duration=0.1).info.limits_active_s == {}  # limits, none reached
    assert pinstab.simulate("fourbar", duration=0.1).info.limits_active_s is None  # pin joints: no limits
    scene = pinstab.load_scene("panda-anchor")
    scene.model.lowerPositionLimit[:] = 0.0
    scene.model.upperPositionLimit[:] = 0.0
    unlimited = pinstab.simulate(scene, duration=1.0)
    assert ignored.info.path == unlimited.info.path == "native"
    assert np.max(np.abs(ignored.q - unlimited.q)) <= 1e-12
    assert np.max(np.abs(ignored.v - unlimited.v)) <= 1e-12
    assert ignored.info.limits_active_s is None and unlimited.info.limits_active_s is None
    main(["run", "panda-anchor", "--ignore-limits", "--json", "--quiet"])
    printed = capsys.readouterr().out
    assert '"max_position_drift": ' + repr(ignored.summary()["max_position_drift"]) in printed
    assert "limits_active_s" not in printed


@pytest.mark.parametrize("t", [0.1, 1.0, 1.7])
def test_active_set_agrees_with_pinocchio(panda_run, t):
    """At three states of the run (no limit held; joint2's lower held; joint2's lower and joint7's upper held),
    the limits the event path holds are those Pinocchio's JointLimitConstraintModel selects near their bound
    (margin 1e-9 rad), with the same Jacobian rows."""
    scene = pinstab.load_scene("panda-anchor")
    model = scene.model
    k = int(np.argmin(np.abs(panda_run.t - t)))
    q, time = panda_run.q[k], float(panda_run.t[k])
    held = set()
    for event in panda_run.info.contact_events:  # the limits held at `time`, from the run's events
        if event["t"] <= time:
            held.discard(event["contact"]) if event["to"] != "active" else held.add(event["contact"])
    joints = pin.StdVec_Index()
    for j in range(1, model.njoints):
        joints.append(j)
    margin = np.full(model.nq, 1e-9)
    constraint = pin.JointLimitConstraintModel(
        model, joints, model.lowerPositionLimit, model.upperPositionLimit, margin
    )
    constraint.makeSelectionFilteredByLimitProximity(q)
    data, constraint_data = model.createData(), constraint.createData()
    pin.forwardKinematics(model, data, q)
    constraint.calc(model, data, constraint_data)
    table = joint_limits(model).limits  # lower limits of joints 1..7, then upper: Pinocchio's activable order
    by_side = sorted(table, key=lambda limit: (limit.side != "lower", limit.index_v))
    selected = [by_side[i].name for i in constraint.active_idx_in_activable()]
    assert set(selected) == held
    assert len(held) == {0.1: 0, 1.0: 1, 1.7: 2}[t]
    dynamics = ModeDynamics(ConstrainedModel(scene), [], table)
    dynamics.active = [limit.name in held for limit in table]
    terms = dynamics.model.dynamics_terms(q, panda_run.v[k], time)
    rows = dynamics.bilateral_rows(terms, q, panda_run.v[k])[0][scene.constraint_set.rows :]
    ours = {limit.name: row for limit, row in zip([x for x in table if x.name in held], rows, strict=True)}
    theirs = np.reshape(constraint.jacobian(model, data, constraint_data), (-1, model.nv))
    for name, row in zip(selected, theirs, strict=True):
        assert np.array_equal(ours[name], row)


def test_pendulum_reaches_holds_and_leaves_its_limit_as_in_closed_form():
    """A pendulum falls from rest at 1.2 rad onto its lower limit 0.4 rad at the time the complete and incomplete
    elliptic integrals give, stops there (e = 0), is held with the reaction m g c sin(theta_l), and is released
    when a torque ramp reaches that reaction."""
    run = pinstab.simulate(_pendulum(), duration=2.0, dt=1e-2)
    inertia = INERTIA + MASS * COM**2
    omega = math.sqrt(MASS * GRAVITY * COM / inertia)
    k2 = math.sin(START / 2) ** 2
    psi = math.asin(math.sin(LOWER / 2) / math.sqrt(k2))
    t_reach = (ellipk(k2) - ellipkinc(psi, k2)) / omega
    reaction = MASS * GRAVITY * COM * math.sin(LOWER)
    t_release = RAMP[0] + (RAMP[1] - RAMP[0]) * reaction / TORQUE
    events = run.info.contact_events
    assert [(e["contact"], e["from"], e["to"]) for e in events] == [
        ("hinge lower", "separated", "closing"),
        ("hinge lower", "closing", "active"),
        ("hinge lower", "active", "separated"),
    ]
    assert abs(events[0]["t"] - t_reach) <= 1e-9
    assert events[0]["impulse"][0] == pytest.approx(
        inertia * omega * math.sqrt(2 * (math.cos(LOWER) - math.cos(START))), rel=1e-8
    )
    assert events[0]["work"] == pytest.approx(-MASS * GRAVITY * COM * (math.cos(LOWER) - math.cos(START)), rel=1e-8)
    assert events[1]["force"][0] == pytest.approx(reaction, rel=1e-9)
    assert abs(events[2]["t"] - t_release) <= 1e-9
    held = (run.t > t_reach + 1e-6) & (run.t < t_release)
    assert np.max(np.abs(run.q[held, 0] - LOWER)) <= 1e-10
    assert run.info.limits_active_s["hinge lower"] == pytest.approx(t_release - t_reach, abs=2e-9)
    assert run.q[-1, 0] > LOWER + 1e-3  # pulled off the limit


def test_limits_read_from_the_urdf_and_bad_bounds_refused():
    """lower == upper is no limit (said by ``pinstab check``), lower > upper a SceneError naming the joint."""
    table = joint_limits(_pendulum(0.0, 0.0).model)
    assert table.limits == [] and "no limit given" in table.unlimited["hinge"]
    assert joint_limits(_pendulum().model).ranges() == {"hinge": [LOWER, 3.0]}
    with pytest.raises(SceneError, match="joint hinge: its lower limit 1 is above its upper limit 0.5"):
        _pendulum(1.0, 0.5)


def test_check_reports_limits(capsys):
    main(["check", "double-pendulum-servo", "--json"])
    printed = capsys.readouterr().out
    assert '"unlimited_joints"' in printed and "no limit given" in printed


def test_a_start_outside_the_limits_is_refused_and_a_scene_may_set_limits_aside():
    """A start 0.1 rad below the lower limit is a SceneError naming the joint, its position and bound, and the ways
    out; ``robot.ignore_limits`` makes those joints unlimited (the run is then the run without limits)."""
    scene = _pendulum(lower=1.3)
    with pytest.raises(SceneError, match=r"hinge = 1.2 beyond its lower limit 1.3.*robot.ignore_limits"):
        pinstab.simulate(scene, duration=0.01)
    data = {
        "robot": {"urdf_text": _pendulum_urdf(1.3, 3.0), "ignore_limits": ["hinge"]},
        "initial": {"q": {"hinge": START}},
    }
    aside = scene_from_dict(data, name="pendulum")
    assert joint_limits(aside.model).limits == []
    free = pinstab.simulate(aside, duration=0.1, dt=1e-2)
    unlimited = pinstab.simulate(aside, duration=0.1, dt=1e-2, limits=False)
    np.testing.assert_array_equal(free.q, unlimited.q)
    for bad, message in (("hinge", "must be a list of joint names or true"), (["elbow"], "unknown joint 'elbow'")):
        with pytest.raises(SceneError, match=message):
            scene_from_dict({**data, "robot": {**data["robot"], "ignore_limits": bad}})


def test_a_limit_left_beside_rolling_rows_keeps_the_held_run_with_a_warning():
    """The event path holds holonomic closures only: a rolling fingertip's Pfaffian rows would lose their drift
    correction there, so a run leaving a limit beside them keeps its held run (the run without limits), warned."""
    from test_rolling_contacts import fixed_ball

    scene = scene_from_dict(fixed_ball("point-friction"))
    with pytest.warns(JointLimitsWarning, match=r"wrist_x lower left at t = 0.78 s.*tip/rolling"):
        held = pinstab.simulate(scene, "mukharlyamov", "rk4", dt=1e-3, duration=1.0, solver="dense")
    free = pinstab.simulate(scene, "mukharlyamov", "rk4", dt=1e-3, duration=1.0, solver="dense", limits=False)
    np.testing.assert_array_equal(held.q, free.q)


def test_the_event_path_assembles_to_the_given_tolerance():
    """panda-anchor reaches a limit within 1 s and reruns on the event path: that path's assembly takes
    ``assembly_tol`` (it used its default) and its report reaches the run info (it was None)."""
    tight = pinstab.simulate("panda-anchor", duration=1.0, assembly_tol=1e-9, progress=False).info
    loose = pinstab.simulate("panda-anchor", duration=1.0, assembly_tol=1e-6, progress=False).info
    assert tight.path == loose.path == "contact-events"
    assert loose.assembly.tolerance == pytest.approx(1e3 * tight.assembly.tolerance, rel=1e-12)
    assert tight.assembly.residual <= tight.assembly.tolerance

"""Joint limits: two coupled limits whose impacts throw each other off settle, held together (they chattered for
ever, one impact every 7e-7 s), and the held path sees a limit left between two kept samples (a large
``record_every`` hid it). Against independent values: the energy balance of the impacts, the reactions and the
free link of the chain held on both limits (Pinocchio's dynamics, SciPy's integrator), a link's arrival at its
limit (the energy integral) and its impact's work."""

from __future__ import annotations

import math
import time

import numpy as np
import pinocchio as pin
import pytest
from fuzzing import time_limit
from scipy.integrate import quad, solve_ivp
from test_fuzz_tables import limited_chain_urdf

from pinstab.constraints.joint_limits import LimitWatch, joint_limits
from pinstab.errors import ContactInfeasibleError
from pinstab.integration import events
from pinstab.integration.events import LIMIT_SLACK
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate

GRAVITY = 9.81  # [m/s^2]
# the chain of the fuzzer's hang: j0 on limits 1e-4 rad apart, j1 swung at 5 rad/s onto its upper limit
CHATTER = {
    "gravity": [0.0, -GRAVITY, 0.0],
    "robot": {"urdf_text": limited_chain_urdf([(0.0, 1e-4), (-1.8622403991037992, -1.538477558662204), (0.0, 0.0)])},
    "initial": {"q": {"j0": 5e-5, "j1": -1.7003589788830016, "j2": 0.0}, "v": {"j1": 5.0}},
}
SETTLED = 0.053  # [s] after the last impact of the chatter (0.05247 s)
DURATION = 0.07  # [s]
TOLERANCE = 1e-8  # [rad] how far beyond a bound a joint may be (docs/guide/contacts.md: 1e-8 rad)
# one link on limits [-3, 0] rad, swung at 1 rad/s toward its upper limit 0.01 rad away, gravity turning it back
SWING = {
    "gravity": [0.0, -GRAVITY, 0.0],
    "robot": {"urdf_text": limited_chain_urdf([(-3.0, 0.0)])},
    "initial": {"q": {"j0": -0.01}, "v": {"j0": 1.0}},
}
MASS, COM, IZZ = 1.0, 0.15, 0.0075  # [kg], [m], [kg m^2]: each link of limited_chain_urdf


def _scene(document: dict):
    return scene_from_dict(document, name="chain")


@pytest.fixture(scope="module")
def chatter():
    with time_limit(20):
        return simulate(_scene(CHATTER), duration=DURATION)


def _impacts(run) -> list[dict]:
    return [e for e in run.info.contact_events if e["cause"] == "impact" and e["to"] == "closing"]


def test_coupled_limits_settle_within_the_duration(chatter) -> None:
    """The run ends at its duration after a bounded number of impacts, each dissipating, j0's lower and j1's upper
    limits then held together (both last switched to active), every joint within its limits."""
    assert chatter.info.t_end == pytest.approx(DURATION, abs=1e-12)
    impacts = _impacts(chatter)
    assert 10 <= len(impacts) <= 40, len(impacts)
    assert all(e["work"] <= 0.0 for e in impacts)
    last = {e["contact"]: e["to"] for e in chatter.info.contact_events}
    assert last["j0 lower"] == "active" and last["j1 upper"] == "active", last
    for limit in joint_limits(_scene(CHATTER).model).limits:
        assert limit.gaps(chatter.q).min() >= -TOLERANCE, limit.name


def test_chatter_energy_is_the_impacts_work(chatter) -> None:
    """Kinetic plus potential energy drops by the work of the impacts (impulse times the mean of the joint speeds
    before and after) and by nothing else: gravity is conservative, a held limit does no work."""
    lost = sum(e["work"] for e in _impacts(chatter))
    assert lost < -0.5  # [J] j1's impact at 5 rad/s
    assert chatter.energy[-1] - chatter.energy[0] == pytest.approx(lost, abs=1e-5)


def test_the_settled_chain_is_a_pendulum_on_two_pushing_limits(chatter) -> None:
    """After the chatter j0 and j1 rest on their bounds; their reactions (Pinocchio's mass matrix and bias forces
    with j0, j1 locked) push, and the free link j2 swings as the 1-DOF pendulum q2'' = -b_2(q, v) / M_22 that SciPy
    integrates from the first settled sample."""
    model = _scene(CHATTER).model
    data = model.createData()
    held = chatter.t >= SETTLED
    assert np.abs(chatter.v[held][:, :2]).max() <= 1e-9
    for q, v in zip(chatter.q[held], chatter.v[held], strict=True):
        mass = pin.crba(model, data, q)
        bias = pin.nle(model, data, q, v)
        a2 = -bias[2] / mass[2, 2]
        reactions = np.array([1.0, -1.0]) * (mass[:2, 2] * a2 + bias[:2])  # lower pushes +, upper pushes -
        assert reactions.min() > 0.0, reactions
    start = int(np.flatnonzero(held)[0])
    q_held = chatter.q[start].copy()

    def pendulum(_t: float, y: np.ndarray) -> list[float]:
        q, v = q_held.copy(), np.zeros(3)
        q[2], v[2] = y
        return [y[1], -pin.nle(model, data, q, v)[2] / pin.crba(model, data, q)[2, 2]]

    times = chatter.t[start:]
    reference = solve_ivp(pendulum, (times[0], times[-1]), chatter.q[start, 2:3].tolist() + [chatter.v[start, 2]],
                          t_eval=times, rtol=1e-12, atol=1e-12, method="DOP853")  # fmt: skip
    # the samples come from the dense output of steps up to 0.017 s long: 2e-8 of the speed (12 rad/s)
    assert np.abs(reference.y[0] - chatter.q[start:, 2]).max() <= 1e-8
    assert np.abs(reference.y[1] - chatter.v[start:, 2]).max() <= 1e-6


def test_chatter_is_deterministic(chatter) -> None:
    again = simulate(_scene(CHATTER), duration=DURATION)
    assert np.array_equal(again.q, chatter.q) and again.info.contact_events == chatter.info.contact_events


def test_a_chatter_that_does_not_settle_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    """A released limit counting as reached LIMIT_SLACK below each release (the rule before: each return a slack
    further, gravity's work over it feeding the chatter) ends the run after CHATTER_IMPACTS impacts each within
    CHATTER_GAP of the last, naming the two limits, with the partial trajectory."""
    monkeypatch.setattr(events, "CHATTER_IMPACTS", 50)
    monkeypatch.setattr(
        events.EventLoop, "_release_floor", lambda self, i, q, v: events._floor(self.dynamics.limits[i], q)
    )
    with time_limit(20), pytest.raises(ContactInfeasibleError) as raised:
        simulate(_scene(CHATTER), duration=DURATION)
    message = str(raised.value)
    assert "the joint limits j0 lower, j1 upper were reached 50 times in a row" in message, message
    assert "within 1e-06 s of the last" in message and "ignore-limits" in message
    assert raised.value.trajectory.info.stopped["t"] == pytest.approx(0.0525, abs=1e-3)


def _arrival() -> tuple[float, float]:
    """When [s] the swung link of :data:`SWING` reaches q = 0 without limits, and its speed there [rad/s]: energy,
    I q'^2 / 2 + m g c sin q constant about the hinge (I = Izz + m c^2), and t = int dq / q'."""
    inertia, weight = IZZ + MASS * COM**2, MASS * GRAVITY * COM
    q0, v0 = -0.01, 1.0

    def speed(q: float) -> float:
        return math.sqrt(v0**2 - 2.0 * weight * (math.sin(q) - math.sin(q0)) / inertia)

    time, _ = quad(lambda q: 1.0 / speed(q), q0, 0.0, epsabs=1e-14, epsrel=1e-13)
    return time, speed(0.0)


@pytest.mark.parametrize("every", [1, 50])
def test_a_limit_left_between_kept_samples_is_held(every: int) -> None:
    """Kept every step or one in 50, the run leaves the held path at the same step for the event path, whose impact
    on j0's upper limit comes at the closed-form time and takes the link's kinetic energy there (restitution 0);
    no sample beyond the limit."""
    run = simulate(_scene(SWING), duration=0.2, record_every=every)
    assert run.info.path == "contact-events"
    assert run.info.path_reason == "joint limits: j0 upper left at t = 0.018 s on the held path"
    (impact,) = _impacts(run)
    time, speed = _arrival()
    assert impact["contact"] == "j0 upper"
    assert impact["t"] == pytest.approx(time, abs=1e-9)
    # the error-controlled loop's global error at its rtol 1e-10: 3e-7 of the work (3e-9 at rtol 1e-12)
    assert impact["work"] == pytest.approx(-0.5 * (IZZ + MASS * COM**2) * speed**2, rel=1e-6)
    assert run.q[:, 0].max() <= TOLERANCE


def test_limit_watch_names_the_first_step_beyond_a_bound() -> None:
    """A state whose gap (the core's ``sign (q - bound)``) is :data:`LIMIT_SLACK` beyond a bound, or less, is on it;
    further, the watch names the first step (and the first limit in the table at that step), at its time. (The gap
    of -3 - 1e-12 from -3 is exact, 1.00009e-12: beyond; half the slack is within it.)"""
    limits = joint_limits(_scene(SWING).model).limits  # j0 lower -3, upper 0
    watch = LimitWatch(limits, LIMIT_SLACK)
    watch.time = lambda k: 0.001 * k
    watch.see(0, np.array([LIMIT_SLACK]))
    watch.see_span(1, np.array([[-3.0 - 0.5 * LIMIT_SLACK], [-1.0]]))
    assert watch.left is None
    watch.see_span(3, np.array([[-1.0], [2 * LIMIT_SLACK], [-4.0]]))
    assert watch.left is not None and watch.left[0].name == "j0 upper" and watch.left[1] == pytest.approx(0.004)
    watch.see(7, np.array([-4.0]))
    assert watch.left[0].name == "j0 upper"  # the first one stays


def test_a_held_run_that_diverges_after_leaving_a_limit_is_run_with_the_limits(monkeypatch) -> None:
    """A held run that passed a limit and then diverged (a gripper's fingers through their stops into a singular
    loop, exit 3, ran fine with --contacts event): the divergence the limit would have prevented is not the answer;
    the run is the event path's with the limits held, the same samples to the last bit as asked for directly. A held
    run that diverged inside its limits still raises."""
    from pinstab.errors import DivergenceError
    from pinstab.simulate import api

    held = api.simulate_held

    def diverging(*args, **kwargs):
        trajectory = held(*args, **kwargs)
        raise DivergenceError(
            "non-finite state", float(trajectory.t[-1]), trajectory.q[-1], trajectory.v[-1], trajectory
        )

    monkeypatch.setattr(api, "simulate_held", diverging)
    run = simulate(_scene(SWING), duration=0.1)
    direct = simulate(_scene(SWING), duration=0.1, contacts="event")
    assert (
        run.info.path_reason
        == "joint limits: j0 upper left at t = 0.018 s on the held path, which then diverged at t = 0.1 s"
    )
    assert np.array_equal(run.t, direct.t) and np.array_equal(run.q, direct.q) and np.array_equal(run.v, direct.v)
    inside = {**SWING, "initial": {"q": {"j0": -1.5}, "v": {"j0": 0.0}}}
    with pytest.raises(DivergenceError, match="non-finite state"):
        simulate(_scene(inside), duration=0.1)


def test_a_run_restarted_for_a_limit_reports_both_attempts_in_its_wall_time(monkeypatch) -> None:
    """The held attempt that left the limit counts in the run's wall time (it reported the second attempt only): the
    held path made 0.3 s slower, the event-path run's wall time grows by at least that, and stays within the call's
    own time measured around it."""
    from pinstab.simulate import api

    held = api.simulate_held

    def slow_held(*arguments, **options):
        time.sleep(0.3)
        return held(*arguments, **options)

    monkeypatch.setattr(api, "simulate_held", slow_held)
    began = time.perf_counter()
    run = simulate(_scene(SWING), duration=0.05)
    outside = time.perf_counter() - began
    assert run.info.path == "contact-events"
    assert 0.3 <= run.wall_time <= outside
    assert run.wall_time == sum(run.info.timings.values())

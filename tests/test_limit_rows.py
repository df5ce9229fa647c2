"""Joint limits in the compiled core: the limit's row (kind 8) against finite differences and against the bound it
names, the watch and the limits' gaps on the core's rule, and a limits run's modes evaluated by the core kernel (the
same trajectory as the modes' numpy evaluation, the pendulum's fall onto its limit at the closed form's time and at a
SciPy reference's)."""

from __future__ import annotations

import importlib
import math
import pickle

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipk, ellipkinc
from test_joint_limits import COM, GRAVITY, INERTIA, LOWER, MASS, START, _pendulum

import pinstab
from pinstab.constraints.joint_limits import ActiveLimit, LimitWatch, joint_limits
from pinstab.kernels import (
    RowBlock,
    block_drift,
    block_jacobian,
    block_rate,
    block_residual,
    joint_limit_gap,
    joint_limit_gaps,
    joint_limit_rate,
    joint_limit_rates,
)
from pinstab.paths.core import CoreDynamics
from pinstab.solvers.contact_modes import ModeDynamics
from pinstab.solvers.core_modes import CORE_STATUS

contacts_module = importlib.import_module("pinstab.simulate.contacts")  # the module (pinstab.simulate: the function)
STEP = 1e-6  # [rad or m] central differences (the row is linear: their error is rounding, ~1e-10)


def _panda():
    scene = pinstab.load_scene("panda-anchor")
    return scene, joint_limits(scene.model).limits


def test_the_limit_row_is_its_gap_and_its_derivatives():
    """Every panda limit's row at a random state: residual sign (q_i - bound) (from the limit's own fields), the
    Jacobian the central difference of the residual along each velocity direction (pin.integrate) to 1e-9, G v the
    rate and JointLimit.speed, the drift the second difference along q(s) = q (+) s v (zero acceleration) to 1e-6,
    and no time term."""
    scene, limits = _panda()
    model = scene.model
    data = model.createData()
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(model)
    v = rng.normal(size=model.nv)
    assert len(limits) == 14
    for limit in limits:
        block = limit.row
        phi = block_residual(model, data, block, q, 0.0)
        assert phi.shape == (1,) and phi[0] == pytest.approx(limit.sign * (q[limit.index_q] - limit.bound), abs=1e-15)
        assert limit.gap(q) == phi[0]
        jacobian, time_term = block_jacobian(model, data, block, 0.0)
        differences = np.array(
            [
                (block_residual(model, data, block, pin.integrate(model, q, STEP * e), 0.0)[0]
                 - block_residual(model, data, block, pin.integrate(model, q, -STEP * e), 0.0)[0]) / (2 * STEP)
                for e in np.eye(model.nv)
            ]
        )  # fmt: skip
        np.testing.assert_allclose(jacobian[0], differences, rtol=0, atol=1e-9)
        assert np.count_nonzero(jacobian) == 1 and time_term[0] == 0.0
        rate = block_rate(model, data, block, v, 0.0)[0]
        assert rate == pytest.approx(jacobian[0] @ v, abs=1e-15) and limit.speed(v) == rate
        h = 1e-3
        second = (
            sum(
                w * block_residual(model, data, block, pin.integrate(model, q, s * h * v), 0.0)[0]
                for w, s in ((1.0, 1.0), (-2.0, 0.0), (1.0, -1.0))
            )
            / h**2
        )
        assert block_drift(model, data, block, 0.0)[0] == 0.0
        assert abs(second) <= 1e-6


def test_gaps_of_many_samples_and_the_watch_follow_the_bounds():
    """joint_limit_gaps over samples equals sign (q - bound) column by column (exactly: one rounding each); the watch
    fed a path that crosses joint4's upper bound at its 7th sample names it there, and one that stays inside by
    twice the slack names none."""
    scene, limits = _panda()
    qs = np.array([pin.randomConfiguration(scene.model) for _ in range(9)])
    gaps = joint_limit_gaps([limit.row for limit in limits], qs)
    expected = np.column_stack([limit.sign * (qs[:, limit.index_q] - limit.bound) for limit in limits])
    np.testing.assert_array_equal(gaps, expected)
    np.testing.assert_array_equal(limits[3].gaps(qs), expected[:, 3])
    rates = np.column_stack([limit.sign * qs[:, limit.index_v] for limit in limits])  # qs as velocities (nq = nv)
    np.testing.assert_array_equal(joint_limit_rates([limit.row for limit in limits], qs), rates)
    upper = next(limit for limit in limits if limit.name == "panda_joint4 upper")
    path = np.tile(scene.q0, (10, 1))
    path[:, upper.index_q] = np.linspace(upper.bound - 0.6, upper.bound + 0.3, 10)
    watch = LimitWatch(limits, 1e-12)
    watch.see_span(0, path)
    assert watch.left == (upper, 7.0)
    inside = LimitWatch(limits, 1e-12)
    inside.see_span(0, np.clip(path, scene.model.lowerPositionLimit + 2e-12, scene.model.upperPositionLimit - 2e-12))
    assert inside.left is None


def test_a_limit_keeps_its_fields_through_pickling_and_refuses_other_blocks():
    """A limit pickles without its compiled row (built again, the same gap); a block that is not a limit is refused
    by the gap functions (naming the kind)."""
    _, limits = _panda()
    q = pinstab.load_scene("panda-anchor").q0
    copy = pickle.loads(pickle.dumps(limits[0]))
    assert copy == limits[0] and copy.gap(q) == limits[0].gap(q)
    point = RowBlock(0, 1, -1, np.eye(4), np.eye(3))
    with pytest.raises(ValueError, match="joint_limit_gaps: a block that is not a joint limit"):
        joint_limit_gaps([point], q[None, :])
    with pytest.raises(ValueError, match="joint_limit_gap: a block that is not a joint limit"):
        joint_limit_gap(point, q)
    with pytest.raises(ValueError, match="joint_limit_rate: an index outside the state"):
        joint_limit_rate(limits[6].row, q[:3])
    assert ActiveLimit(limits[0]).compiled_rows() is limits[0].row


def _numpy_modes(monkeypatch):
    """Evaluate the modes by ModeDynamics' numpy solves (the path before the core took them)."""
    monkeypatch.setattr(contacts_module, "CoreModeDynamics", ModeDynamics)


@pytest.mark.parametrize(("scene", "duration", "dq"), [("pendulum", 2.0, 1e-11), ("panda-anchor", 1.0, 1e-9)])
def test_the_core_evaluates_the_modes_as_numpy_did(monkeypatch, scene, duration, dq):
    """A limits run's modes on the core kernel and by the numpy solves: the same events (to 1e-10 s) and q to ``dq``
    [rad] at every sample (measured: 4e-13 rad and 8e-14 s on the pendulum, 2e-10 rad and 9e-13 s on the panda, the
    solves' rounding carried by the error control through the impacts); the core solved every evaluation."""
    scene = _pendulum() if scene == "pendulum" else pinstab.load_scene(scene)
    core = pinstab.simulate(scene, duration=duration, dt=1e-2, progress=False)
    _numpy_modes(monkeypatch)
    numpy = pinstab.simulate(scene, duration=duration, dt=1e-2, progress=False)
    assert core.info.path == numpy.info.path == "contact-events"
    counts = core.info.solver_statistics.status_counts
    assert set(counts) == {CORE_STATUS} and CORE_STATUS not in numpy.info.solver_statistics.status_counts
    events = [(e["contact"], e["from"], e["to"]) for e in core.info.contact_events]
    assert events == [(e["contact"], e["from"], e["to"]) for e in numpy.info.contact_events]
    times = np.array(
        [[a["t"], b["t"]] for a, b in zip(core.info.contact_events, numpy.info.contact_events, strict=True)]
    )
    assert np.max(np.abs(times[:, 0] - times[:, 1]), initial=0.0) <= 1e-10
    assert core.t.shape == numpy.t.shape
    assert np.max(np.abs(core.q - numpy.q)) <= dq


def test_the_pendulum_reaches_its_limit_at_the_closed_form_and_the_scipy_time():
    """Released from rest at 1.2 rad, the pendulum reaches its lower limit 0.4 rad on the core at the time the
    elliptic integrals give, t = (K(k) - F(psi, k)) / omega (k = sin(theta0 / 2), sin psi = sin(theta_l / 2) / k), to
    1e-9 s, and at a SciPy DOP853 solve of I theta'' = -m g c sin(theta) at rtol 1e-12 located by its event to 1e-9 s
    (the two references agree to 1e-11 s)."""
    run = pinstab.simulate(_pendulum(), duration=1.0, dt=1e-2, progress=False)
    assert set(run.info.solver_statistics.status_counts) == {CORE_STATUS}
    inertia = INERTIA + MASS * COM**2
    omega = math.sqrt(MASS * GRAVITY * COM / inertia)
    k2 = math.sin(START / 2) ** 2
    t_closed = (ellipk(k2) - ellipkinc(math.asin(math.sin(LOWER / 2) / math.sqrt(k2)), k2)) / omega

    def reached(_t, y):
        return y[0] - LOWER

    reached.terminal, reached.direction = True, -1
    solution = solve_ivp(
        lambda _t, y: [y[1], -(omega**2) * math.sin(y[0])], (0.0, 2.0), [START, 0.0], method="DOP853", rtol=1e-12,
        atol=1e-14, events=reached,
    )  # fmt: skip
    t_scipy = float(solution.t_events[0][0])
    assert abs(t_scipy - t_closed) <= 1e-11
    t_event = run.info.contact_events[0]["t"]
    assert run.info.contact_events[0]["to"] == "closing"
    assert abs(t_event - t_closed) <= 1e-9 and abs(t_event - t_scipy) <= 1e-9


def test_an_evaluation_the_core_does_not_accept_is_solved_by_numpy(monkeypatch):
    """Where the core kernel refuses an evaluation (unusable: its residual missed), the modes' numpy solve takes it:
    a run whose every core evaluation is refused is the numpy run to the last bit, counted under ``contact modes``."""
    _numpy_modes(monkeypatch)
    numpy = pinstab.simulate(_pendulum(), duration=1.0, dt=1e-2, progress=False)
    monkeypatch.undo()

    def refused(self, q, v, tau, t, stage=0):
        self.unusable = True
        return np.full(q.size, np.nan)

    monkeypatch.setattr(CoreDynamics, "acceleration", refused)
    fallen = pinstab.simulate(_pendulum(), duration=1.0, dt=1e-2, progress=False)
    assert set(fallen.info.solver_statistics.status_counts) == {"contact modes"}
    np.testing.assert_array_equal(fallen.q, numpy.q)
    np.testing.assert_array_equal(fallen.v, numpy.v)

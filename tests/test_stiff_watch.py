"""The stiff-mode watch along the run and ``--integrator auto`` (issue 37; pinstab.integration.stiffness,
pinstab.simulate.integrator_choice), on stiff-fourbar against its Radau reference (pinstab.analysis.spring_chain)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinstab import PinstabError, StiffStepError, load_scene, simulate
from pinstab.analysis.spring_chain import scene_chain
from pinstab.cli import main
from pinstab.integration import INTEGRATORS, Integrator
from pinstab.integration import stepping as stepping_module
from pinstab.integration.stiffness import StiffWatch, implicit_integrators
from pinstab.kernels import SchemeStep
from pinstab.simulate.held import held_system
from pinstab.stability.criterion import mode_growth, mode_step_limit

DURATION = 1.0  # [s]
RK4_BOUND = 2.7853  # |h lambda| at which RK4's stability region meets the negative real axis


@pytest.fixture(scope="module")
def scene():
    return load_scene("stiff-fourbar")


class SubsteppedRK4(Integrator):
    """A stand-in for an implicit integrator (registered in a test only): 16 RK4 substeps per step, stable on
    stiff-fourbar's mode up to 16 x 0.315 ms."""

    implicit = True
    nodes = (0.0,)

    def __init__(self, system, options=None) -> None:
        super().__init__(system, options)
        self._rk4 = SchemeStep(3, None)

    def step(self, q, v, t, dt):
        h = dt / 16
        for i in range(16):
            q, v = self._rk4.step(self.system.acceleration, q, v, t + i * h, h)
        return q, v


@pytest.fixture
def fake_implicit(monkeypatch):
    """The registry of the explicit integrators and :class:`SubsteppedRK4` as ``implicit-midpoint``, for the test (the
    registry's own implicit integrators, if any, left out; restored after)."""
    explicit = {entry.name: entry for entry in INTEGRATORS.entries() if not getattr(entry.factory, "implicit", False)}
    monkeypatch.setattr(INTEGRATORS, "_entries", explicit)
    INTEGRATORS.register("implicit-midpoint", type("FakeMidpoint", (SubsteppedRK4,), {"name": "implicit-midpoint"}))
    return "implicit-midpoint"


@pytest.fixture
def no_implicit(monkeypatch):
    """The registry of the explicit integrators only, for the test."""
    explicit = {entry.name: entry for entry in INTEGRATORS.entries() if not getattr(entry.factory, "implicit", False)}
    monkeypatch.setattr(INTEGRATORS, "_entries", explicit)


def test_mode_growth_is_rk4s_polynomial_and_the_limit_its_real_bound():
    """|R| of RK4 on x' = lambda x is |1 + z + z^2/2 + z^3/6 + z^4/24| at z = h lambda (1.104 at z = -2.851); the limit
    is 2.7853 / |lambda| (the polynomial's real root); a complex pair's limit is inside the region's boundary."""
    for z in (-1.0, -2.5, -2.851, -3.2):
        assert mode_growth(complex(z / 1e-4), 1e-4, "rk4") == pytest.approx(
            abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24), rel=1e-12
        )
    assert mode_step_limit(complex(-7159.2), "rk4") * 7159.2 == pytest.approx(RK4_BOUND, rel=1e-4)
    assert mode_step_limit(complex(-7159.2), "euler") * 7159.2 == pytest.approx(2.0, rel=1e-6)
    pair = complex(-100.0, 1000.0)
    assert (
        mode_growth(pair, 0.999 * mode_step_limit(pair, "rk4"), "rk4")
        <= 1.0
        < mode_growth(pair, 1.001 * mode_step_limit(pair, "rk4"), "rk4")
    )


def test_above_the_runs_limit_the_watch_stops_before_the_blow_up(scene, capsys, no_implicit):
    """``pinstab run stiff-fourbar --dt 3.5e-4`` (RK4 inside the start's limit 0.389 ms, above the run's 0.315 ms) ended
    with exit 0 and its energy 8.8 J -> 6347 J. The watch stops it at the check of t = 0.28 s (step 800: the mode's
    |R| = 1.104 per step, a 2e4-fold growth over 100 steps) with exit 3, naming the element: the kept samples are the
    clean motion (energy at most the start's 8.816 J, the motion within 2e-2 rad of the Radau reference), the limit
    2.7853 / |lambda| of the reference's own Jacobian's stiffest eigenvalue at the stopped state (-8146 /s)."""
    code = main(["run", "stiff-fourbar", "--dt", "3.5e-4", "--quiet", "--json"])
    out, err = capsys.readouterr()
    assert code == 3 and "the run stopped at t = 0.28 s (step 800): dt = 0.35 ms is above rk4's stability" in err
    payload = json.loads(out)
    assert payload["stiff_mode"]["element"] == "rocker-spring" and payload["diverged_at"] == pytest.approx(0.28)
    with pytest.raises(StiffStepError) as caught:
        simulate(scene, integrator="rk4", dt=3.5e-4, duration=DURATION)
    error, finite = caught.value, caught.value.finite_trajectory
    assert finite.t[-1] == pytest.approx(0.245) and finite.energy.max() <= 8.8160 + 1e-4
    chain = scene_chain(scene)
    reference = chain.solve(scene.q0, scene.v0, finite.t)
    assert np.abs(finite.q - reference[:, :2]).max() < 2e-2
    stopped = error.trajectory
    measured = np.linalg.eigvals(chain.jacobian(0.28, np.r_[stopped.q[-1], stopped.v[-1], 0.0])[:4, :4])
    stiffest = measured[np.argmax(np.abs(measured))]
    assert error.eigenvalue == pytest.approx(stiffest, rel=1e-6) and stiffest.real == pytest.approx(-8146, abs=1)
    assert error.limit == pytest.approx(RK4_BOUND / abs(stiffest), rel=1e-4)
    assert "|R| = 1.104 per step there, 1.97e+04-fold" in str(error) and "implicit" not in str(error)  # none registered


@pytest.mark.parametrize("dt", [1e-4, 3e-4, 3.2e-4])
def test_below_the_limit_or_crossing_it_briefly_the_run_is_unchanged(scene, monkeypatch, dt):
    """At 0.1 ms and 0.3 ms (|h lambda| <= 2.65 over the run, inside 2.785) and at 0.32 ms (the limit crossed at two
    checks, |R| = 1.047 and 1.063: a 99- and 433-fold growth, below the 1e3 that stops) the run goes to its end with
    the same numbers to the last bit as without the watch, its final energy within 4e-3 J of the reference's 4.4677 J
    (the reference's mechanical energy after 1 s)."""
    run = simulate(scene, integrator="rk4", dt=dt, duration=DURATION)
    monkeypatch.setattr(stepping_module.StiffWatch, "of", classmethod(lambda cls, *arguments: None))
    unwatched = simulate(scene, integrator="rk4", dt=dt, duration=DURATION)
    assert run.t[-1] == DURATION and np.array_equal(run.q, unwatched.q) and np.array_equal(run.v, unwatched.v)
    chain = scene_chain(scene)
    end = chain.solve(scene.q0, scene.v0, np.array([0.0, DURATION]))[-1]
    assert abs(run.energy[-1] - chain.energy(end[:2], end[2:4])) < 4e-3


def test_the_watch_is_absent_where_no_stiff_element_limits_the_step(scene):
    """No watch (nothing added to the checks) on a scene without force elements, for an implicit integrator, under
    error control (the controller shortens its steps) or for an integrator the criterion does not know."""
    fourbar = load_scene("fourbar")
    system, stepper = held_system(fourbar, "baumgarte", "rk4", None, None, None, {})
    assert StiffWatch.of(system, stepper, 1e-3, 100) is None
    system, stepper = held_system(scene, "baumgarte", "rk4", None, None, None, {})
    assert StiffWatch.of(system, stepper, 1e-4, 100) is not None
    stepper.implicit = True
    assert StiffWatch.of(system, stepper, 1e-4, 100) is None
    run = simulate(scene, integrator="dop853", rtol=1e-6, dt=1e-3, duration=0.05)
    assert run.t[-1] == pytest.approx(0.05)


def test_the_message_suggests_the_registered_implicit_integrators(scene, fake_implicit):
    """With an implicit integrator registered, a stopped run names it as the alternative to a smaller step."""
    assert implicit_integrators()[0] == fake_implicit
    with pytest.raises(StiffStepError) as caught:
        simulate(scene, integrator="rk4", dt=5e-4, duration=DURATION)
    assert str(caught.value).endswith(f"leave a margin), or an implicit integrator: --integrator {fake_implicit}")


def test_auto_picks_rk4_within_the_margin_of_the_limit(capsys):
    """``--integrator auto`` at 0.1 ms: RK4's limit of the spring's mode at the start is 2.7853 / 7159.2 /s = 0.389 ms,
    0.1 ms is within 0.8 of it: rk4, the JSON saying why; on a scene without force elements: rk4, no stiff mode."""
    code = main(["run", "stiff-fourbar", "--integrator", "auto", "--duration", "0.1", "--quiet", "--json"])
    payload = json.loads(capsys.readouterr().out)
    choice = payload["integrator_choice"]
    assert code == 0 and payload["integrator"] == "rk4" and choice["picked"] == "rk4"
    assert choice["reason"].endswith(": within") and choice["stiff_mode"]["element"] == "rocker-spring"
    assert choice["stiff_mode"]["step_limit"] == pytest.approx(RK4_BOUND / 7159.2, rel=1e-4)
    plain = simulate("fourbar", integrator="auto", duration=0.01)
    assert plain.info.integrator == "rk4" and plain.info.integrator_choice["reason"] == "no force elements"
    assert simulate("fourbar", duration=0.01).info.integrator_choice is None


def test_auto_above_the_margin_without_an_implicit_integrator_is_refused(scene, no_implicit):
    """At 0.35 ms (above 0.8 x 0.389 ms = 0.311 ms) with no implicit integrator registered: a PinstabError naming the
    element and the step to use."""
    with pytest.raises(PinstabError, match=r"integrator auto: .*'rocker-spring'.*no implicit integrator is registered"):
        simulate(scene, integrator="auto", dt=3.5e-4, duration=DURATION)


def test_auto_above_the_margin_picks_the_implicit_integrator(scene, fake_implicit):
    """With an implicit integrator registered, auto at 0.35 ms picks it and the run goes to its end, its final energy
    within 1e-4 J of the reference's. Under rtol the explicit scheme is dop853, whose limit of the mode at the start is
    0.893 ms (its real stability interval is longer than RK4's): 0.35 ms is within 0.8 of it; 1 ms is not, and asks
    for an implicit integrator with an error estimator: refused (the stand-in has none), naming the registered one."""
    run = simulate(scene, integrator="auto", dt=3.5e-4, duration=DURATION)
    assert run.info.integrator == fake_implicit and run.info.integrator_choice["reason"].endswith(": above")
    chain = scene_chain(scene)
    end = chain.solve(scene.q0, scene.v0, np.array([0.0, run.t[-1]]))[-1]
    assert abs(run.energy[-1] - chain.energy(end[:2], end[2:4])) < 1e-4
    with pytest.raises(PinstabError, match=f"error estimator.*implicit ones registered: {fake_implicit}"):
        simulate(scene, integrator="auto", dt=1e-3, duration=DURATION, rtol=1e-6)
    controlled = simulate(scene, integrator="auto", dt=3.5e-4, duration=0.01, rtol=1e-6)
    assert controlled.info.integrator == "dop853"
    assert controlled.info.integrator_choice["stiff_mode"]["step_limit"] == pytest.approx(
        mode_step_limit(complex(-7159.2068), "dop853"), rel=1e-6
    )


@pytest.mark.parametrize("dt", [5e-5, 1e-4])
def test_the_energy_balance_is_the_trajectorys_energy_error(scene, dt):
    """The damper's work was Simpson's over the samples, which miss its fast initial power (the spring's mode decays at
    7159 /s): at 0.1 ms the balance reported 0.041 J where the run's energy is within 5.0e-4 J of the Radau
    reference's (whose own balance closes to 6e-12 J). The intervals the samples do not resolve are integrated along
    the flow: the balance is now E(end) - E(flow from the start) there, the run's energy error, 4.977e-4 J at 0.1 ms
    (the reference's largest energy difference to 1 %), 4.5e-5 J at 0.05 ms (the difference 3.1e-5 J: the local
    errors' sum bounds it within a factor 2); the work is the reference's 4.3487 J to 4e-4 J."""
    run = simulate(scene, integrator="rk4", dt=dt, duration=DURATION)
    chain = scene_chain(scene)
    reference = chain.solve(scene.q0, scene.v0, run.t)
    difference = np.abs(run.energy - [chain.energy(state[:2], state[2:4]) for state in reference]).max()
    summary = run.summary()
    assert difference <= summary["max_energy_balance_error"] <= 2 * difference
    assert summary["force_work"] == pytest.approx(-reference[-1, 4], abs=4e-4)
    if dt == 1e-4:
        assert summary["max_energy_balance_error"] == pytest.approx(difference, rel=0.01)

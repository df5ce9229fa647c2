"""The stiff four-bar (robots/stiff-fourbar.toml, issue 37): the scene's stiff mode, its SciPy Radau reference
(pinstab.analysis.spring_chain) and what RK4 does below and above its stability limit.

The reference's chain here is built by Pinocchio alone from the URDF with the rocker cut out and the spring's
numbers written out, not from pinstab's scene reader; the registered ``--reference exact`` (read from the scene)
is checked to give the same motion.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

from conftest import ROBOTS
from pinstab import (
    DivergenceError,
    PinstabError,
    StepTooLargeError,
    StiffStepError,
    UnstableGainsWarning,
    load_scene,
    simulate,
)
from pinstab.analysis import exact_reference
from pinstab.analysis.spring_chain import Spring, SpringChain, scene_chain
from pinstab.cli import main
from pinstab.forces.spring_damper import SpringDamper
from pinstab.model import ConstrainedModel
from pinstab.stability.criterion import mode_step_limit
from pinstab.stability.modes import stiffest_mode

STIFFNESS, DAMPING, REST_LENGTH = 5e4, 2500.0, 0.5  # [N/m], [N s/m], [m]: the scene's rocker-spring
COUPLER_END = ROCKER_PIVOT = np.array([0.6, 0.0, 0.0])  # [m] in the coupler's frame, in the world
DURATION, SAMPLE = 1.0, 1e-3  # [s]
RK4_BOUND = 2.785  # |h lambda| at which RK4's stability region meets the negative real axis


@pytest.fixture(scope="module")
def chain() -> SpringChain:
    text = (ROBOTS / "urdf" / "fourbar.urdf").read_text()
    text = re.sub(r'\s*<link name="rocker">.*?</link>', "", text, flags=re.S)
    text = re.sub(r'\s*<joint name="rocker".*?</joint>', "", text, flags=re.S)
    model = pin.buildModelFromXML(text)
    model.gravity.linear[:] = [0.0, -9.81, 0.0]
    end, pivot = pin.SE3(np.eye(3), COUPLER_END), pin.SE3(np.eye(3), ROCKER_PIVOT)
    spring = Spring("rocker-spring", model.getJointId("coupler"), end, 0, pivot, STIFFNESS, DAMPING, REST_LENGTH)
    return SpringChain(model, [spring])


@pytest.fixture(scope="module")
def scene():
    return load_scene("stiff-fourbar")


@pytest.fixture(scope="module")
def reference(chain, scene) -> np.ndarray:
    """(q, v, W) every 1 ms over 1 s: Radau at rtol = atol = 1e-12 (1.7 s of CPU)."""
    return chain.solve(scene.q0, scene.v0, np.arange(0.0, DURATION + SAMPLE / 2, SAMPLE))


def test_the_scene_is_the_stated_stiff_mechanism(chain, scene, reference):
    """At the start, the generalized eigenvalue of the spring's stiffness k (J^T u)(J^T u)^T against the mass matrix
    (pin.crba) is omega^2: omega = 378.99 rad/s (the other is 0: the slow mode); the effective mass along the line,
    1 / (u^T J M^-1 J^T u) = 0.3481 kg, gives the damping ratio c / (2 sqrt(k m)) = 9.47. The linearized ODE's
    eigenvalues (its Jacobian by central differences) are -7159 /s, -19.8 /s and -1.26 +- 141.2i /s at the start;
    |lambda| over the reference's first second peaks at 8846 /s (t = 0.33 s): RK4's limit 2.785 / |lambda| is
    0.389 ms at the start, 0.315 ms over the run. The spring stays within 0.4997-0.5123 m."""
    (spring,) = scene.forces
    assert isinstance(spring, SpringDamper) and not scene.constraints and scene.model.nv == 2
    assert (spring.stiffness, spring.damping, spring.rest_length) == (STIFFNESS, DAMPING, REST_LENGTH)
    q0, v0 = scene.q0, scene.v0
    ((_, _, lever),) = chain.lines(q0, v0)
    mass = pin.crba(chain.model, chain.data, q0)
    mass = np.triu(mass) + np.triu(mass, 1).T
    omega = np.sqrt(np.abs(scipy.linalg.eigh(STIFFNESS * np.outer(lever, lever), mass, eigvals_only=True)))
    np.testing.assert_allclose(omega, [0.0, 378.99], atol=0.01)
    line_mass = 1.0 / (lever @ np.linalg.solve(mass, lever))
    assert DAMPING / (2 * np.sqrt(STIFFNESS * line_mass)) == pytest.approx(9.47, abs=0.01)
    start = np.sort_complex(np.linalg.eigvals(chain.jacobian(0.0, reference[0])[:4, :4]))
    np.testing.assert_allclose(start, [-7159.2, -19.78, -1.26 - 141.20j, -1.26 + 141.20j], atol=0.1)
    largest = max(np.abs(np.linalg.eigvals(chain.jacobian(0.0, state)[:4, :4])).max() for state in reference[::10])
    assert largest == pytest.approx(8846, abs=1) and RK4_BOUND / largest == pytest.approx(0.315e-3, abs=1e-6)
    lengths = [chain.lines(state[:2], state[2:4])[0][0] for state in reference]
    assert min(lengths) == pytest.approx(0.4997, abs=1e-4) and max(lengths) == pytest.approx(0.5123, abs=1e-4)


def test_the_reference_closes_its_energy_balance_and_agrees_with_a_looser_run(chain, scene, reference):
    """Kinetic + gravity + spring energy (8.816 J at the start) plus the damper's dissipated work W (4.349 J after
    1 s) stays constant to 6.3e-12 J (bound 1e-10 J); Radau at rtol = atol = 1e-10 agrees in q to 2.5e-10 rad
    (bound 1e-8 rad), so the 1e-12 run is good to well below 1e-8 rad."""
    q, v, work = reference[:, :2], reference[:, 2:4], reference[:, 4]
    energy = np.array([chain.energy(qi, vi) for qi, vi in zip(q, v, strict=True)])
    assert energy[0] == pytest.approx(8.816, abs=1e-3) and work[-1] == pytest.approx(4.349, abs=1e-3)
    assert np.abs(energy + work - energy[0]).max() < 1e-10
    looser = chain.solve(scene.q0, scene.v0, np.arange(0.0, DURATION + SAMPLE / 2, SAMPLE), tolerance=1e-10)
    assert np.abs(looser[:, :2] - q).max() < 1e-8


def test_rk4_below_the_stiff_limit_follows_the_reference(chain, scene, reference):
    """pinstab's RK4 at dt = 0.05 ms (|h lambda| <= 0.44) is within 2.36e-6 rad of the Radau reference over 1 s
    (bound 5e-6 rad; 4.8e-5 rad at 0.1 ms, 1.5e-3 rad at 0.2 ms: the crank turns 1.5 times). The registered
    ``--reference exact``, read from the scene, is the same Radau motion to 1e-12 rad."""
    run = simulate(scene, integrator="rk4", dt=5e-5, duration=DURATION, record_every=20)
    assert len(run.t) == len(reference) and np.abs(run.t - np.arange(len(run.t)) * SAMPLE).max() < 1e-12
    assert np.abs(run.q - reference[:, :2]).max() < 5e-6
    registered = exact_reference(scene, scene.q0, scene.v0, run.t[:101])
    np.testing.assert_allclose(registered.q, reference[:101, :2], rtol=0, atol=1e-12)
    assert registered.default_of == ("crank", "coupler")


@pytest.mark.parametrize(("dt", "diverged_by"), [(5e-4, 0.01), (4e-4, 0.1)])
def test_rk4_above_the_stiff_limit_stops_as_diverged(scene, dt, diverged_by):
    """RK4 at dt = 0.5 ms (|h lambda| = 3.6 at the start) leaves the finite states at t = 6 ms, at 0.4 ms (2.86,
    just past 2.785) at t = 54 ms: simulate() raises DivergenceError (the CLI exits 3), no plausible wrong answer."""
    with pytest.raises(DivergenceError) as caught:
        simulate(scene, integrator="rk4", dt=dt, duration=DURATION)
    assert caught.value.time < diverged_by


def test_rk4_above_the_stiff_limit_names_the_stiff_element(scene):
    """Issue 37's acceptance: an explicit run refused for a stiff element names it (rocker-spring), its frequency and
    the largest stable step, keeping the partial trajectory. The frequency is the element's tangent stiffness against
    M at the start: 375.3 rad/s, within 1.5 % of the 378.99 rad/s of its stiffness k alone (the 600 N preload's
    geometric terms make the difference); the limit 0.38905 ms is 2.7853 / 7159.2 /s (the first test's start)."""
    with pytest.raises(StiffStepError, match=r"dt = 0.5 ms is above rk4's stability limit 0.389 ms") as caught:
        simulate(scene, integrator="rk4", dt=5e-4, duration=DURATION)
    error = caught.value
    assert isinstance(error, DivergenceError)  # the CLI's exit 3
    assert "force element 'rocker-spring' (|lambda| = 7.16e+03 /s, 375.3 rad/s" in str(error)
    assert "at t = 0 s): use --dt 0.000389 or smaller (the limit changes with the state" in str(error)
    assert "(the limit changes with the state: leave a margin)" in str(error) and "not have yet" not in str(error)
    assert error.element == "rocker-spring" and error.frequency == pytest.approx(378.99, rel=0.015)
    assert error.limit == pytest.approx(RK4_BOUND / 7159.2, rel=5e-4) and 0.3891e-3 > error.limit > 0.3890e-3
    assert error.diverged_at == pytest.approx(6e-3) and len(error.trajectory.t) == 13
    assert np.isfinite(error.finite_trajectory.q).all() and error.finite_trajectory.t[-1] == pytest.approx(5.5e-3)


def test_the_command_line_exits_3_naming_the_element(capsys):
    """``pinstab run stiff-fourbar --dt 1e-3`` (the scene's RK4 at 1 ms, |h lambda| = 7.2): exit 3, the element on
    stderr and in the JSON's ``stiff_mode`` (eigenvalue -7159 /s, limit 0.389 ms)."""
    code = main(["run", "stiff-fourbar", "--dt", "1e-3", "--duration", "1", "--quiet", "--json"])
    out, err = capsys.readouterr()
    assert code == 3 and "force element 'rocker-spring'" in err and "Traceback" not in err
    mode = json.loads(out)["stiff_mode"]
    assert mode["element"] == "rocker-spring" and mode["eigenvalue"] == [pytest.approx(-7159.2, abs=0.1), 0.0]
    assert mode["step_limit"] == pytest.approx(0.38905e-3, rel=1e-4) and mode["frequency"] == pytest.approx(
        375.3, abs=0.1
    )


def test_rk4_below_the_start_limit_is_stopped_by_the_watch_at_a_check(chain, scene):
    """RK4 at 0.38 ms is inside the start's limit (0.389 ms) but not the run's (0.315 ms): without the stiff-mode watch
    it left the finite states at t = 0.2447 s (step 644). The watch stops it at the check of t = 0.228 s (step 600),
    where the mode grows 6e7-fold over 100 steps, before the blow-up: the kept finite trajectory ends at the check
    before (t = 0.19 s), its energy within the start's 8.816 J; the limit there, 0.369 ms, is 2.7853 over the Radau
    chain's own Jacobian's stiffest eigenvalue at the stopped state (-7545 /s) to 1e-6 relative."""
    with pytest.raises(StiffStepError, match=r"limit 0.369 ms .* at t = 0.228 s\): use --dt 0.000369") as caught:
        simulate(scene, integrator="rk4", dt=3.8e-4, duration=DURATION)
    error, run = caught.value, caught.value.trajectory
    assert error.diverged_at == pytest.approx(0.228) and run.t[-1] == pytest.approx(0.228)
    assert len(run.t) == 502  # steps 0 .. 500, then 600
    finite = error.finite_trajectory
    assert finite.t[-1] == pytest.approx(0.19) and finite.energy.max() == pytest.approx(8.816, abs=1e-3)
    measured = np.linalg.eigvals(chain.jacobian(0.228, np.r_[run.q[-1], run.v[-1], 0.0])[:4, :4])
    assert error.eigenvalue == pytest.approx(measured[np.argmax(np.abs(measured))], rel=1e-6)
    assert error.limit == pytest.approx(2.7853 / 7544.6, rel=5e-4)


def test_the_stiffest_mode_is_the_measured_linearization(chain, scene, reference):
    """pinstab.stability.modes' eigenvalue (the force elements' and RNEA's central differences against M) is the
    Radau chain's own Jacobian's stiffest (SciPy helper, ABA by differences) to 1e-6 relative at every 10th sample of
    the first second (-7159 /s at the start, up to |lambda| = 8846 /s); the spring owns it (share > 0.99); the step
    limits are the closed forms' intervals on the real axis over |lambda|: RK4 2.7853 (the real root of 1 + x/2 + x^2/6
    + x^3/24), Euler 2, to 1e-9 (mode_step_limit of the mode's eigenvalue)."""
    model = ConstrainedModel(scene)
    rk4_interval = -min(r.real for r in np.roots([1 / 24, 1 / 6, 1 / 2, 1]) if abs(r.imag) < 1e-12)
    assert rk4_interval == pytest.approx(RK4_BOUND, abs=1e-3)
    largest = 0.0
    for time, state in zip(np.arange(0.0, DURATION, 10 * SAMPLE), reference[::10], strict=False):
        mode = stiffest_mode(model, state[:2], state[2:4], time)
        measured = np.linalg.eigvals(chain.jacobian(time, state)[:4, :4])
        stiffest = measured[np.argmax(np.abs(measured))]
        assert mode.eigenvalue == pytest.approx(stiffest, rel=1e-6) and mode.eigenvalue.imag == 0
        assert mode.element == "rocker-spring" and mode.share > 0.99
        assert mode_step_limit(mode.eigenvalue, "rk4") * abs(mode.eigenvalue) == pytest.approx(rk4_interval, rel=1e-9)
        assert mode_step_limit(mode.eigenvalue, "euler") * abs(mode.eigenvalue) == pytest.approx(2.0, rel=1e-9)
        largest = max(largest, abs(mode.eigenvalue))
    assert largest == pytest.approx(8846, abs=1)
    assert stiffest_mode(model, scene.q0, scene.v0, 0.0).eigenvalue.real == pytest.approx(-7159.2, abs=0.1)


def test_a_divergence_of_the_gains_names_no_element(tmp_path):
    """The four-bar with a soft spring added (50 N/m, undamped) and Baumgarte gains too stiff for the step (the
    divergence contract's run: kp = 3.6e4, kd = 0, semi-implicit Euler at 10 ms) diverges at t = 3.11 s (drift),
    unnamed: the stiffest mode of the motion on the closure's free coordinate (-3.71 /s) is not the spring's (its
    share 42 %), and the gains' instability is no force element's."""
    text = (ROBOTS / "fourbar.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    text += (
        '\n[[forces]]\nname = "soft"\nkind = "spring-damper"\nframe_a = "crank"\noffset_a = [0.2, 0.0, 0.0]\n'
        'frame_b = "world"\noffset_b = [0.0, 0.5, 0.0]\nstiffness = 50.0\ndamping = 0.0\nrest_length = 0.3\n'
    )
    (tmp_path / "soft.toml").write_text(text)
    scene = load_scene(tmp_path / "soft.toml")
    mode = stiffest_mode(ConstrainedModel(scene), scene.q0, scene.v0, 0.0)
    assert mode.element is None and mode.share < 0.5 and abs(mode.eigenvalue) < 10  # -3.71 /s, the spring's 42 %
    assert not mode.decays  # kp = -13.8 /s^2: the four-bar's motion there moves away, no step limit applies
    with (
        pytest.raises(DivergenceError, match="simulation diverged at") as caught,
        pytest.warns(UnstableGainsWarning, match="kp = 36000"),
    ):
        simulate(scene, method="baumgarte", kp=3.6e4, kd=0.0, integrator="semi-implicit-euler", dt=1e-2, duration=5.0)
    assert not isinstance(caught.value, StepTooLargeError) and caught.value.diverged_at == pytest.approx(3.11)


def test_the_reference_refuses_what_it_does_not_model(chain, tmp_path):
    """A closed chain (the four-bar's closure), another force kind (a joint torque) and a state with the spring's
    points together (crank at acos(1/6), the coupler's end on the rocker's pivot) are refused, naming the closure's
    scene, the element or the spring."""
    with pytest.raises(PinstabError, match="'fourbar' has constraints"):
        scene_chain(load_scene("fourbar"))
    text = (ROBOTS / "stiff-fourbar.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    text += '\n[[forces]]\nname = "motor"\nkind = "joint-torque"\njoint = "crank"\ntorque = 0.2\n'
    (tmp_path / "driven.toml").write_text(text)
    with pytest.raises(PinstabError, match="spring-damper forces only; 'motor' is JointTorque"):
        scene_chain(load_scene(tmp_path / "driven.toml"))
    crank = np.arccos(1 / 6)
    coupler = np.arctan2(-0.2 * np.sin(crank), 0.6 - 0.2 * np.cos(crank)) - crank
    with pytest.raises(PinstabError, match="spring 'rocker-spring': its points coincide"):
        chain.lines(np.array([crank, coupler]), np.zeros(2))

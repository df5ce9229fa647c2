"""The energy budget of a run: the work of impacts, force elements and servo controls separated from the energy
error, against closed forms (Newton's restitution at each bounce, a constant torque's work), from a run in memory
and from its saved file; the chart's panels say which is which."""

from __future__ import annotations

import numpy as np
import pytest

import pinstab
from pinstab.analysis.energy import CONTROLS, IMPACTS, energy_budget
from pinstab.trajectory import Trajectory
from pinstab.viz.plots import trajectory_figure

G, HEIGHT, BALL_MASS = 9.81, 1.0, 1.0  # the bouncing-ball scene: 1 kg dropped from a 1 m gap, gravity 9.81 m/s^2


def ylabels(figure) -> list[str]:
    return [axis.get_ylabel() for axis in figure.axes]


@pytest.mark.parametrize("restitution", [0.5, 0.8])
def test_each_bounce_loses_the_restitutions_share_and_the_remainder_is_rounding(restitution):
    """Bounce k (from 1) meets the ground at speed e^(k-1) sqrt(2 g h) and leaves at e times it: its impulse does
    the work -m g h e^(2(k-1)) (1 - e^2). Between the bounces the ball flies freely: E(t) - E(0) is the impacts' work
    to the integration's error, while E itself falls by joules."""
    scene = pinstab.load_scene("bouncing-ball", restitution=restitution)
    run = pinstab.simulate(scene, duration=3.0, contacts="event")
    impacts = [event for event in run.info.contact_events if "work" in event]
    expected = [-BALL_MASS * G * HEIGHT * restitution ** (2 * k) * (1 - restitution**2) for k in range(5)]
    np.testing.assert_allclose([event["work"] for event in impacts[:5]], expected, rtol=1e-8, atol=1e-12)
    budget = energy_budget(run, scene)
    assert set(budget.work) == {IMPACTS} and budget.uncounted == []
    assert budget.change[-1] < -0.9 * BALL_MASS * G * HEIGHT * (1 - restitution**2)  # joules lost
    assert np.max(np.abs(budget.remainder)) < 1e-8
    before = np.flatnonzero(run.t < impacts[0]["t"])[-1]  # the first bounce's loss lands between these samples
    assert budget.work[IMPACTS][before] == 0.0 and budget.work[IMPACTS][before + 1] == pytest.approx(expected[0])


def test_the_motor_and_the_dampers_work_explain_the_slider_cranks_energy(tmp_path):
    """slider-crank: a constant 0.2 N m motor on the crank (work 0.2 (theta(t) - theta(0)) exactly) and a 2 N s/m
    damper on the slider (work negative): they, and not the integration, change the energy; a saved run gives the
    same budget with its scene reloaded by name."""
    scene = pinstab.load_scene("slider-crank")
    run = pinstab.simulate(scene, duration=1.0)
    budget = energy_budget(run, scene)
    assert list(budget.work) == ["motor", "load"] and budget.uncounted == []
    crank = scene.model.joints[scene.model.getJointId("crank")].idx_q
    np.testing.assert_allclose(budget.work["motor"], 0.2 * (run.q[:, crank] - run.q[0, crank]), atol=1e-9)
    assert budget.work["load"][-1] < -0.05 and np.all(np.diff(budget.work["load"]) <= 1e-12)
    assert np.max(np.abs(budget.change)) > 0.3
    assert np.max(np.abs(budget.remainder)) < 1e-7
    path = tmp_path / "run.npz"
    run.save(path)
    loaded = energy_budget(Trajectory.load(path))
    np.testing.assert_allclose(loaded.remainder, budget.remainder, atol=1e-15)


@pytest.mark.filterwarnings("ignore::pinstab.errors.ZeroDynamicsWarning")  # its free joint speeds up, as it does
def test_servo_controls_work_is_counted_in_memory_and_named_uncounted_from_a_file(tmp_path):
    scene = pinstab.load_scene("double-pendulum-servo")
    run = pinstab.simulate(scene, duration=0.4)  # before its free joint runs away
    budget = energy_budget(run, scene)
    assert list(budget.work) == [CONTROLS]
    assert np.max(np.abs(budget.change)) > 0.5 and np.max(np.abs(budget.remainder)) < 1e-6
    path = tmp_path / "run.npz"
    run.save(path)
    assert energy_budget(Trajectory.load(path)).uncounted == ["the servo controls (not kept with a saved run)"]


def test_the_chart_calls_energy_error_only_what_is_left_after_the_counted_work():
    conservative = trajectory_figure(pinstab.simulate("fourbar", dt=1e-3, duration=0.2))
    assert "energy error E(t) - E(0) [J]" in ylabels(conservative)
    bounces = trajectory_figure(pinstab.simulate("bouncing-ball", duration=1.0, contacts="event"))
    assert {"energy change, work [J]", "energy error E - E(0) - W [J]"} <= set(ylabels(bounces))
    energy_axis = bounces.axes[ylabels(bounces).index("energy change, work [J]")]
    assert [line.get_label() for line in energy_axis.get_lines()][:2] == ["E(t) - E(0)", f"work of {IMPACTS}"]
    sliding = trajectory_figure(pinstab.simulate("incline", duration=0.2, contacts="event"))
    assert "energy change E(t) - E(0) [J]" in ylabels(sliding)
    notes = [text.get_text() for axis in sliding.axes for text in axis.texts]
    assert "not counted: sliding friction" in notes

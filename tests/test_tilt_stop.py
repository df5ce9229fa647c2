"""A tilt that stops (``[tilt] stop``): gravity turns at its rate until the turn reaches ``stop`` and stays,
the same rule on the compiled core (``cpp/core_kernel.cpp`` GravityTilt) as in Python (which calls it): against
Rodrigues' rotation formula, and a run on the core against the same run on the general path."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pinstab import load_scene, simulate
from pinstab.errors import SceneError
from pinstab.scene import GravityTilt, _tilt


def _rodrigues(axis: np.ndarray, angle: float, vector: np.ndarray) -> np.ndarray:
    """``vector`` turned by ``angle`` [rad] about the unit ``axis``."""
    return (
        vector * math.cos(angle)
        + np.cross(axis, vector) * math.sin(angle)
        + axis * (axis @ vector) * (1.0 - math.cos(angle))
    )


@pytest.mark.parametrize("rate", [0.5, -0.5])
def test_gravity_turns_until_the_stop_and_stays(rate):
    """g(t) = R(axis, -angle) g0 with angle = start + rate t until it reaches stop: equal to Rodrigues' formula to 1e-15
    m/s^2 before, at and after the stop (which comes at t = 0.4 s)."""
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    tilt = GravityTilt(axis, rate, np.array([0.0, 0.0, -9.81]), 0.1, 0.1 + math.copysign(0.2, rate))
    for t, angle in [(0.0, 0.1), (0.2, 0.1 + 0.2 * rate), (0.4, 0.1 + 0.4 * rate), (0.5, tilt.stop), (7.0, tilt.stop)]:
        assert np.max(np.abs(tilt.gravity(t) - _rodrigues(axis, -angle, tilt.gravity0))) <= 1e-15


def test_a_stop_the_turn_does_not_reach_is_refused():
    """A stop behind the start (for the rate's sense) is a SceneError naming tilt.stop."""
    with pytest.raises(SceneError, match="tilt.stop"):
        _tilt({"axis": [1, 0, 0], "rate": "2 deg/s", "start": "1.5 deg", "stop": "1 deg"}, np.array([0.0, 0.0, -9.81]))


def test_a_stopping_tilt_runs_on_the_core_as_on_the_general_path():
    """The delta robot under gravity turning about x at 40 deg/s until 10 deg (t = 0.25 s), 0.5 s with RK4: on the core
    (which tilts gravity) and on the general path (ProxQP named: Python's gravity), q equal to 1e-11, v to 1e-8
    (measured 2.1e-12, 2.9e-9; without a tilt the two paths part as much, 5.0e-12 and 1.5e-8: the delta's passages
    amplify the two solves' rounding); and the stop acts: the same run turning on ends elsewhere (0.062 rad)."""
    scene = load_scene("delta")
    turning = GravityTilt(np.array([1.0, 0.0, 0.0]), math.radians(40.0), scene.model.gravity.linear.copy())
    stopping = dataclasses.replace(scene, tilt=dataclasses.replace(turning, stop=math.radians(10.0)))
    runs = {
        solver: simulate(stopping, "baumgarte", "rk4", duration=0.5, progress=False, **options)
        for solver, options in [("core", {}), ("general", {"solver": "proxsuite"})]
    }
    assert runs["core"].info.path == "core" and runs["general"].info.path == "general"
    assert np.max(np.abs(runs["core"].q - runs["general"].q)) <= 1e-11
    assert np.max(np.abs(runs["core"].v - runs["general"].v)) <= 1e-8
    on = simulate(dataclasses.replace(scene, tilt=turning), "baumgarte", "rk4", duration=0.5, progress=False)
    assert on.info.path == "core" and np.max(np.abs(on.q[-1] - runs["core"].q[-1])) > 1e-2

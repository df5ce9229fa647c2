"""The time-stepping contacts' step with its numbers compiled (cpp/cone_step.hpp, issue 36) against the same step in
NumPy and Pinocchio's Python bindings (pinstab/bench/python_stepper.py: SciPy's Cholesky factor, ADMM through the
bindings), step by step from the same state: the two compute the same physics in another order of sums, so they agree
to rounding amplified by the cone solve (ADMM's tolerance 1e-12), not bitwise; and the compiled run repeats itself to
the last bit."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import load_scene
from pinstab.bench.python_stepper import PythonStepper
from pinstab.contact.modes import Mode
from pinstab.generators import box_stack
from pinstab.integration.contact_stepping import ContactStepper
from pinstab.scene import scene_from_dict
from pinstab.simulate.contacts import stepping_parts
from pinstab.simulate.loop import start_state

DT = 1e-3  # [s]
# [m or rad, m/s or rad/s; N s] the largest difference of one step's end state, and of its impulses, taken by both from
# the same state. Measured over these runs: v 5.8e-16, 4.2e-15, 3.3e-16, 0 (box-stack, incline, sphere-spin,
# bouncing-ball), q below 3e-18, impulses below 3.3e-16; the bounds leave rounding room (ADMM stops at 1e-12).
STEP_TOLERANCE = 1e-12
IMPULSE_TOLERANCE = 1e-12
SCENES = {  # name: (generator parameters, steps: through the scene's mode changes)
    "box-stack": ({"count": 3}, 200),
    "incline": ({"theta": 0.5, "mu": 0.3}, 200),
    "sphere-spin": ({}, 400),  # slides, rolls from t* = 0.242 s
    "bouncing-ball": ({"height": 0.05}, 250),  # lands at 0.101 s, bounces (e = 0.5)
}


def steppers(name: str) -> tuple[ContactStepper, PythonStepper, np.ndarray, np.ndarray]:
    """The compiled and the NumPy stepper of scene ``name`` and its start state."""
    parameters = SCENES[name][0]
    scene = load_scene(name, **parameters)
    _, compiled, q, v = stepping_parts(scene, DT, *start_state(scene, None, None))
    scene = load_scene(name, **parameters)
    _, reference, _, _ = stepping_parts(scene, DT, *start_state(scene, None, None), PythonStepper)
    return compiled, reference, q, v


@pytest.mark.parametrize("name", SCENES)
def test_each_compiled_step_is_the_numpy_step(name: str) -> None:
    """From the compiled run's state at every step, both steppers step: the same end state to STEP_TOLERANCE, the
    same modes and the same impulses to IMPULSE_TOLERANCE."""
    compiled, reference, q, v = steppers(name)
    worst, modes = 0.0, set()
    for k in range(SCENES[name][1]):
        expected = reference.step(q.copy(), v.copy(), k * DT, DT)
        q, v = compiled.step(q, v, k * DT, DT)
        worst = max(worst, float(np.max(np.abs(q - expected[0]))), float(np.max(np.abs(v - expected[1]))))
        assert compiled.modes == reference.modes, k
        np.testing.assert_allclose(compiled.impulses, reference.impulses, rtol=0, atol=IMPULSE_TOLERANCE)
        modes.update(compiled.modes)
    assert worst <= STEP_TOLERANCE
    assert Mode.STICKING in modes or Mode.SLIDING in modes  # the runs pass through contact


def test_box_stack_rests_and_repeats_to_the_last_bit() -> None:
    """Three cubes at rest on 12 sticking corners stay put (1e-9 m in 0.2 s) and two runs give the same bits."""
    ends = []
    for _ in range(2):
        compiled, _, q0, v = steppers("box-stack")
        q = q0
        for k in range(200):
            q, v = compiled.step(q, v, k * DT, DT)
        ends.append(q)
        assert float(np.max(np.abs(q - q0))) < 1e-9
        assert compiled.modes.count(Mode.STICKING) == 12
    assert np.array_equal(ends[0], ends[1])


def test_the_compiled_step_refuses_arrays_of_other_sizes() -> None:
    compiled, _, q, v = steppers("sphere-spin")
    contact = (np.zeros(1), np.zeros(1), np.zeros((3, 6)), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros((0, 6)))
    with pytest.raises(ValueError, match="not of the model's sizes"):
        compiled.compiled.step(q[:-1], v, DT, np.eye(6), np.zeros(6), *contact, np.zeros(3), np.zeros(5),
                               compiled.solver.cones)  # fmt: skip
    with pytest.raises(ValueError, match="guess is not one impulse per contact row"):
        compiled.compiled.step(q, v, DT, np.eye(6), np.zeros(6), *contact, np.zeros(2), np.zeros(5),
                               compiled.solver.cones)  # fmt: skip


def test_both_steps_take_the_contacts_the_others_impulses_close() -> None:
    """Two stacked cubes, the top one held up by half its weight (tests/test_contact_stepping.py): the contacts
    between them open in free motion and close only once the ground stops the bottom cube. Both steppers grow their
    problems with them (all 8 corners sticking at every step, which the free motion alone leaves separated) and end
    each step in the same state to STEP_TOLERANCE."""
    data = box_stack(2, 0.5)
    data["forces"] = [{"name": "lift", "kind": "external-force", "frame": "box1", "force": [0.0, 0.0, 0.5 * 9.81]}]
    parts = [
        stepping_parts(scene, DT, *start_state(scene, None, None), stepper)
        for scene, stepper in (
            (scene_from_dict(data, "lifted"), ContactStepper),
            (scene_from_dict(data, "lifted"), PythonStepper),
        )
    ]
    (_, compiled, q, v), (_, reference, _, _) = parts
    worst = 0.0
    for k in range(100):
        expected = reference.step(q.copy(), v.copy(), k * DT, DT)
        q, v = compiled.step(q, v, k * DT, DT)
        worst = max(worst, float(np.max(np.abs(q - expected[0]))), float(np.max(np.abs(v - expected[1]))))
        assert compiled.modes == reference.modes and compiled.modes.count(Mode.STICKING) == 8, k
    assert worst <= STEP_TOLERANCE

"""CPU per step of time-stepping contacts (issue 36): pinstab's step with its numbers compiled
(:class:`~pinstab.integration.contact_stepping.ContactStepper`, cpp/cone_step.hpp) against the same step in NumPy and
Pinocchio's Python bindings (:class:`~pinstab.bench.python_stepper.PythonStepper`, the step before it was compiled)
and against MuJoCo on the same scene at its best settings (elliptic cones, impratio 100, noslip 20 iterations, the
same dt), measured interleaved: ROUNDS rounds, each running every simulator STEPS steps in turn from the scene's
start, the least CPU per step (``time.process_time``) of each kept; their ratios. Also the share of the compiled
stepper's step spent in its compiled call (the rest is Python: contacts found by coal, their gaps and Jacobians, the
applied forces, modes and events), and how far the two pinstab steppers' end states differ.

* ``box-stack``: three 1 kg cubes at rest, 12 corner contacts sticking (20 found by coal, 12 in the problem);
* ``incline``: the cube sliding down the slope (theta 0.5 rad, mu 0.3), 4 corners;
* ``sphere-spin``: the ball thrown with backspin, sliding then rolling, 1 contact.

    python benchmarks/stepping_core.py            # prints the table (~1 min); with --save, writes
                                                  # benchmarks/results/stepping_core.json
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pinstab import load_scene
from pinstab.bench import mujoco_contacts as mj
from pinstab.bench import save_results
from pinstab.bench.python_stepper import PythonStepper
from pinstab.integration.contact_stepping import ContactStepper
from pinstab.simulate.contacts import stepping_parts
from pinstab.simulate.loop import start_state
from pinstab.simulate.threads import single_blas_thread

DT = 1e-3  # [s]
STEPS = 300
ROUNDS = 5
OUT = Path(__file__).parent / "results" / "stepping_core.json"
MUJOCO = mj.MujocoSettings(DT, impratio=100.0, noslip_iterations=20)  # tests/test_contact_peers.py's BEST
# name: (generator parameters, MuJoCo's scene)
SCENES: dict[str, tuple[dict[str, Any], mj.MujocoScene]] = {
    "box-stack": ({"count": 3, "mu": 0.5}, mj.box_stack(3, 0.5)),
    "incline": ({"theta": 0.5, "mu": 0.3}, mj.incline(0.5, 0.3)),
    "sphere-spin": ({"v0": 2.0, "omega0": 5.0, "mu": 0.3, "radius": 0.1}, mj.sphere_spin(2.0, 5.0, 0.3, 0.1)),
}


class TimedCall:
    """The compiled stepper's call, timed: CPU seconds inside it, and the contacts in each step's problem."""

    def __init__(self, compiled: Any) -> None:
        self.compiled, self.cpu, self.active = compiled, 0.0, 0

    def step(self, *arguments: Any) -> tuple:
        began = time.process_time()
        result = self.compiled.step(*arguments)
        self.cpu += time.process_time() - began
        self.active += len(result[2])
        return result


@single_blas_thread  # as simulate() runs
def pinstab_steps(name: str, stepper: type[ContactStepper]) -> tuple[float, np.ndarray, TimedCall | None]:
    """STEPS steps of scene ``name`` with ``stepper``: CPU per step [s], the end configuration, the timed compiled
    call (None for the NumPy stepper)."""
    scene = load_scene(name, **SCENES[name][0])
    _, stepping, q, v = stepping_parts(scene, DT, *start_state(scene, None, None), stepper)
    timed = None
    if stepper is ContactStepper:
        timed = TimedCall(stepping.compiled)
        stepping.compiled = timed
    began = time.process_time()
    for k in range(STEPS):
        q, v = stepping.step(q, v, k * DT, DT)
    return (time.process_time() - began) / STEPS, q, timed


def mujoco_steps(name: str) -> float:
    """CPU per step [s] of STEPS MuJoCo steps of scene ``name`` at :data:`MUJOCO`."""
    import mujoco

    scene = SCENES[name][1]
    model = mujoco.MjModel.from_xml_string(mj.mjcf(scene, MUJOCO))
    data = mujoco.MjData(model)
    data.qvel[:] = scene.qvel0
    began = time.process_time()
    mujoco.mj_step(model, data, STEPS)
    return (time.process_time() - began) / STEPS


def measure() -> dict[str, dict[str, float]]:
    """Per scene: CPU per step [us] of each simulator (least over the rounds), the ratios, the compiled call's
    share of the compiled step, the mean contacts per problem and the two pinstab steppers' largest end difference."""
    best: dict[str, dict[str, float]] = {name: {} for name in SCENES}
    for _ in range(ROUNDS):
        for name in SCENES:
            row = best[name]
            compiled, q_compiled, timed = pinstab_steps(name, ContactStepper)
            numpy_cost, q_numpy, _ = pinstab_steps(name, PythonStepper)
            mujoco_cost = mujoco_steps(name)
            if compiled < row.get("compiled_us", np.inf) / 1e6:
                row["compiled_call_share"] = timed.cpu / (compiled * STEPS)
            row["compiled_us"] = min(row.get("compiled_us", np.inf), compiled * 1e6)
            row["numpy_us"] = min(row.get("numpy_us", np.inf), numpy_cost * 1e6)
            row["mujoco_us"] = min(row.get("mujoco_us", np.inf), mujoco_cost * 1e6)
            row["contacts_in_problem"] = timed.active / STEPS
            row["end_difference"] = float(np.max(np.abs(q_compiled - q_numpy)))
    for row in best.values():
        row["numpy_over_compiled"] = row["numpy_us"] / row["compiled_us"]
        row["compiled_over_mujoco"] = row["compiled_us"] / row["mujoco_us"]
    return best


def main(argv: list[str]) -> None:
    results = measure()
    print(
        f"CPU per step [us], dt {DT:g} s, {STEPS} steps, least of {ROUNDS} interleaved rounds; MuJoCo {MUJOCO.label()}"
    )
    print("| scene | contacts | compiled | NumPy | MuJoCo | NumPy / compiled | compiled / MuJoCo | in call | end dq |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in results.items():
        print(
            f"| {name} | {r['contacts_in_problem']:.1f} | {r['compiled_us']:.0f} | {r['numpy_us']:.0f} | "
            f"{r['mujoco_us']:.1f} | {r['numpy_over_compiled']:.2f} | {r['compiled_over_mujoco']:.1f} | "
            f"{r['compiled_call_share']:.0%} | {r['end_difference']:.1e} |"
        )
    if "--save" in argv:
        save_results(OUT, {"dt": DT, "steps": STEPS, "rounds": ROUNDS, "mujoco": MUJOCO.label(), "scenes": results})


if __name__ == "__main__":
    main(sys.argv[1:])

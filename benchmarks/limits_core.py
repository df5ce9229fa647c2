"""Joint-limit runs with their modes evaluated by the compiled core against the numpy evaluation they had (issue 35,
joint limits in the core): the path of each run, its CPU seconds per simulated second both ways, measured interleaved
in one run (REPEATS times each, the least kept), their ratio, and the largest difference of q between the two runs.

* ``pendulum``: the pendulum of tests/test_joint_limits.py, falling from rest onto its lower limit, held, pulled off by
  a torque ramp (2 s);
* ``panda-anchor``: the bundled closed chain, whose held run (native path) leaves joint2's lower limit and is run again
  from the start by the event path with its closure and 14 limits (1 s; the held attempt is in both timings);
* ``mjcf-biped``: tests/data/mjcf_biped.xml, two legs of six hinges with 12 limits, 5 dry joint frictions (MJCF
  ``frictionloss``: sticking ones held as one-row entries, slipping ones' torques applied), springs and a joint
  equality, from its keyframe (1 s): its CPU s/s "after" is whether it runs in real time (<= 1).

"before" evaluates each mode by :class:`~pinstab.solvers.contact_modes.ModeDynamics` (a Pinocchio pass from Python and
dense numpy solves), "after" by :class:`~pinstab.solvers.core_modes.CoreModeDynamics` (the core kernel). A third
figure prices the evaluation of a mode's limit rows (gaps and Jacobian rows of the 14 panda limits, two held) at one
state, per call from Python: the core's rows (joint_limit_gaps, block_jacobian) against Pinocchio 4.1's
JointLimitConstraintModel (makeSelectionFilteredByLimitProximity, calc, jacobian); and the core kernel's whole
evaluation (kinematics, rows, KKT solve) of the panda's closure alone and with those two limits held.

    python benchmarks/limits_core.py    # prints the table, writes benchmarks/results/limits_core.json (~2 min)
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import pinstab
from pinstab.bench import save_results
from pinstab.constraints.joint_limits import joint_limits
from pinstab.kernels import block_jacobian, joint_limit_gaps
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict
from pinstab.solvers.contact_modes import ModeDynamics
from pinstab.solvers.core_modes import CoreModeDynamics

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from test_joint_limits import _pendulum  # noqa: E402

contacts_module = importlib.import_module("pinstab.simulate.contacts")  # the module (pinstab.simulate: the function)
REPEATS = 3
CALLS = 20_000  # evaluations of the limit rows per timing
OUT = Path(__file__).parent / "results" / "limits_core.json"
DATA = Path(__file__).parents[1] / "tests" / "data"
RUNS = {
    "pendulum": (_pendulum, 2.0),
    "panda-anchor": (lambda: pinstab.load_scene("panda-anchor"), 1.0),
    "mjcf-biped": (lambda: scene_from_dict({"robot": {"mjcf": "mjcf_biped.xml"}}, base_dir=DATA), 1.0),
}
EVALUATIONS = {
    "before": ModeDynamics,
    "after": CoreModeDynamics,
}


def timed_run(name: str, evaluation: str) -> tuple[float, pinstab.Trajectory]:
    """CPU seconds per simulated second of a run with that evaluation of its modes, and the run."""
    make, duration = RUNS[name]
    scene = make()
    contacts_module.CoreModeDynamics = EVALUATIONS[evaluation]
    try:
        start = time.process_time()
        run = pinstab.simulate(scene, duration=duration, dt=1e-2, progress=False)
        return (time.process_time() - start) / duration, run
    finally:
        contacts_module.CoreModeDynamics = CoreModeDynamics


def row_costs() -> dict[str, float]:
    """Microseconds per evaluation of the panda's limit rows (gaps of all 14, Jacobian rows of the two held), and per
    core kernel evaluation without and with the two held."""
    scene = pinstab.load_scene("panda-anchor")
    model = scene.model
    data = model.createData()
    limits = joint_limits(model).limits
    q = scene.q0.copy()
    held = [limit for limit in limits if limit.name in ("panda_joint2 lower", "panda_joint7 upper")]
    for limit in held:
        q[limit.index_q] = limit.bound
    rows = [limit.row for limit in limits]
    joints = pin.StdVec_Index()
    for j in range(1, model.njoints):
        joints.append(j)
    constraint = pin.JointLimitConstraintModel(
        model, joints, model.lowerPositionLimit, model.upperPositionLimit, np.full(model.nq, 1e-9)
    )
    constraint_data = constraint.createData()
    pin.forwardKinematics(model, data, q)

    def core() -> None:
        joint_limit_gaps(rows, q[None, :])
        for limit in held:
            block_jacobian(model, data, limit.row, 0.0)

    def pinocchio() -> None:
        constraint.makeSelectionFilteredByLimitProximity(q)
        constraint.calc(model, data, constraint_data)
        constraint.jacobian(model, data, constraint_data)

    system = CoreModeDynamics(ConstrainedModel(scene), [], limits)
    kernels = {}
    for label, on in (("kernel_closure_only", ()), ("kernel_two_limits_held", held)):
        system.active = [limit in on for limit in limits]
        kernels[label] = system.mode_kernel()
    v = tau = np.zeros(model.nv)

    def evaluation(label: str):
        return lambda: kernels[label].acceleration(q, v, tau, 0.0)

    calls = {"core": core, "pinocchio": pinocchio, **{label: evaluation(label) for label in kernels}}
    costs = dict.fromkeys(calls, np.inf)
    for _ in range(REPEATS):
        for label, call in calls.items():
            start = time.process_time()
            for _ in range(CALLS):
                call()
            costs[label] = min(costs[label], (time.process_time() - start) / CALLS * 1e6)
    constraint.makeSelectionFilteredByLimitProximity(q)
    assert len(constraint.active_idx_in_activable()) == len(held)  # the same two rows
    return costs


def main() -> None:
    results: dict[str, dict] = {}
    for name in RUNS:
        cpu = {"before": np.inf, "after": np.inf}
        runs = {}
        for _ in range(REPEATS):
            for evaluation in ("before", "after"):  # interleaved: the machine's load falls on both alike
                seconds, runs[evaluation] = timed_run(name, evaluation)
                cpu[evaluation] = min(cpu[evaluation], seconds)
        before, after = runs["before"], runs["after"]
        results[name] = {
            "path": after.info.path,
            "path_reason": after.info.path_reason,
            "status_before": before.info.solver_statistics.status_counts,
            "status_after": after.info.solver_statistics.status_counts,
            "cpu_s_per_s_before": cpu["before"],
            "cpu_s_per_s_after": cpu["after"],
            "speedup": cpu["before"] / cpu["after"],
            "max_dq_rad": float(np.max(np.abs(before.q - after.q))),
            "events": len(after.info.contact_events),
        }
        row = results[name]
        print(
            f"{name:<13} {row['path']}: before {row['cpu_s_per_s_before']:.3f} after {row['cpu_s_per_s_after']:.3f} "
            f"CPU s/s, {row['speedup']:.2f}x; max |dq| {row['max_dq_rad']:.2e} rad; {row['events']} events",
            flush=True,
        )
    costs = row_costs()
    results["limit_rows_us"] = {**costs, "pinocchio_over_core": costs["pinocchio"] / costs["core"]}
    print(f"limit rows from Python per evaluation: core {costs['core']:.2f} us, Pinocchio's JointLimitConstraintModel "
          f"{costs['pinocchio']:.2f} us; the core kernel's evaluation: closure only {costs['kernel_closure_only']:.2f} "
          f"us, with two limits held {costs['kernel_two_limits_held']:.2f} us")  # fmt: skip
    save_results(OUT, results)


if __name__ == "__main__":
    main()

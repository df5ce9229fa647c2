"""Should the core's KKT solve exploit sparsity? (issue 35, Deliver 2: "decide by measurement"). On cassie (nv 32,
16 closures), delta and the N-four-bar at N = 10, 40, 80 on the core path (forced: the N-four-bar takes the banded
path), at a state of a short run, side by side in one run:

- the cost of each part of one core evaluation (``pinstab._compiled.kkt_cost_split``, cpp/kkt_sparsity_bindings.cpp:
  the core's own pass and rows, then the dense solve of cpp/kkt_solve.cpp part by part, and whole), and of the sparse
  solves that could replace its dense part: the core's structured solve (``KktSolve::solve`` given the model: the tree
  factorization of M and the Delassus matrix in sparse storage where ``sparse_delassus_pays``, else the dense solve),
  Pinocchio's tree LDL^T of M (``cholesky::decompose``) under the dense Delassus matrix, Eigen's sparse Cholesky of M
  and of the Delassus matrix (``SimplicialLLT``), Eigen's sparse LDL^T of the regularized KKT matrix
  (``SimplicialLDLT``, refined twice on the exact system), each one's accelerations against the extended-precision
  solve of the whole KKT system (``pinstab.solvers.ExtendedSolver``, an independent reference);
- the core evaluation as its step loop makes it now, with the structured solve (compiled RK4 at 1 ms over STEPS steps,
  CPU s per evaluation);
- Pinocchio 4.1 on the closures it can express (point, planar-point as 3-D contacts; weld, revolute, prismatic as 6-D
  ones; Cassie's gearbox relations have no Pinocchio form and are left out, so its problem is a proxy): the
  factorization alone (``ContactCholeskyDecomposition.compute``, the cost of an empty binding call subtracted) and the
  whole ``constraintDynamics`` call at each proximal mu, with its accelerations' distance from the exact solution of its
  own KKT system (dense least squares in extended precision, its Jacobian and drift from Pinocchio itself).

A sparse solve pays where (pass + rows + its parts) is below (pass + rows + the dense KktSolve) by 1.2x or more.

    python benchmarks/kkt_sparsity.py    # prints the tables, writes benchmarks/results/kkt_sparsity.json (~3 min)
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

import pinstab
from pinstab.bench import save_results
from pinstab.bench.kkt_split import split_and_reference
from pinstab.constraints import FrameClosure
from pinstab.integration.compiled import SCHEMES
from pinstab.kinematics import LWA
from pinstab.model import ConstrainedModel
from pinstab.paths.core import CoreDynamics
from pinstab.solvers.base import ACCEPTED_RESIDUAL
from pinstab.solvers.proxsuite_ import DIRECT_PIVOT
from pinstab.system import build_system

CASES = {
    "cassie": ("cassie", {}),
    "delta": ("delta", {}),
    "nfourbar N=10": ("nfourbar", {"N": 10}),
    "nfourbar N=40": ("nfourbar", {"N": 40}),
    "nfourbar N=80": ("nfourbar", {"N": 80}),
}
WARM_UP = 0.05  # [s]: the state measured is the end of a run this long (the N-four-bar away from its start)
ROUNDS, REPEATS = 15, 40  # parts: the median of ROUNDS interleaved rounds of REPEATS calls
STEPS = 200  # the core's step loop: RK4 steps of DT
DT = 1e-3  # [s]
REGULARIZATION = 1e-10  # the sparse KKT LDL^T's -eps I block, relative to M's largest diagonal entry
MUS = (1e-12, 1e-10, 1e-8, 1e-6, 1e-4)  # Pinocchio's proximal mu
PROXIMAL_ITERATIONS = 50
PAYS = 1.2  # the factor a sparse solve must gain on the evaluation
DENSE = ("dense: KktSolve::solve",)
SOLVES = {  # each solve's parts besides the pass and the rows
    "dense (today)": DENSE,
    "structured KktSolve": ("structured: KktSolve::solve",),
    "tree M + dense Delassus": (
        "tree: M factorization",
        "tree: Delassus",
        "dense: Delassus factorization",
        "dense: solve",
    ),
    "sparse M + sparse Delassus": (
        "sparse: to sparse",
        "sparse: M factorization",
        "sparse: Delassus",
        "sparse: Delassus factorization",
        "sparse: solve",
    ),
    "sparse KKT LDL^T": ("sparse KKT: to sparse", "sparse KKT: factorization", "sparse KKT: solve"),
}
ACCURACY_OF = {
    "dense (today)": "KktSolve",
    "structured KktSolve": "structured",
    "tree M + dense Delassus": "tree",
    "sparse M + sparse Delassus": "sparse",
    "sparse KKT LDL^T": "sparse KKT",
}
OUT = Path(__file__).parent / "results" / "kkt_sparsity.json"


def cpu_per_call(call: Any, repeats: int) -> float:
    """CPU seconds per call of ``call()``, the median of 5 rounds of ``repeats`` calls."""
    samples = []
    for _ in range(5):
        began = time.process_time()
        for _ in range(repeats):
            call()
        samples.append((time.process_time() - began) / repeats)
    return float(np.median(samples))


def relative(a: np.ndarray, reference: np.ndarray) -> float:
    """max |a - reference| / max |reference| [-]."""
    return float(np.max(np.abs(a - reference)) / np.max(np.abs(reference)))


def pinocchio_contacts(model: ConstrainedModel) -> tuple[pin.StdVec_RigidConstraintModel, list[str]]:
    """Pinocchio's contacts for the closures it can express (Kp = Kd = 0: the bare rows), and the constraints left
    out."""
    contacts, left_out = pin.StdVec_RigidConstraintModel(), []
    kinds = {"point": pin.ContactType.CONTACT_3D, "planar-point": pin.ContactType.CONTACT_3D}
    for constraint in model.constraints.constraints:
        if not isinstance(constraint, FrameClosure):
            left_out.append(constraint.name)
            continue
        (joint_a, placement_a), (joint_b, placement_b) = constraint.sides(model.model)
        kind = kinds.get(constraint.kind, pin.ContactType.CONTACT_6D)
        contacts.append(pin.RigidConstraintModel(kind, model.model, joint_a, placement_a, joint_b, placement_b, LWA))
    return contacts, left_out


def pinocchio_side(model: ConstrainedModel, q: np.ndarray, v: np.ndarray) -> dict[str, Any]:
    """Pinocchio's factorization alone and its whole constraintDynamics at each mu, with their accuracy."""
    contacts, left_out = pinocchio_contacts(model)
    data = model.model.createData()
    datas = pin.StdVec_RigidConstraintData()
    for contact in contacts:
        datas.append(contact.createData())
    pin.initConstraintDynamics(model.model, data, contacts, datas)
    tau = np.zeros(model.nv)
    exact = pin.ProximalSettings(1e-14, 0.0, 1)  # mu = 0: one factorization of the exact KKT matrix
    pin.constraintDynamics(model.model, data, q, v, tau, contacts, datas, exact)
    # its own KKT system [0 J; J^T M] (-lambda, a) = (rhs, tau - h), J and rhs (the drift) from Pinocchio itself
    jacobian = pin.getConstraintsJacobian(model.model, data, contacts, datas)
    mass = np.triu(data.M) + np.triu(data.M, 1).T
    rows = jacobian.shape[0]
    system = np.block([[np.zeros((rows, rows)), jacobian], [jacobian.T, mass]])
    target = np.concatenate([data.primal_rhs_contact, tau - data.nle]).astype(np.longdouble)
    solution = np.zeros(model.nv + rows, dtype=np.longdouble)
    for _ in range(3):
        miss = np.asarray(target - system.astype(np.longdouble) @ solution, dtype=float)
        solution = solution + np.linalg.lstsq(system, miss, rcond=None)[0]
    reference = np.asarray(solution[rows:], dtype=float)
    decomposition = pin.ContactCholeskyDecomposition(model.model, data, contacts, datas)
    overhead = cpu_per_call(decomposition.size, 2000)
    factorization = {
        f"{mu:g}": cpu_per_call(lambda mu=mu: decomposition.compute(model.model, data, contacts, datas, mu), 200)
        - overhead
        for mu in (0.0, 1e-8)
    }
    empty = cpu_per_call(lambda: pin.neutral(model.model), 2000)  # a call of similar arguments' conversion
    dynamics = {}
    for mu in MUS:
        settings = pin.ProximalSettings(1e-12, mu, PROXIMAL_ITERATIONS)
        a = pin.constraintDynamics(model.model, data, q, v, tau, contacts, datas, settings).copy()
        cost = cpu_per_call(
            lambda settings=settings: pin.constraintDynamics(model.model, data, q, v, tau, contacts, datas, settings),
            100,
        )
        dynamics[f"{mu:g}"] = {
            "s_per_call": cost - empty,
            "iterations": int(settings.iter),
            "acceleration_error_relative": relative(a, reference),
        }
    return {
        "rows": rows,
        "left_out": left_out,
        "empty_call_s": overhead,
        "factorization_s": factorization,
        "constraint_dynamics": dynamics,
    }


def measure(label: str, name: str, parameters: dict[str, Any]) -> dict[str, Any]:
    scene = pinstab.load_scene(name, **parameters)
    run = pinstab.simulate(scene, duration=WARM_UP, progress=False)
    q, v = run.q[-1].copy(), run.v[-1].copy()
    q_other = run.q[len(run.q) // 2].copy()
    model = ConstrainedModel(scene)
    split, reference = split_and_reference(model, q, v, q_other, ROUNDS, REPEATS, REGULARIZATION)
    seconds: dict[str, float] = split["seconds"]
    base = seconds["pass (kinematics, M, h)"] + seconds["rows"]
    evaluations = {solve: base + sum(seconds[part] for part in parts) for solve, parts in SOLVES.items()}
    solves = {
        solve: {
            "evaluation_s": evaluations[solve],
            "solve_s": evaluations[solve] - base,
            "evaluation_speedup": evaluations["dense (today)"] / evaluations[solve],
            "acceleration_error_relative": relative(split["acceleration"][ACCURACY_OF[solve]], reference),
        }
        for solve in SOLVES
    }
    # the core evaluation in its own step loop (the stabilization term, the forces, the status bookkeeping included)
    system = build_system(scene)
    system.bind(DT, "rk4", q)
    term = system.stabilizer.core_term()  # Baumgarte's at its defaults
    core = CoreDynamics(model, term, DIRECT_PIVOT, ACCEPTED_RESIDUAL).kernel
    tau = np.zeros(model.nv)
    loop = cpu_per_call(lambda: core.run(SCHEMES["rk4"], q, v, tau, DT, STEPS, 0), 1) / (4 * STEPS)
    row = {
        "nv": model.nv,
        "rows": int(split["jacobian"].shape[0]),
        "rank_dependent": bool(split["dependent"]),
        "nonzeros": split["nnz"],
        "parts_s": seconds,
        "solves": solves,
        "core_step_loop_s_per_evaluation": loop,
        "pinocchio": pinocchio_side(model, q, v),
    }
    best = max(solves, key=lambda solve: solves[solve]["evaluation_speedup"])
    print(
        f"{label:<14} nv {row['nv']:>3} rows {row['rows']:>3}{' (dependent)' if row['rank_dependent'] else ''}: "
        f"pass {seconds['pass (kinematics, M, h)'] * 1e6:7.1f} us, rows {seconds['rows'] * 1e6:6.1f} us, "
        f"dense solve {solves['dense (today)']['solve_s'] * 1e6:7.1f} us; step loop "
        f"{loop * 1e6:7.1f} us/evaluation",
        flush=True,
    )
    for solve, figures in solves.items():
        print(
            f"    {solve:<28} solve {figures['solve_s'] * 1e6:8.1f} us  "
            f"evaluation x{figures['evaluation_speedup']:5.2f}"
            f"  |da|/|a| {figures['acceleration_error_relative']:.1e}",
            flush=True,
        )
    pinocchio_row = row["pinocchio"]
    print(
        f"    Pinocchio ({pinocchio_row['rows']} rows, left out: {len(pinocchio_row['left_out'])}): factorization "
        + ", ".join(f"mu {mu} {s * 1e6:.1f} us" for mu, s in pinocchio_row["factorization_s"].items())
        + "; constraintDynamics "
        + ", ".join(
            f"mu {mu} {d['s_per_call'] * 1e6:.1f} us ({d['iterations']} it, {d['acceleration_error_relative']:.0e})"
            for mu, d in pinocchio_row["constraint_dynamics"].items()
        ),
        flush=True,
    )
    row["best_sparse"] = best
    return row


def main() -> None:
    rows = {label: measure(label, name, parameters) for label, (name, parameters) in CASES.items()}
    pays = {
        label: [
            solve
            for solve, f in row["solves"].items()
            if solve != "dense (today)"
            and f["evaluation_speedup"] >= PAYS
            and f["acceleration_error_relative"] <= 1e-11
        ]
        for label, row in rows.items()
    }
    for label, solves in pays.items():
        print(f"{label}: a sparse solve pays (>= {PAYS}x on the evaluation, 1e-11 accurate): {solves or 'none'}")
    save_results(
        OUT,
        {
            "warm_up_s": WARM_UP,
            "rounds": ROUNDS,
            "repeats": REPEATS,
            "regularization": REGULARIZATION,
            "pays_factor": PAYS,
            "cases": rows,
            "pays": pays,
        },
    )


if __name__ == "__main__":
    main()

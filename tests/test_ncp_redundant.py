"""The checked cone solve (pinstab.solvers.ncp, cpp/cone_solve.hpp) on redundant contacts (issue 36): hand-cube's cube
on the table, under the palm and between three fingertips, 11 contacts whose Delassus matrix (33 x 33) has rank 12.
The problem (tests/data/hand_cube_redundant.json: D, g, mus and ADMM's answer after 1e5 iterations) is the run's at
t = 0.5 s (dt = 1 ms), taken with the admission growth of pinstab.integration.contact_stepping."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from pinstab.solvers.ncp import CHECK_RTOL, NcpSolver, admm_settings, friction_cones, ncp_residual

PROBLEM = {
    name: np.array(values)
    for name, values in json.loads((Path(__file__).parent / "data" / "hand_cube_redundant.json").read_text()).items()
}


def test_the_problem_is_redundant_and_admm_alone_does_not_stop():
    """ADMM to its own tolerance (1e-12) runs out of 1e4 iterations: its impulses drift within the set of solutions
    (the same contact velocities), which its tolerances on their change never meet."""
    delassus, g, mus = PROBLEM["delassus"], PROBLEM["g"], PROBLEM["mus"]
    assert np.linalg.matrix_rank(delassus) == 12 and max(mus) <= 1.0  # cones of at most 1: posed as they are
    solver, result = pin.ADMMConstraintSolver(len(g)), pin.ADMMSolverResult()
    models, datas = friction_cones(mus)
    solver.solve(pin.DelassusOperatorDense(0.5 * (delassus + delassus.T)), g, models, datas,
                 admm_settings(1e-12, 10_000), result)  # fmt: skip
    assert not result.converged and result.iterations > 10_000


def test_the_checked_solve_settles_in_a_few_runs():
    """The solve, run for 128 then 64 iterations (the first run's residual settled against its half), ends in 194 (250
    asserted: a run of 256 after the first, 386; ADMM alone ran out of 1e4) with the contact velocities sigma = D lambda
    + g of ADMM's answer after 1e5 iterations to 1e-8 m/s (measured 5.8e-9 m/s, of a scale of 0.21 m/s), though the
    impulses differ by half their size (2.4e-3 of 4.8e-3 N s: not unique); its residual far within the check (8.9e-11
    m/s)."""
    delassus, g, mus, reference = (PROBLEM[name] for name in ("delassus", "g", "mus", "reference"))
    solver = NcpSolver(len(g))
    impulses = solver.cones.solve(delassus, g, mus, CHECK_RTOL)
    solver.read_status()
    status = solver.status()
    assert solver.method == "ADMM" and status.converged and status.iterations <= 250
    velocities, expected = delassus @ impulses + g, delassus @ reference + g
    assert np.max(np.abs(velocities - expected)) <= 1e-8
    assert np.max(np.abs(impulses - reference)) > 1e-3  # another solution, the same velocities
    scale = max(np.max(np.abs(g)), np.max(np.abs(delassus @ impulses)))
    assert ncp_residual(delassus, g, impulses, mus) <= 1e-9 * scale

"""Clarabel, an interior-point solver for conic programs, as pinstab calls it: ``min c^T x`` subject to
``G x + slack = h`` with the slack in a product of cones (zero, non-negative, second-order), one thread, its gap and
feasibility tolerances given, its linear systems refined to :data:`REFINEMENT` (near a grasp's let-go, where the
held set shrinks to a point, Clarabel's default refinement ended 357 of 845 solves of allegro-drop's first 0.15 s in
numerical errors). Its answer is x with the status's name; callers check it against their own limits."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

SOLVED = ("Solved", "AlmostSolved")  # statuses whose x a caller may keep (after its own checks)
PRIMAL_INFEASIBLE = "PrimalInfeasible"  # the status of a certificate that no x meets the constraints
INFEASIBLE = (PRIMAL_INFEASIBLE, "AlmostPrimalInfeasible")  # statuses that say no x meets them (the second: reduced
# accuracy)
REFINEMENT, REFINEMENT_PASSES = 1e-14, 50  # iterative refinement: tolerance, passes (default 1e-13, 1e-12, 10)
CONES = ("zero", "nonnegative", "second-order")  # the cone kinds of :func:`conic_solve`


def conic_solve(
    gradient: np.ndarray,
    matrix: np.ndarray,
    bounds: np.ndarray,
    cones: Sequence[tuple[str, int]],
    tolerance: float,
) -> tuple[str, np.ndarray]:
    """``min c^T x`` (``gradient`` c) with ``G x + slack = h`` (``matrix`` G, ``bounds`` h), the slack's entries in
    ``cones`` in their order, each (kind, size), kind one of :data:`CONES`; Clarabel's gap and feasibility tolerances
    ``tolerance`` (relative). Returns (Clarabel's status's name, x)."""
    import clarabel
    from scipy import sparse

    kinds = {"zero": clarabel.ZeroConeT, "nonnegative": clarabel.NonnegativeConeT}
    kinds["second-order"] = clarabel.SecondOrderConeT
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_threads = 1
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tolerance
    settings.tol_infeas_abs = settings.tol_infeas_rel = tolerance
    settings.iterative_refinement_reltol = settings.iterative_refinement_abstol = REFINEMENT
    settings.iterative_refinement_max_iter = REFINEMENT_PASSES
    count = len(gradient)
    solver = clarabel.DefaultSolver(
        sparse.csc_matrix((count, count)),
        np.asarray(gradient, float),
        sparse.csc_matrix(matrix),
        np.asarray(bounds, float),
        [kinds[kind](size) for kind, size in cones if size],
        settings,
    )
    solution = solver.solve()
    return str(solution.status), np.array(solution.x)

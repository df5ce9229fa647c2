"""The core KKT solve's parts measured one by one (``kkt_cost_split``, ``cpp/kkt_sparsity_bindings.cpp``) beside the
extended system's acceleration at the same state: the problem ``benchmarks/kkt_sparsity.py`` times and
``tests/test_kkt_structured.py`` checks."""

from __future__ import annotations

from typing import Any

import numpy as np

from pinstab.kernels import kkt_cost_split
from pinstab.model import ConstrainedModel
from pinstab.solvers import ExtendedSolver
from pinstab.solvers.base import KKTProblem


def split_and_reference(
    model: ConstrainedModel,
    q: np.ndarray,
    v: np.ndarray,
    q_other: np.ndarray,
    rounds: int,
    repeats: int,
    regularization: float,
) -> tuple[dict[str, Any], np.ndarray]:
    """``kkt_cost_split`` at (q [rad or m], v [rad/s or m/s]) (timed over ``rounds`` x ``repeats`` calls, alternating
    with ``q_other``; ``regularization`` the proximal term of the regularized candidates) and the extended system's
    acceleration [rad/s^2 or m/s^2] on the same mass matrix, forces, rows and right-hand side, the reference the
    candidates' accelerations are compared with."""
    blocks = [constraint.compiled_rows() for constraint in model.constraints.constraints]
    split = kkt_cost_split(model.model, blocks, q, v, q_other, rounds, repeats, regularization)
    problem = KKTProblem(
        q,
        v,
        0.0,
        np.zeros(model.nv),
        split["mass"],
        split["force"],
        split["jacobian"],
        split["rhs"],
        model.constraints.layout,
    )
    return split, ExtendedSolver().solve(problem).acceleration

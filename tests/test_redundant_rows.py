"""Redundant constraint rows: the accelerations do not depend on which of the redundant rows are kept,
and every solver that takes rank-deficient rows gives those accelerations."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import ConstrainedModel, build_system, load_scene, simulate

RANK_TOLERANCE = 1e-9  # singular values of G below this fraction of the largest: dependent rows


def kept_rows_acceleration(model: ConstrainedModel, q: np.ndarray, v: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The constrained acceleration [rad/s^2] with the rows ``rows @ (G a + gamma) = 0`` (a selection or a
    combination of G's rows), by numpy's KKT solve (independent of pinstab's solvers)."""
    terms = model.dynamics_terms(q, v, 0.0)
    mass, force = terms.mass_matrix, terms.tau - terms.bias
    jacobian, drift = rows @ terms.values.jacobian, rows @ terms.values.drift
    nv, s = mass.shape[0], rows.shape[0]
    kkt = np.block([[mass, jacobian.T], [jacobian, np.zeros((s, s))]])
    return np.linalg.solve(kkt, np.concatenate((force, -drift)))[:nv]


@pytest.mark.parametrize("solver", ["proxsuite", "pinocchio"])
def test_accelerations_do_not_depend_on_the_rows_kept(solver):
    """The five-bar (rows of rank one less than their count) at a state of its motion: every row that can
    be dropped without losing rank, dropped, and G's orthonormal row basis (from its SVD) give the same
    acceleration to 1e-9 (relative); the solver, given every row, the same to 1e-7."""
    scene = load_scene("fivebar")
    model = ConstrainedModel(scene)
    run = simulate(scene, method="projection", dt=1e-3, duration=0.3)
    q, v = run.q[-1], run.v[-1]
    jacobian = model.constraint_values(q, v, 0.0).jacobian
    values = np.linalg.svd(jacobian, compute_uv=False)
    rank = int(np.sum(values > RANK_TOLERANCE * values[0]))
    assert jacobian.shape[0] - rank >= 1  # redundant rows at this state
    basis = np.linalg.svd(jacobian)[0][:, :rank].T
    variants = [kept_rows_acceleration(model, q, v, basis)]
    identity = np.eye(jacobian.shape[0])
    for dropped in range(jacobian.shape[0]):
        rows = np.delete(identity, dropped, axis=0)
        if np.linalg.matrix_rank(rows @ jacobian, tol=RANK_TOLERANCE * values[0]) == rank:
            variants.append(kept_rows_acceleration(model, q, v, rows))
    assert len(variants) >= 2
    scale = np.abs(variants[0]).max()
    for variant in variants[1:]:
        np.testing.assert_allclose(variant, variants[0], rtol=0, atol=1e-9 * scale)
    system = build_system(scene, method="none", solver=solver)
    np.testing.assert_allclose(system.acceleration(q, v, 0.0, 0), variants[0], rtol=0, atol=1e-7 * scale)

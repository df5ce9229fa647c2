"""Mukharlyamov's inertial variant on the core (cpp/inertial_term.cpp): its matrices against numpy's formulas, and its
trajectory against the general path's, which computes the same matrices from its own rows and mass matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pinstab import kernels, simulate


def test_inertial_matrices_are_the_formulas_with_a_redundant_row():
    """S = D H, K = D B - (D_ahead - D) / eps D^+ with D = G M^-1 G^T, D^+ by numpy's pinv at the same cutoff: a third
    row that repeats the first (D singular) is left out of D^+ as numpy leaves it out (to 1e-12 relative)."""
    rng = np.random.default_rng(3)
    nv, rows = 5, 3
    root = rng.normal(size=(nv, nv))
    mass, mass_ahead = root @ root.T + nv * np.eye(nv), root @ root.T + (nv + 1e-3) * np.eye(nv)
    jacobian = rng.normal(size=(rows, nv))
    jacobian[2] = jacobian[0]
    jacobian_ahead = jacobian + 1e-4 * rng.normal(size=(rows, nv))
    gains = {"stiffness": rng.normal(size=(rows, rows)), "damping": rng.normal(size=(rows, rows)), "rate_step": 1e-4}
    gains["cutoff"] = 1e-10
    stiffness, damping = kernels.inertial_matrices(gains, mass, jacobian, mass_ahead, jacobian_ahead)
    delassus = jacobian @ np.linalg.solve(mass, jacobian.T)
    ahead = jacobian_ahead @ np.linalg.solve(mass_ahead, jacobian_ahead.T)
    expected_damping = delassus @ gains["damping"] - (ahead - delassus) / 1e-4 @ np.linalg.pinv(delassus, rcond=1e-10)
    np.testing.assert_allclose(stiffness, delassus @ gains["stiffness"], rtol=0, atol=1e-12 * np.abs(stiffness).max())
    np.testing.assert_allclose(damping, expected_damping, rtol=0, atol=1e-9 * np.abs(expected_damping).max())
    pseudo = kernels.delassus_pseudo_inverse(delassus, 1e-10)
    np.testing.assert_allclose(pseudo, np.linalg.pinv(delassus, rcond=1e-10), rtol=0, atol=1e-12 * np.abs(pseudo).max())


def test_the_core_runs_the_inertial_term_as_the_general_path_does():
    """The four-bar over 2 s (automatic gains, RK4 at 1 ms, the term held over each step): the core's trajectory equals
    the general path's (solver dense) to 1e-11 rad in q and 1e-10 rad/s in v (measured 4.5e-13 and 7.3e-12)."""
    common = dict(method="mukharlyamov", variant="inertial", dt=1e-3, duration=2.0, progress=False)
    core = simulate("fourbar", **common)
    general = simulate("fourbar", solver="dense", **common)
    assert (core.info.path, general.info.path) == ("core", "general")
    np.testing.assert_allclose(core.q, general.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(core.v, general.v, rtol=0, atol=1e-10)
    assert core.position_drift.max() < 1e-9


@pytest.mark.parametrize("delassus", [[[math.inf]], [[1.0, math.inf], [math.inf, 1.0]], [[math.nan]]])
def test_the_pseudo_inverse_of_a_delassus_matrix_that_is_not_finite_is_nan(delassus):
    """D^+ of a D that overflowed is NaN (its caller then refuses the state), not 0: the 1 x 1 infinite D decomposes
    without an error (eigenvalue inf), and a cutoff of cutoff * inf kept no eigenvalue, a zero D^+ that read as 'no
    correction needed'."""
    assert np.isnan(kernels.delassus_pseudo_inverse(np.array(delassus), 1e-10)).all()

"""The core's KKT solve on the kinematic tree (cpp/kkt_solve.hpp, KktSolve::solve with the model): M factored along the
tree, the Delassus matrix in sparse storage where it is sparse (the N-four-bar's long chain of loops), against the
extended-precision solve of the whole KKT system (``ExtendedSolver``, which forms no Delassus matrix) and against the
dense solve of the same problem."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import load_scene, simulate
from pinstab.bench.kkt_split import split_and_reference
from pinstab.model import ConstrainedModel

EXACT = 1e-11  # relative to the largest |a| (the refinement's bound, tests/test_kkt_refinement.py)


def _solved(scene, q, v):
    """kkt_cost_split at (q, v) once: the problem, each solve's accelerations and the extended solve's."""
    return split_and_reference(ConstrainedModel(scene), q, v, q, 1, 1, 1e-10)


def _off(a, reference):
    return np.abs(a - reference).max() / np.abs(reference).max()


def test_a_long_chain_of_loops_takes_the_sparse_delassus_matrix_and_the_exact_solution():
    scene = load_scene("nfourbar", N=40)
    run = simulate(scene, duration=0.05, progress=False)
    split, reference = _solved(scene, run.q[-1], run.v[-1])
    assert split["structured_sparse"]
    assert split["structured_outcome"] == 0  # direct: independent rows by the direct test
    assert _off(split["acceleration"]["structured"], reference) <= EXACT
    assert _off(split["acceleration"]["KktSolve"], reference) <= EXACT


def test_the_sparse_solve_at_the_aligned_configuration_takes_the_pseudo_inverse():
    """Every crank horizontal (the couplers along them): the loops' rows dependent, the sparse factor fails the direct
    test and the pseudo-inverse of the same Delassus matrix answers as the dense solve's."""
    scene = load_scene("nfourbar", N=20)
    model = ConstrainedModel(scene)
    q = np.zeros(model.nv)
    for joint in range(1, model.model.njoints):
        name = model.model.names[joint]
        q[model.model.joints[joint].idx_q] = -np.pi / 2 if name.startswith("crank") else np.pi / 2
    v = scene.v0.copy()
    split, reference = _solved(scene, q, v)
    assert split["structured_sparse"]
    assert split["structured_outcome"] == split["outcome"] == 2  # pseudo-inverse
    assert _off(split["acceleration"]["structured"], split["acceleration"]["KktSolve"]) <= 1e-10
    assert _off(split["acceleration"]["structured"], reference) <= 1e-8


@pytest.mark.parametrize("scene_name", ["cassie", "delta"])
def test_a_floating_base_or_a_short_stack_keeps_the_dense_delassus_matrix(scene_name):
    scene = load_scene(scene_name)
    run = simulate(scene, duration=0.01, progress=False)
    split, reference = _solved(scene, run.q[-1], run.v[-1])
    assert not split["structured_sparse"]
    assert split["structured_outcome"] == split["outcome"]
    assert _off(split["acceleration"]["structured"], split["acceleration"]["KktSolve"]) <= EXACT
    assert _off(split["acceleration"]["structured"], reference) <= EXACT

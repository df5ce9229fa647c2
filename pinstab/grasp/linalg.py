"""Small dense factorizations at every evaluation of a grasp force element, through LAPACK directly:
numpy's wrappers cost more than the factorization of a matrix of a few dozen entries."""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgesdd

from .. import kernels

RANK_TOLERANCE = 1e-10  # singular values below this times the largest (or 1) count as zero
NORMAL_EQUATIONS_CONDITION = 300.0  # condition of A at most this: the normal equations lose < 1e-11


def svd(matrix: np.ndarray, full: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(u, s, vt)`` as ``np.linalg.svd(matrix, full_matrices=full)`` gives them (LAPACK's ``gesdd``, as
    numpy calls it); numpy's own call when LAPACK reports a failure (it raises ``LinAlgError``)."""
    u, s, vt, info = dgesdd(matrix, compute_uv=1, full_matrices=int(full))
    if info != 0:
        return np.linalg.svd(matrix, full_matrices=full)
    return u, s, vt


def pinv(matrix: np.ndarray, rcond: float = 1e-15) -> np.ndarray:
    """The pseudo-inverse as ``np.linalg.pinv(matrix, rcond)`` computes it: singular values above ``rcond``
    times the largest inverted, the others dropped."""
    u, s, vt = svd(matrix, full=False)
    large = s > rcond * np.max(s, initial=0.0)
    inverse = np.divide(1.0, s, where=large, out=np.zeros_like(s))
    return vt.T @ (inverse[:, None] * u.T)


def closest_solution(matrix: np.ndarray, rhs: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The x closest to ``target`` among the least-squares solutions of ``matrix x = rhs`` (k x m):
    ``target + A^+ (rhs - A target)``, singular values below :data:`RANK_TOLERANCE` times the largest (or 1)
    dropped. A of full row rank whose A A^T has a condition number (Eigen's estimate) at most
    :data:`NORMAL_EQUATIONS_CONDITION` squared: through the Cholesky factor of A A^T (the same x to 1e-12
    relative, at a third of the cost of the SVD), else through the SVD. The compiled rule (``cpp/grasp_forces.cpp``,
    the core's hold's too); entries that are not numbers where the terms are not."""
    x, _ = kernels.closest_solution(matrix, rhs, target, RANK_TOLERANCE, NORMAL_EQUATIONS_CONDITION)
    return x

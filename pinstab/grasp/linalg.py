"""Small dense factorizations at every evaluation of a grasp force element, through LAPACK directly:
numpy's wrappers cost more than the factorization of a matrix of a few dozen entries."""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgesdd


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

"""KKT backends (docs/mathematics.md eq. 4-5), one per module, each registered in :data:`SOLVERS`:
``proxsuite`` (default), ``pinocchio``, ``dense``, ``extended`` (a reference)."""

from ..registry import load_extensions
from .base import SOLVERS, KKTProblem, KKTSolution, KKTSolver, solvers_with
from .dense_ import DenseSolver
from .extended_ import ExtendedSolver
from .pinocchio_ import PinocchioSolver
from .proxsuite_ import ProxsuiteSolver

load_extensions(__name__, __path__)

__all__ = [
    "SOLVERS",
    "DenseSolver",
    "ExtendedSolver",
    "KKTProblem",
    "KKTSolution",
    "KKTSolver",
    "PinocchioSolver",
    "ProxsuiteSolver",
    "solvers_with",
]

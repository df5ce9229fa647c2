"""KKT backends (MATH.md eq. 4-5): ``proxsuite`` (default), ``pinocchio``, ``dense``."""

from .base import KKTProblem, KKTSolution, KKTSolver
from .dense_ import DenseSolver
from .pinocchio_ import PinocchioSolver
from .proxsuite_ import ProxsuiteSolver

SOLVERS = ("proxsuite", "pinocchio", "dense")

__all__ = ["SOLVERS", "DenseSolver", "KKTProblem", "KKTSolution", "KKTSolver", "PinocchioSolver", "ProxsuiteSolver"]

"""pinstab: constrained multibody simulation on Pinocchio with measurable constraint stabilization.

Public API::

    scene = pinstab.load_scene("fourbar")          # or a path to a TOML scene file
    traj = pinstab.simulate(scene, method="baumgarte", integrator="rk4", dt=1e-3, duration=10)
    traj.summary()["max_position_drift"]
"""

from .assembly import AssemblyReport, assemble
from .constraints import Constraint, FrameClosure, HolonomicConstraint, PfaffianConstraint
from .errors import (
    AssemblyError,
    ConstraintError,
    DivergenceError,
    PinstabError,
    ProjectionError,
    SceneError,
    SolverError,
    UnstableGainsError,
    UnstableGainsWarning,
)
from .integrators import INTEGRATORS
from .scene import Scene, load_scene
from .simulate import build_system, simulate
from .solvers import SOLVERS
from .stabilizers import METHODS
from .system import ConstrainedSystem
from .trajectory import Trajectory

__version__ = "0.1.0"

__all__ = [
    "INTEGRATORS",
    "METHODS",
    "SOLVERS",
    "AssemblyError",
    "AssemblyReport",
    "ConstrainedSystem",
    "Constraint",
    "ConstraintError",
    "DivergenceError",
    "FrameClosure",
    "HolonomicConstraint",
    "PfaffianConstraint",
    "PinstabError",
    "ProjectionError",
    "Scene",
    "SceneError",
    "SolverError",
    "Trajectory",
    "UnstableGainsError",
    "UnstableGainsWarning",
    "__version__",
    "assemble",
    "build_system",
    "load_scene",
    "simulate",
]

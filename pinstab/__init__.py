"""pinstab: constrained multibody simulation on Pinocchio with measurable constraint stabilization.

Public API::

    scene = pinstab.load_scene("fourbar")          # or a path to a TOML scene file
    traj = pinstab.simulate(scene, method="baumgarte", integrator="rk4", dt=1e-3, duration=10)
    traj.summary()["max_position_drift"]
"""

from . import grasp as grasp  # registers the force kinds grasp-hold and grasp-control (they sit above the scene)
from .actuation import Actuation
from .analysis import EXACT_REFERENCES, trajectory_error
from .assembly import AssemblyReport, assemble
from .constraints import (
    CONSTRAINT_KINDS,
    Constraint,
    FrameClosure,
    FrictionCone,
    HolonomicConstraint,
    PfaffianConstraint,
    PointContact,
    RowKind,
)
from .errors import (
    AssemblyError,
    BranchChangeWarning,
    ConstraintError,
    ContactInfeasibleError,
    CutShortWarning,
    DivergenceError,
    EdgeContactWarning,
    GraspLostError,
    JointLimitsWarning,
    MemoryBudgetError,
    NewtonError,
    PenetrationWarning,
    PinstabError,
    PinstabWarning,
    ProjectionError,
    SceneError,
    ServoInfeasibleError,
    SolverError,
    StepTooLargeError,
    StiffStepError,
    UnstableGainsError,
    UnstableGainsWarning,
    WaypointError,
    ZeroDynamicsWarning,
)
from .forces import FORCE_KINDS, ForceElement
from .integration import INTEGRATORS
from .memory import memory_limit
from .model import ConstrainedModel
from .registry import NoOptions, Registry
from .runinfo import RunInfo, SolverStatistics
from .scene import Scene, load_scene
from .simulate import simulate
from .solvers import SOLVERS
from .stabilizers import STABILIZERS, Stabilizer
from .system import ConstrainedSystem, build_system
from .trajectory import Comparison, Trajectory

METHODS = STABILIZERS  # the registered method names (a registry iterates over its names)
__version__ = "0.1.0"

__all__ = [
    "CONSTRAINT_KINDS",
    "EXACT_REFERENCES",
    "FORCE_KINDS",
    "INTEGRATORS",
    "METHODS",
    "SOLVERS",
    "STABILIZERS",
    "Actuation",
    "AssemblyError",
    "AssemblyReport",
    "BranchChangeWarning",
    "Comparison",
    "ConstrainedModel",
    "ConstrainedSystem",
    "Constraint",
    "ConstraintError",
    "ContactInfeasibleError",
    "CutShortWarning",
    "DivergenceError",
    "EdgeContactWarning",
    "ForceElement",
    "FrameClosure",
    "FrictionCone",
    "GraspLostError",
    "JointLimitsWarning",
    "MemoryBudgetError",
    "NewtonError",
    "HolonomicConstraint",
    "NoOptions",
    "PfaffianConstraint",
    "PenetrationWarning",
    "PinstabError",
    "PinstabWarning",
    "PointContact",
    "ProjectionError",
    "Registry",
    "RowKind",
    "RunInfo",
    "Scene",
    "SceneError",
    "ServoInfeasibleError",
    "SolverError",
    "SolverStatistics",
    "StepTooLargeError",
    "StiffStepError",
    "Stabilizer",
    "Trajectory",
    "UnstableGainsError",
    "UnstableGainsWarning",
    "WaypointError",
    "ZeroDynamicsWarning",
    "__version__",
    "assemble",
    "build_system",
    "load_scene",
    "memory_limit",
    "simulate",
    "trajectory_error",
]

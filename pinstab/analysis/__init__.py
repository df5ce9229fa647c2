"""Accuracy of a run: the trajectory error against a reference (a scene's exact motion, or a saved run).

Each exact reference is a module here that registers itself in :data:`EXACT_REFERENCES` under its
scene's name (``fourbar``: the crank-angle equation; ``nfourbar``: the parallelogram pendulum; ``stiff-fourbar``:
SciPy's Radau on the open chain's ODE). Stability maps of runs over a (step, gain) grid, observed beside the
criterion's prediction: :mod:`.stability_map`; over a (step, element scale) grid, one panel per integrator, beside
the prediction from the linearized motion's eigenvalues: :mod:`.element_map` (neither imported here).
"""

from ..registry import load_extensions
from .error import ERROR_OF_JOINTS, check_coordinates, trajectory_error
from .references import (
    EXACT_REFERENCES,
    Reference,
    check_reference,
    exact_name,
    exact_reference,
    reference_for,
    saved_reference,
)

load_extensions(__name__, __path__)

__all__ = [
    "ERROR_OF_JOINTS",
    "EXACT_REFERENCES",
    "Reference",
    "check_coordinates",
    "check_reference",
    "exact_name",
    "exact_reference",
    "reference_for",
    "saved_reference",
    "trajectory_error",
]

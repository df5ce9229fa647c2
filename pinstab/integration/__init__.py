"""Time integration: explicit schemes on the configuration group (:mod:`.schemes`, their tableaus in
:mod:`.tableaus`) and the stepping loop that runs them over a time grid (:mod:`.stepping`)."""

from .schemes import INTEGRATORS, ExplicitRungeKutta, Integrator
from .stepping import CHECK_STEPS, Records, StepLoop, TimeGrid

__all__ = ["CHECK_STEPS", "INTEGRATORS", "ExplicitRungeKutta", "Integrator", "Records", "StepLoop", "TimeGrid"]

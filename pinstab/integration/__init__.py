"""Time integration: explicit schemes on the configuration group (:mod:`.schemes`, their tableaus in
:mod:`.tableaus`), diagonally implicit ones (:mod:`.implicit`), the stepping loop that runs them over a time grid
(:mod:`.stepping`), the samples it keeps (:mod:`.records`: in memory, or streamed to a file), error control with
embedded pairs (:mod:`.adaptive`), dense output (:mod:`.dense`) and the planning of steps around singular
configurations (:mod:`.passages`)."""

from .adaptive import AdaptiveLoop, ErrorControl
from .implicit import ImplicitRungeKutta
from .passages import Passage
from .records import Records, StreamedRecords
from .schemes import INTEGRATORS, ExplicitRungeKutta, Integrator, embedded_pairs
from .stepping import CHECK_STEPS, StepLoop, TimeGrid

__all__ = [
    "CHECK_STEPS",
    "INTEGRATORS",
    "AdaptiveLoop",
    "ErrorControl",
    "ExplicitRungeKutta",
    "ImplicitRungeKutta",
    "Integrator",
    "Passage",
    "Records",
    "StreamedRecords",
    "StepLoop",
    "TimeGrid",
    "embedded_pairs",
]

"""``projection`` (coordinate + velocity projection after every step) and ``post``
(Ascher, Chin, Petzold & Reich 1995: one correction per step with the projector evaluated once).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..projection import correct, loop_correction
from ..registry import NoOptions
from .base import STABILIZERS, Correction, Stabilizer

if TYPE_CHECKING:
    from ..kernels import CoreCorrection
    from ..model import ConstrainedModel
    from ..projection import Projector


@dataclass(frozen=True)
class ProjectionOptions:
    """Coordinate projection settings."""

    tolerance: float = field(
        default=1e-13,
        metadata={
            "flag": "--projection-tolerance",
            "help": "position residual and Gauss-Newton step projection reaches [m or rad per m of mechanism size, "
            "at least 1 m]",
        },
    )
    max_iterations: int = field(
        default=20, metadata={"flag": "--projection-iterations", "help": "Gauss-Newton iterations per step"}
    )

    def __post_init__(self) -> None:
        if not (isinstance(self.tolerance, float | int) and self.tolerance > 0):
            raise ValueError(f"tolerance must be > 0, got {self.tolerance!r}")
        if not (isinstance(self.max_iterations, int) and self.max_iterations >= 1):
            raise ValueError(f"max_iterations must be an integer >= 1, got {self.max_iterations!r}")


class ProjectingStabilizer(Stabilizer):
    """A method whose correction after every step is one of the compiled corrections
    (:func:`pinstab.projection.correct`): ``projection``'s (post False) or ``post``'s, with Gauss-Newton's tolerance
    [m or rad, relative] and iterations."""

    corrects = True
    post = False
    tolerance = 0.0
    max_iterations = 1

    def baumgarte_gains(self) -> tuple[float, float]:
        return (0.0, 0.0)

    def correct(
        self, model: ConstrainedModel, projector: Projector, q: np.ndarray, v: np.ndarray, t: float
    ) -> Correction:
        return Correction(*correct(model, projector, q, v, t, self.post, self.tolerance, self.max_iterations))

    def loop_correction(self, model: ConstrainedModel, projector: Projector) -> CoreCorrection:
        """:meth:`correct` as the compiled step loop makes it after each step, on the projector's compiled
        projections (the core path's: :func:`pinstab.projection.loop_correction`)."""
        return loop_correction(model, projector, self.post, self.tolerance, self.max_iterations)


@STABILIZERS.register("projection", options=ProjectionOptions, summary="project q and v onto the manifold every step")
class ProjectionStabilizer(ProjectingStabilizer):
    """Project q onto phi = 0 by Gauss-Newton, then v onto G v + g_t = 0, after every step.

    Args:
        options: tolerance [m or rad] and iterations before :class:`~pinstab.errors.ProjectionError`.
    """

    name = "projection"

    def __init__(self, options: ProjectionOptions | None = None) -> None:
        options = options or ProjectionOptions()
        self.tolerance, self.max_iterations = options.tolerance, options.max_iterations

    def parameters(self) -> dict[str, float | str]:
        return {"tolerance": self.tolerance, "max_iterations": self.max_iterations}


@STABILIZERS.register("post", options=NoOptions, summary="one projection step per step (Ascher et al. 1995)")
class PostStabilizer(ProjectingStabilizer):
    """One post-stabilization step: ``q <- q (+) (-F phi)``, ``v <- v - F g`` with
    ``F = M^-1 G^T (G M^-1 G^T)^+`` evaluated once, at the uncorrected state."""

    name = "post"
    post = True

    def __init__(self, options: NoOptions | None = None) -> None:
        pass

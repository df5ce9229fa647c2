"""``projection`` (coordinate + velocity projection after every step) and ``post``
(Ascher, Chin, Petzold & Reich 1995: one correction per step with the projector evaluated once).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..projection import project_positions
from ..registry import NoOptions
from .base import STABILIZERS, Correction, Stabilizer

if TYPE_CHECKING:
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


@STABILIZERS.register("projection", options=ProjectionOptions, summary="project q and v onto the manifold every step")
class ProjectionStabilizer(Stabilizer):
    """Project q onto phi = 0 by Gauss-Newton, then v onto G v + g_t = 0, after every step.

    Args:
        options: tolerance [m or rad] and iterations before :class:`~pinstab.errors.ProjectionError`.
    """

    name = "projection"
    corrects = True

    def __init__(self, options: ProjectionOptions | None = None) -> None:
        options = options or ProjectionOptions()
        self.tolerance, self.max_iterations = options.tolerance, options.max_iterations

    def baumgarte_gains(self) -> tuple[float, float]:
        return (0.0, 0.0)

    def correct(
        self, model: ConstrainedModel, projector: Projector, q: np.ndarray, v: np.ndarray, t: float
    ) -> Correction:
        q, iterations = project_positions(model, projector, q, t, self.tolerance, self.max_iterations)
        return Correction(q, projector.velocity_projection(q, v, t), iterations)

    def parameters(self) -> dict[str, float | str]:
        return {"tolerance": self.tolerance, "max_iterations": self.max_iterations}


@STABILIZERS.register("post", options=NoOptions, summary="one projection step per step (Ascher et al. 1995)")
class PostStabilizer(Stabilizer):
    """One post-stabilization step: ``q <- q (+) (-F phi)``, ``v <- v - F g`` with
    ``F = M^-1 G^T (G M^-1 G^T)^+`` evaluated once, at the uncorrected state."""

    name = "post"
    corrects = True

    def __init__(self, options: NoOptions | None = None) -> None:
        pass

    def baumgarte_gains(self) -> tuple[float, float]:
        return (0.0, 0.0)

    def correct(
        self, model: ConstrainedModel, projector: Projector, q: np.ndarray, v: np.ndarray, t: float
    ) -> Correction:
        step, _ = projector.position_step(q, t)
        return Correction(model.integrate(q, step), projector.velocity_projection(q, v, t), 1)

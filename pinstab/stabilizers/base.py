"""What a stabilizer provides (docs/mathematics.md section 3): a term gamma_stab and/or a post-step correction,
and, where it has one, the discrete stability indicator rho(R(tau W)) of its deviation dynamics; and
the registry of stabilization methods."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .. import kernels
from ..constraints import ConstraintValues
from ..errors import PinstabError
from ..paths.core import CoreTerm
from ..registry import Registry
from ..stability.criterion import deviation_radius

if TYPE_CHECKING:
    from ..model import ConstrainedModel
    from ..projection import Projector


@dataclass
class Correction:
    """A post-step correction: the corrected state and the iterations it took."""

    q: np.ndarray
    v: np.ndarray
    iterations: int = 0


class DeviationGains(NamedTuple):
    """The linearized deviation dynamics ``dv~/dt = -S q~ - K v~``.

    Attributes:
        stiffness: S, s x m [1/s^2] (columns: holonomic rows). damping: K, s x s [1/s].
        holonomic_mask: which of the s rows are holonomic.
    """

    stiffness: np.ndarray
    damping: np.ndarray
    holonomic_mask: np.ndarray


class Stabilizer:
    """Base stabilizer: no term, no correction, no stability indicator.

    Attributes:
        name: method name.
        required_solver: a KKT backend the method implies (``pinocchio``), else None.
        constant_gains: S and K do not depend on the state, so rho is computed once per run.
        corrects: the method corrects the state after every step (:meth:`correct`).
        guards_passages: before a step that straddles a singular configuration the state is projected
            onto its branch (methods that do not correct every step; :mod:`pinstab.integration.passages`).
    """

    name = "none"
    required_solver: str | None = None
    constant_gains = True
    corrects = False
    guards_passages = True

    def bind(self, model: ConstrainedModel, step: float, integrator: str, q: np.ndarray, varying: bool = False) -> None:
        """Called once before a run with the step [s] (the first, where ``varying``: error control takes steps of
        varying length), the integrator name and the start configuration."""
        self.step, self.integrator = step, integrator
        self.scheme = integrator  # the amplification matrix R that describes the method's deviations
        self.mask = model.constraints.holonomic_mask
        self._cached_radius: float | None = None

    def deviation_gains(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray) -> DeviationGains | None:
        """S, K and the holonomic mask of the linearized deviations at (q, v), or None.

        s and the mask may be those of the deviations that can occur (redundant rows removed) rather
        than of every row.
        """
        return None

    def stabilization_term(
        self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float, values: ConstraintValues, stage: int
    ) -> np.ndarray | None:
        """gamma_stab (s,) added to the acceleration-level right-hand side, or None for zero.

        ``model.kin`` holds the full kinematics at (q, v) when this is called; ``stage`` is the
        integrator's stage index within the step (0 first).
        """
        return None

    def baumgarte_gains(self) -> tuple[float, float] | None:
        """(Kp, Kd) when the term is Baumgarte's (so Pinocchio's corrector can apply it, (0, 0) for no
        term), else None. The base class says None: a new method must claim the form to get it."""
        return None

    def core_term(self) -> CoreTerm | None:
        """The term in the core kernel's form once bound, or None when it has no such form. The base class
        gives Baumgarte's when :meth:`baumgarte_gains` names it (Kd / 2 on nonholonomic rows), not held."""
        gains = self.baumgarte_gains()
        if gains is None:
            return None
        kp, kd = gains
        return CoreTerm(float(kp), kernels.baumgarte_velocity_gains(float(kd), self.mask), False)

    def hold_term(self, term: np.ndarray) -> None:
        """Take ``term`` (s,) [m/s^2 or rad/s^2] as the one held over this step, computed at its first stage by
        the core kernel (:meth:`core_term` held); a method whose term is not held has none to take."""
        raise PinstabError(f"method {self.name}: its term is not held over a step")

    def correct(
        self, model: ConstrainedModel, projector: Projector, q: np.ndarray, v: np.ndarray, t: float
    ) -> Correction:
        """Correct the state after a step with the path's projections (:mod:`pinstab.projection`); the
        default leaves it as it is."""
        return Correction(q, v)

    def spectral_radius(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> float | None:
        """rho(R(tau W)) of the deviation dynamics at (q, v, t) [dimensionless], or None for a method
        without a stabilization term; needs :meth:`bind` first."""
        if self.constant_gains and self._cached_radius is not None:
            return self._cached_radius
        gains = self.deviation_gains(model, q, v)
        if gains is None:
            return None
        radius = deviation_radius(*gains, self.step, self.scheme)
        if self.constant_gains:
            self._cached_radius = radius
        return radius

    def parameters(self) -> dict[str, float | str]:
        """The method's parameters, for reports."""
        return {}

    def error_control_obstacle(self) -> str | None:
        """Why the method, as configured, does not suit error control (steps of varying length), or None."""
        return None


STABILIZERS: Registry[Stabilizer] = Registry("method")
"""Stabilization methods. A factory is ``factory(options) -> Stabilizer``. Options fields named
``kp`` and ``kd`` mark a method whose gains a stability map can sweep."""

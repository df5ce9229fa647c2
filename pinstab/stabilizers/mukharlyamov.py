"""``mukharlyamov``: the extended system with designed perturbation equations (docs/mathematics.md 3.2, [M]).

The deviations ``q~ = phi`` (holonomic rows) and ``v~ = g`` (all rows) are driven by the Lagrange
equations of ``L~ = 1/2 v~^T A v~ - 1/2 q~^T H q~`` with dissipation ``D~ = 1/2 v~^T B v~``:
``dv~/dt = -S q~ - K v~`` with ``S = A^-1 H``, ``K = A^-1 (B + dA/dt)``, imposed through
``gamma_stab = -S q~ - K v~``. Nonholonomic rows have no potential term (first order).

Variants:

* ``kinematic``: A = E. H and B are rates (1/s^2, 1/s); H = beta^2 E, B = 2 alpha E is Baumgarte.
* ``inertial``: A = Lambda(q) = (G M^-1 G^T)^-1, the constraint-space inertia. H and B are a
  physical stiffness and damping (N/m, N s/m) acting on the violated constraint; dA/dt is taken
  as a forward difference of G M^-1 G^T along the motion (step 1e-7 s).

Gains are either given (H = stiffness E, B = damping E) or automatic: placed from the step and the
integrator so that every eigenvalue of the amplification matrix R(tau W) has modulus ``decay`` per
step (:func:`pinstab.stability.criterion.place_gains`); in the inertial variant the automatic H and B are
those gains times Lambda at the start of the run. With heun and rk4 the term is evaluated at the
first stage and held over the step (scheme ``held``): evaluated at every stage, gains of order
1/tau^2 turn the stages' O(tau^2) excursions off the manifold into O(1) accelerations and RK4 loses
its accuracy (benchmarks/decay_factor.py: drift 8e-6 instead of 3e-11 at dt = 1e-3, r = 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .. import kernels
from ..constraints import ConstraintValues
from ..errors import PinstabError, choices
from ..kinematics import Kinematics
from ..stability.criterion import is_multistage, place_gains
from .base import STABILIZERS, CoreTerm, DeviationGains, Stabilizer

if TYPE_CHECKING:
    from ..model import ConstrainedModel

VARIANTS = ("kinematic", "inertial")
# per-step decay factor r of the automatic gains, measured by benchmarks/decay_factor.py: dead-beat
# (r = 0) repairs a violation fastest and leaves the lowest drift in every kinematic row; the
# inertial variant's rate follows Lambda(q), which changes ~2x over the four-bar's motion, and
# dead-beat gains then leave no margin (it diverges), while r = 0.3 stays stable with a small drift.
DEFAULT_DECAY = {"kinematic": 0.0, "inertial": 0.3}
RATE_STEP = 1e-7  # [s] forward-difference step for dA/dt in the inertial variant
RCOND = 1e-10


@dataclass(frozen=True)
class MukharlyamovOptions:
    """Extended-system stabilization settings.

    Attributes:
        variant: ``kinematic`` (A = E) or ``inertial`` (A = Lambda(q)).
        kp: the stiffness H = kp E [1/s^2 kinematic, N/m inertial]; None for automatic gains.
        kd: the damping B = kd E [1/s kinematic, N s/m inertial]; None for automatic gains.
        decay: per-step decay factor r in [0, 1) of the automatic gains (None: the variant's
            :data:`DEFAULT_DECAY`).
        hold: with a multi-stage integrator (heun, rk4, ...), evaluate the term at the first stage and
            hold it over the step (the ``held`` amplification matrix) instead of at every stage. None (the default):
            held on fixed steps, evaluated at every stage under error control, whose error estimate would not see a
            held term (on the four-bar at rtol 1e-6 a held term ends 14 rad off the reference, one evaluated at every
            stage 1.2e-8: tests/test_mukharlyamov.py); True under error control is refused.
    """

    variant: str = field(
        default="kinematic",
        metadata={"help": "kinematic (A = E) or inertial (A = Lambda)", "choices": VARIANTS},
    )
    kp: float | None = field(default=None, metadata={"help": "stiffness H (default: automatic gains)"})
    kd: float | None = field(default=None, metadata={"help": "damping B (default: automatic gains)"})
    decay: float | None = field(default=None, metadata={"help": "automatic gains: decay factor r per step"})
    hold: bool | None = field(
        default=None,
        metadata={
            "flag": "--no-hold",
            "help": "with a multi-stage integrator, evaluate the term at every stage instead of holding it over a "
            "fixed step (under --rtol it is always evaluated at every stage)",
        },
    )

    def __post_init__(self) -> None:
        if self.variant not in VARIANTS:
            raise ValueError(f"unknown variant {self.variant!r}; valid variants: {choices(VARIANTS)}")
        if (self.kp is None) != (self.kd is None):
            raise ValueError("give both stiffness (--kp) and damping (--kd), or neither for automatic gains")
        for label in ("kp", "kd"):
            value = getattr(self, label)
            if value is not None and (
                isinstance(value, bool) or not isinstance(value, float | int) or not math.isfinite(value) or value < 0
            ):
                raise ValueError(
                    f"{'stiffness' if label == 'kp' else 'damping'} must be a finite number >= 0, got {value!r}"
                )
        if self.decay is not None:
            if self.kp is not None:
                raise ValueError("the decay factor sets automatic gains; it cannot be combined with --kp/--kd")
            if not (isinstance(self.decay, float | int) and 0.0 <= self.decay < 1.0):
                raise ValueError(f"decay factor r must be in [0, 1), got {self.decay!r}")
        if self.hold is not None and not isinstance(self.hold, bool):
            raise ValueError(f"hold must be true, false or unset, got {self.hold!r}")


@STABILIZERS.register(
    "mukharlyamov", options=MukharlyamovOptions, summary="extended system: deviation dynamics with placed gains"
)
class MukharlyamovStabilizer(Stabilizer):
    """Extended-system stabilization.

    Args:
        options: :class:`MukharlyamovOptions`.
    """

    name = "mukharlyamov"

    def __init__(self, options: MukharlyamovOptions | None = None) -> None:
        options = options or MukharlyamovOptions()
        variant = options.variant
        self.variant = variant
        self.decay = float(DEFAULT_DECAY[variant] if options.decay is None else options.decay)
        self.stiffness, self.damping = options.kp, options.kd
        self.automatic = options.kp is None
        self.hold = options.hold
        self._bound = False

    def error_control_obstacle(self) -> str | None:
        if self.automatic:
            return (
                "places its automatic gains for one fixed step; with rtol (error control, steps of varying length) "
                "give its gains (kp, kd), or use baumgarte, projection or post"
            )
        if self.hold:
            return (
                "holds its term over a step's stages (hold=True), which the error estimate of steps of varying "
                "length does not see; with rtol leave hold unset (the term is then evaluated at every stage)"
            )
        return None

    # -- set-up --------------------------------------------------------------------------------
    def bind(self, model: ConstrainedModel, step: float, integrator: str, q: np.ndarray, varying: bool = False) -> None:
        super().bind(model, step, integrator, q, varying)
        mask = self.mask
        self.constant_gains = self.variant == "kinematic"
        self.holding = (not varying if self.hold is None else self.hold) and is_multistage(integrator)
        if self.holding:
            self.scheme = "held"
        if self.automatic:
            placed = place_gains(step, self.scheme, self.decay)
            rate_stiffness = placed.stiffness
            rate_damping = np.where(mask, placed.damping, placed.first_order_damping)
            self.placed = placed
        else:
            rate_stiffness = float(self.stiffness)
            rate_damping = np.full(len(mask), float(self.damping))
        self._pick = np.eye(len(mask))[:, mask]  # s x m: holonomic columns
        if self.variant == "kinematic":
            self._s_scalar, self._k_diagonal = rate_stiffness, rate_damping
        else:
            self._rate_kin = Kinematics(model.model)
            self._h_matrix, self._b_matrix = self._physical_gains(model, q, rate_stiffness, rate_damping)
        self._bound = True

    def _physical_gains(
        self, model: ConstrainedModel, q0: np.ndarray, stiffness: float, damping: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """H (s x m, zero-padded) and B (s x s) of the inertial variant; automatic ones scale Lambda(q0)."""
        if not self.automatic:
            return stiffness * self._pick, np.diag(damping)
        jac = model.constraint_values(q0, np.zeros(model.nv), 0.0).jacobian
        inertia = kernels.delassus_pseudo_inverse(_delassus(jac, model.mass_matrix(q0)), RCOND)
        weighted = inertia @ np.diag(damping)
        return stiffness * inertia @ self._pick, 0.5 * (weighted + weighted.T)

    # -- the term ----------------------------------------------------------------------------------
    def stabilization_term(self, model, q, v, t, values: ConstraintValues, stage: int) -> np.ndarray:
        if not self._bound:
            raise PinstabError("mukharlyamov: bind() the stabilizer to a step and an integrator before use")
        if self.holding and stage > 0:
            return self._held_term
        if self.variant == "kinematic":  # the core kernel's
            term = kernels.stabilization_term(self._s_scalar, self._k_diagonal, values.phi, values.velocity_residual)
        else:
            stiffness, damping = self._inertial_matrices(model, q, v, t, values.jacobian, model.kin.mass_matrix)
            term = -stiffness @ values.phi[self.mask] - damping @ values.velocity_residual
        self._held_term = term
        return term

    def _inertial_matrices(self, model, q, v, t, jac, mass_matrix) -> tuple[np.ndarray, np.ndarray]:
        """S = D H and K = D B - dD/dt Lambda (D = G M^-1 G^T = Lambda^-1, so D dLambda/dt = -dD/dt Lambda): the core
        kernel's (``cpp/inertial_term.hpp``), from G and M at q and at q + RATE_STEP v (at t [s])."""
        q_ahead = model.integrate(q, RATE_STEP * v)
        self._rate_kin.update_jacobians(q_ahead)
        jac_ahead = model.constraints.velocity_terms(self._rate_kin, q_ahead, t).jacobian
        gains = self._inertial_gains(self._h_matrix)
        return kernels.inertial_matrices(gains, mass_matrix, jac, model.mass_matrix(q_ahead), jac_ahead)

    def _inertial_gains(self, stiffness: np.ndarray) -> dict:
        """H (``stiffness``), B, the difference step [s] and the cutoff, as the compiled functions take them."""
        return {"stiffness": stiffness, "damping": self._b_matrix, "rate_step": RATE_STEP, "cutoff": RCOND}

    def core_term(self) -> CoreTerm | None:
        """(S, K per row, held) once bound, in the kinematic variant; in the inertial one (S and K follow Lambda(q))
        its H, padded to every row (zero columns on nonholonomic rows, whose phi is zero), and B."""
        if not self._bound:
            return None
        if self.variant == "kinematic":
            return CoreTerm(float(self._s_scalar), self._k_diagonal, self.holding)
        rows = len(self.mask)
        inertial = self._inertial_gains(self._h_matrix @ self._pick.T)
        return CoreTerm(0.0, np.zeros(rows), self.holding, inertial)

    def hold_term(self, term: np.ndarray) -> None:
        if not self.holding:
            super().hold_term(term)
        self._held_term = term

    def baumgarte_gains(self) -> tuple[float, float] | None:
        """(S, K) once bound, when the term is Baumgarte's: the kinematic variant on holonomic rows with
        the term evaluated at every stage (not held)."""
        if not self._bound or self.variant != "kinematic" or self.holding or not self.mask.all():
            return None
        damping = float(self._k_diagonal[0]) if len(self._k_diagonal) else 0.0
        return (float(self._s_scalar), damping)

    # -- the criterion -------------------------------------------------------------------------------
    def deviation_gains(self, model, q, v) -> DeviationGains:
        if self.variant == "kinematic":
            return DeviationGains(self._s_scalar * self._pick, np.diag(self._k_diagonal), self.mask)
        model.kin.update(q, v)
        jac = model.constraints.velocity_terms(model.kin, q, 0.0).jacobian
        stiffness, damping = self._inertial_matrices(model, q, v, 0.0, jac, model.kin.mass_matrix)
        return _on_row_space(jac, stiffness, damping, self.mask)

    def parameters(self) -> dict[str, float | str]:
        report: dict[str, float | str] = {"variant": self.variant, "gains": "auto" if self.automatic else "given"}
        if self._bound:
            report["scheme"] = self.scheme
        if self.automatic:
            report["decay"] = self.decay
            if self._bound:
                report.update(stiffness=self.placed.stiffness, damping=self.placed.damping)
        else:
            report.update(stiffness=float(self.stiffness), damping=float(self.damping))
        return report


def _delassus(jac: np.ndarray, mass_matrix: np.ndarray) -> np.ndarray:
    """G M^-1 G^T, the inverse of the constraint-space inertia Lambda [1/kg, 1/(kg m^2)]."""
    return jac @ np.linalg.solve(mass_matrix, jac.T)


def _on_row_space(jac: np.ndarray, stiffness: np.ndarray, damping: np.ndarray, mask: np.ndarray) -> DeviationGains:
    """Restrict S, K to the deviations that can occur: g = G v lies in range(G), and so (to first
    order) does phi. With redundant rows Lambda = pinv(G M^-1 G^T) leaves the redundant direction
    without stiffness or damping, a marginal eigenvalue of R that says nothing about stability.
    Only applied when every row is holonomic (then S is square)."""
    if not mask.all():
        return DeviationGains(stiffness, damping, mask)
    left, singular, _ = np.linalg.svd(jac, full_matrices=False)
    rank = int(np.sum(singular > 1e-9 * max(singular[0], 1e-300))) if singular.size else 0
    if rank == len(mask):
        return DeviationGains(stiffness, damping, mask)
    basis = left[:, :rank]
    return DeviationGains(basis.T @ stiffness @ basis, basis.T @ damping @ basis, np.ones(rank, dtype=bool))

"""Exceptions raised by pinstab.

Every error a user can provoke with bad input is a :class:`PinstabError` subclass whose
message names the offending item and, where it helps, the valid alternatives.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Hashable, Iterable


class PinstabError(Exception):
    """Base class of every error pinstab raises on purpose."""


class SceneError(PinstabError):
    """A scene file or scene argument is invalid (unknown key, frame, joint, type or unit)."""


class WaypointError(SceneError):
    """A target trajectory's waypoints are unusable: times not strictly increasing, or as many values as times
    missing."""


class AssemblyError(PinstabError):
    """The loop closures cannot be satisfied from the given initial configuration.

    Attributes:
        residual: the largest closure residual reached [m or rad].
    """

    def __init__(self, message: str, residual: float) -> None:
        super().__init__(message)
        self.residual = residual


class SolverError(PinstabError):
    """A KKT solve failed or is not applicable to the scene (e.g. rank loss with ``dense``)."""


class ContactInfeasibleError(SolverError):
    """Sticking contacts that cannot hold: the force they need is outside a friction cone, or pulls.

    Attributes:
        contacts: the contacts named, worst first. time: when [s].
    """

    def __init__(self, message: str, contacts: list[str], time: float) -> None:
        super().__init__(message)
        self.contacts = contacts
        self.time = time


class GraspLostError(ContactInfeasibleError):
    """A sticking fingertip contact would have to pull on the object or slide over it.

    Attributes:
        contacts: the contacts named, worst first. time: when [s]. margin: the worst violated margin (negative)
            [N or N m]. margins: each contact's violated margin.
    """

    def __init__(self, message: str, contact: str, time: float, margin: float) -> None:
        super().__init__(message, [contact], time)
        self.margin = margin
        self.margins = {contact: margin}

    @classmethod
    def joined(cls, errors: list[GraspLostError]) -> GraspLostError:
        """One error naming every contact of ``errors`` (at one time), worst (most negative margin) first;
        ``margins`` maps each contact to its violated margin [N or N m]."""
        ordered = sorted(errors, key=lambda error: error.margin)
        prefix = f"grasp lost at t = {ordered[0].time:.6g} s: "
        reasons = "; ".join(str(error).removeprefix(prefix) for error in ordered)
        joined = cls(
            f"{prefix}{len(ordered)} contacts leave their cones: {reasons}",
            ordered[0].contacts[0],
            ordered[0].time,
            ordered[0].margin,
        )
        joined.contacts = [error.contacts[0] for error in ordered]
        joined.margins = {error.contacts[0]: error.margin for error in ordered}
        return joined


class PainleveError(ContactInfeasibleError):
    """At an event no assignment of contact modes is consistent, or two consistent ones move differently
    (Painleve's paradox of rigid contact with Coulomb friction).

    Attributes:
        contacts: the touching contacts. time: when [s].
    """


class ContactSolveError(ContactInfeasibleError):
    """The frictional contact problem of a step was not solved: no solver tried (ADMM, then PGS) met the contact
    law to its tolerance (the problem may have a solution; the run keeps its samples up to the step).

    Attributes:
        contacts: the contacts of the problem. time: the step's start [s].
    """


class ServoInfeasibleError(PinstabError):
    """A prescribed constraint (servoconstraint) that the controls cannot realize at a state.

    Attributes:
        constraints: the prescribed constraints named (those the unreachable direction involves).
        time: when [s]. q, v: the state. direction: the unreachable direction over the prescribed rows
            (unit vector; None when the controls could reach it but their limits forbid it).
    """

    def __init__(self, message: str, constraints: list[str], time: float, q, v, direction=None) -> None:
        super().__init__(message)
        self.constraints = constraints
        self.time = time
        self.q = q
        self.v = v
        self.direction = direction


class MemoryBudgetError(PinstabError):
    """What a command would allocate exceeds the memory budget, or it ran out of memory (a ``MemoryError``)
    (see :mod:`pinstab.memory`).

    Attributes:
        estimate: the estimated need [bytes] (None after a MemoryError). limit: the budget, or the memory the
            tightest limit left [bytes]. source: that limit (``MemAvailable``, a cgroup's, ``RLIMIT_AS``, or
            ``--memory-limit``). needed_by: what needed the memory. trajectory: a run's samples up to the
            failure (None when no run had started).
    """

    def __init__(
        self,
        message: str,
        estimate: int | None,
        limit: int,
        source: str = "",
        needed_by: str = "",
        trajectory=None,
    ) -> None:
        super().__init__(message)
        self.estimate = estimate
        self.limit = limit
        self.source = source
        self.needed_by = needed_by
        self.trajectory = trajectory


class ProjectionError(PinstabError):
    """Coordinate projection onto the constraint manifold did not converge."""


class DivergenceError(PinstabError):
    """A simulation left the finite or drift-bounded region.

    Attributes:
        time: time of the last finite state [s].
        q: last finite configuration.
        v: last finite velocity.
        trajectory: the partial trajectory up to and including that state (from :func:`~pinstab.simulate`:
            and then the failed step's sample, its state NaN when not reached).
        finite_trajectory: the partial trajectory ending at the last finite state (from
            :func:`~pinstab.simulate`; None otherwise).
        diverged_at: time of the step that failed [s] (None when not located at a step).
    """

    def __init__(self, message: str, time: float, q, v, trajectory=None, diverged_at: float | None = None) -> None:
        super().__init__(message)
        self.time = time
        self.q = q
        self.v = v
        self.trajectory = trajectory
        self.finite_trajectory = None
        self.diverged_at = diverged_at


class NewtonError(DivergenceError):
    """An implicit integrator's Newton iteration did not solve a stage of a fixed step, even globalized (a continuation
    in the stage's share, a Jacobian at every iterate: :mod:`pinstab.integration.implicit`). The message names the
    scheme, the stage, the step's start time and length, the last scaled increment and what to do (a smaller step, or
    error control); the run keeps its trajectory up to the step's start."""


class StepTooLargeError(DivergenceError):
    """A run failed (a blow-up, a solve, a contact that could not hold) only because its step is too large
    for the motion: with a smaller one it goes on. The message names dt and a step that works."""


class StiffStepError(StepTooLargeError):
    """An explicit run diverged with a step above its scheme's stability limit of the stiffest mode of the
    motion, a mode a force element owns (issue 37). The message names the element, its frequency and the
    largest stable step.

    Attributes:
        element: the force element's name. frequency: its frequency on the mode [rad/s].
        eigenvalue: the mode's eigenvalue lambda [1/s]. limit: the largest stable step [s].
    """

    element: str = ""
    frequency: float = float("nan")
    eigenvalue: complex = complex("nan")
    limit: float = float("nan")


def choices(valid: Iterable[str]) -> str:
    """Format a list of valid alternatives for an error message."""
    names = sorted(str(name) for name in valid)
    return ", ".join(names) if names else "(none)"


def repeated(items: Iterable[Hashable]) -> list:
    """The items that occur more than once, each once, sorted by their text (for an error message)."""
    return sorted((item for item, count in Counter(items).items() if count > 1), key=str)


class ConstraintError(PinstabError):
    """A constraint is ill-defined (bad frame, wrong shape from a user callable, non-finite value)."""


class UnstableGainsError(PinstabError):
    """Stabilization gains whose discrete deviation dynamics are unstable at the chosen step (strict mode)."""


class PinstabWarning(UserWarning):
    """Base class of the warnings pinstab gives about a scene or a run."""


class ZeroDynamicsWarning(PinstabWarning):
    """The coordinates a servo leaves free (its internal or zero dynamics) ran away during a run."""


class PenetrationWarning(PinstabWarning):
    """A link of the robot and a scene object interpenetrate beyond the tolerance (at the start or during a run)."""


class EdgeContactWarning(PinstabWarning):
    """A fingertip contact sits on an edge or a vertex of its object's geometry, where the normal is not unique."""


class UnstableGainsWarning(PinstabWarning):
    """Stabilization gains predicted unstable (rho(R(tau W)) >= 1) at the chosen step and integrator."""


class JointLimitsWarning(PinstabWarning):
    """A run left a joint limit that it could not hold (its scene's constraints are not all closures and
    event-driven contacts): the run ignores the limits."""


class BranchChangeWarning(PinstabWarning):
    """The motion left its branch of the constraint manifold at a singular configuration (its tangent space
    turned by a finite angle at once)."""


class SolverLimitWarning(PinstabWarning):
    """An iterative KKT backend (ProxQP) stopped at its iteration limit on some solves of a run: each was accepted by
    its residual, but the limit, not the tolerance, ended it."""


class CutShortWarning(PinstabWarning):
    """A run file read back holds a run cut short (interrupted, or killed) before its end: its samples up to the last
    one written, not its derived series."""

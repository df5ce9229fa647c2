"""The interface every constraint family implements (docs/mathematics.md section 1), its row kinds, and the
registry of constraint kinds that scene files name."""

from __future__ import annotations

from abc import ABC, abstractmethod
from enum import StrEnum
from typing import NamedTuple

import numpy as np

from ..contact.collisions import Touch
from ..contact.cones import FrictionCone
from ..kernels import RowBlock, block_drift, block_jacobian, block_residual
from ..kinematics import Kinematics
from ..registry import Registry


class RowKind(StrEnum):
    """How a block's rows enter the dynamics.

    * ``equality``: ``G a = rhs``, multiplier free (closures, user rows).
    * ``unilateral``: ``G a >= rhs`` with multiplier >= 0 and complementarity (a normal contact
      force that can only push, a joint limit); its position residual phi >= 0 is a gap.
    * ``cone``: a sticking point contact: ``G a = rhs`` on its 3 rows (normal first, then two
      tangents), the force (multipliers) inside the Coulomb cone ``|f_t| <= mu f_n``.
    """

    EQUALITY = "equality"
    UNILATERAL = "unilateral"
    CONE = "cone"


class VelocityTerms(NamedTuple):
    """``G`` (rows x nv) and the explicit time term ``g_t`` (rows,) of ``g = G v + g_t``."""

    jacobian: np.ndarray
    time_term: np.ndarray


class Constraint(ABC):
    """A block of constraint rows.

    Holonomic blocks have a residual ``phi(q, t)`` with ``G = d phi / dq`` (right-trivialized on
    the configuration group, i.e. through ``pin.integrate``). Pfaffian blocks only have the velocity
    level ``A(q, t) v + b(q, t) = 0``. Both give the drift term ``gamma0`` of
    ``G a + gamma0 = 0`` (docs/mathematics.md eq. 2).

    Attributes:
        name: unique name, used in messages and to slice multipliers.
        rows: number of rows.
        holonomic: whether ``residual`` is defined.
        force_frame: the frame in which this block's multipliers are expressed (human-readable).
        row_kind: how the rows enter the dynamics (:class:`RowKind`); equality by default.
        friction: the cone of a ``cone`` block (3 rows: normal, tangent, tangent), else None.
        limits_force: the block's equality rows hold only while their multipliers stay within limits
            (a contact that can only push, a friction cone): :meth:`check_force` after every solve.
        force_partners: blocks whose multipliers come before this block's own in what :meth:`margins`
            and :meth:`check_force` receive (a rolling contact's normal force is its touching block's).
        prescribed: a servoconstraint (docs/mathematics.md section 5): the controls realize it, its reaction is zero
            (a scene's ``[[servos]]``).
        nv: the velocity dimension the block was written for (a user block declares it), or None: the model's.
        touch: a fingertip contact's finger and object frames, for the collision checks
            (:mod:`pinstab.contact.collisions`), or None.
        residual_units: (accepted, aimed) [-]: the residual over the first is what the assembly's tolerance accepts,
            over the second what its iteration drives to rounding, both in m or rad (1 and 1 for geometric rows; a
            joint relation's largest and smallest nonzero coefficient in magnitude).
    """

    name: str
    rows: int
    holonomic: bool
    force_frame: str
    row_kind: RowKind = RowKind.EQUALITY
    friction: FrictionCone | None = None
    limits_force: bool = False
    force_partners: tuple[str, ...] = ()
    prescribed: bool = False
    nv: int | None = None
    touch: Touch | None = None
    residual_units: tuple[float, float] = (1.0, 1.0)

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        """Position-level residual phi [m or rad]; needs placements updated at q."""
        raise NotImplementedError(f"constraint {self.name} is not holonomic")

    @abstractmethod
    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        """(G, g_t): rows x nv Jacobian and explicit time term; needs Jacobians updated at q."""

    @abstractmethod
    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """gamma0 = dG/dt v + d g_t/dt; needs a full :meth:`Kinematics.update` at (q, v)."""

    def compiled_rows(self) -> RowBlock | None:
        """The block as the compiled core evaluates it (``cpp/core_rows.hpp``: point, weld, revolute, prismatic and
        joint-relation rows), or None (the default): its rows are computed in Python, and a scene with it runs on
        the general path."""
        return None

    def margins(self, force: np.ndarray) -> dict[str, float]:
        """How far this block's multipliers are inside their limits, by name [N or N m] (>= 0: held);
        empty for a block without limits."""
        return {}

    def slip(self, kin: Kinematics) -> float | None:
        """For a sticking contact: the distance between the material points it holds together [m] (its
        creep); None for other blocks. Placements must be current."""
        return None

    def check_force(self, force: np.ndarray, t: float) -> None:
        """Raise a :class:`~pinstab.errors.PinstabError` naming the block and the time ``t`` [s] when its
        multipliers ``force`` are outside their limits (blocks with ``limits_force``)."""
        return None


CONSTRAINT_KINDS: Registry[Constraint] = Registry("constraint kind")
"""Scene-file constraint kinds: ``kind = NAME`` in ``[[closures]]`` / ``[[contacts]]``. A factory is
``parse(table, tables, name, where) -> Constraint``: it reads its own keys from the scene table
through :class:`~pinstab.tables.SceneTables` (which adds frames to the model) and names ``where``
in its errors; it returns one Constraint, or a list of blocks (rows of different kinds)."""


class BlockRows(Constraint):
    """A constraint whose rows are one row block of the compiled core (``cpp/core_rows.cpp``): its residual, Jacobian
    with time term and drift are the core's functions on :meth:`block_at`."""

    def block_at(self, t: float) -> RowBlock:
        """The block whose rows hold at time t [s]: :meth:`compiled_rows` (a block that takes its target's values
        from Python at t sets them here)."""
        block = self.compiled_rows()
        if block is None:  # pragma: no cover - a subclass without compiled rows overrides this
            raise NotImplementedError(f"{type(self).__name__} has no compiled rows: override block_at")
        return block

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return block_residual(kin.model, kin.data, self.block_at(t), q, t)

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        return VelocityTerms(*block_jacobian(kin.model, kin.data, self.block_at(t), t))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return block_drift(kin.model, kin.data, self.block_at(t), t)

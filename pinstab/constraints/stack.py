"""All constraint blocks of a scene stacked into one set of rows (docs/mathematics.md eq. 1-2)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..contact.cones import FrictionCone
from ..errors import ConstraintError, GraspLostError, repeated
from ..kinematics import Kinematics
from .base import Constraint, RowKind, VelocityTerms


@dataclass
class ConstraintValues:
    """Stacked constraint quantities at one state (s rows in all).

    Attributes:
        phi: position residual, zero on nonholonomic rows [m or rad].
        jacobian: G, s x nv.
        time_term: g_t (s,).
        velocity_residual: g = G v + g_t [m/s or rad/s].
        drift: gamma0 (s,).
    """

    phi: np.ndarray
    jacobian: np.ndarray
    time_term: np.ndarray
    velocity_residual: np.ndarray
    drift: np.ndarray | None = None


class Violation(NamedTuple):
    """How far a state is from the constraints: max ``|phi|`` [m or rad] and max ``|g|`` [m/s or rad/s]
    (a unilateral row counts only its penetration and its approach)."""

    position: float
    velocity: float


@dataclass(frozen=True)
class ConeRows:
    """The three rows of a sticking contact with friction: normal row, then the two tangent rows."""

    name: str
    rows: tuple[int, int, int]
    cone: FrictionCone


@dataclass(frozen=True)
class RowLayout:
    """What a KKT backend needs to know about the rows besides G and the right-hand side.

    Attributes:
        names: the constraint block of each row.
        unilateral: mask of ``unilateral`` rows (``G a >= rhs``, multiplier >= 0).
        cones: the ``cone`` row triples (sticking, force inside the friction cone).
    """

    names: tuple[str, ...]
    unilateral: np.ndarray
    cones: tuple[ConeRows, ...]

    @property
    def kinds(self) -> frozenset[RowKind]:
        """The row kinds present (equality included when some row is neither unilateral nor cone)."""
        kinds = set()
        if self.unilateral.any():
            kinds.add(RowKind.UNILATERAL)
        if self.cones:
            kinds.add(RowKind.CONE)
        if len(self.names) > int(self.unilateral.sum()) + 3 * len(self.cones):
            kinds.add(RowKind.EQUALITY)
        return frozenset(kinds)

    @cached_property
    def equality_only(self) -> bool:
        """No unilateral and no cone rows (asked at every solve)."""
        return not self.cones and not self.unilateral.any()


class ConstraintSet:
    """An ordered list of constraint blocks with their row slices."""

    def __init__(self, constraints: list[Constraint], nv: int) -> None:
        duplicates = repeated(c.name for c in constraints)
        if duplicates:
            raise ConstraintError(f"constraint names must be unique; repeated: {', '.join(duplicates)}")
        for c in constraints:
            if c.nv is not None and c.nv != nv:
                raise ConstraintError(f"constraint {c.name!r} is declared for nv = {c.nv}, but the model has nv = {nv}")
        self.constraints = list(constraints)
        self.nv = nv
        self.slices: dict[str, slice] = {}
        start = 0
        for c in self.constraints:
            self.slices[c.name] = slice(start, start + c.rows)
            start += c.rows
        self.rows = start
        self.holonomic_mask = np.zeros(self.rows, dtype=bool)
        self.prescribed_mask = np.zeros(self.rows, dtype=bool)
        unilateral = np.zeros(self.rows, dtype=bool)
        cones = []
        for c in self.constraints:
            rows = self.slices[c.name]
            self.holonomic_mask[rows] = c.holonomic
            self.prescribed_mask[rows] = c.prescribed
            unilateral[rows] = c.row_kind == RowKind.UNILATERAL
            if c.row_kind == RowKind.CONE:
                if c.rows != 3 or c.friction is None:
                    raise ConstraintError(
                        f"constraint {c.name}: cone rows come as 3 (normal, t1, t2) with a friction cone"
                    )
                cones.append(ConeRows(c.name, (rows.start, rows.start + 1, rows.start + 2), c.friction))
        names = tuple(c.name for c in self.constraints for _ in range(c.rows))
        self.layout = RowLayout(names, unilateral, tuple(cones))
        # per row, Constraint.residual_units (accepted, aimed): phi over either is in m or rad
        units = [c.residual_units for c in self.constraints for _ in range(c.rows)]
        self.residual_units = np.array(units).reshape(-1, 2)
        self._has_unilateral = bool(unilateral.any())
        self.force_limited = [(c, self._force_rows(c)) for c in self.constraints if c.limits_force]
        self._every_row = np.ones(self.rows, dtype=bool)

    def _force_rows(self, constraint: Constraint) -> slice | np.ndarray:
        """The multiplier rows a force-limited block checks: its partners' (``force_partners``), then its own."""
        if not constraint.force_partners:
            return self.slices[constraint.name]
        missing = [name for name in constraint.force_partners if name not in self.slices]
        if missing:
            raise ConstraintError(f"constraint {constraint.name}: its force partner {missing[0]!r} is not in the set")
        parts = [self.slices[name] for name in (*constraint.force_partners, constraint.name)]
        return np.concatenate([np.arange(part.start, part.stop) for part in parts])

    def check_forces(self, multipliers: np.ndarray, t: float) -> None:
        """Every block with force limits checks its multipliers at time ``t`` [s]; raises when one is outside
        (a :class:`GraspLostError` names every contact that is, worst first)."""
        found: dict[tuple[str, ...], GraspLostError] = {}  # one per contact (a rolling contact has two blocks)
        for constraint, rows in self.force_limited:
            try:
                constraint.check_force(multipliers[rows], t)
            except GraspLostError as error:
                found.setdefault(tuple(error.contacts), error)
        lost = list(found.values())
        if lost:
            raise lost[0] if len(lost) == 1 else GraspLostError.joined(lost)

    @property
    def holonomic(self) -> list[Constraint]:
        return [c for c in self.constraints if c.holonomic]

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        """phi on every row (zero on nonholonomic rows); placements must be current."""
        phi = np.zeros(self.rows)
        for c in self.constraints:
            if c.holonomic:
                phi[self.slices[c.name]] = c.residual(kin, q, t)
        return phi

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        """(G, g_t); Jacobians must be current."""
        jac = np.zeros((self.rows, self.nv))
        time_term = np.zeros(self.rows)
        for c in self.constraints:
            rows = self.slices[c.name]
            jac[rows], time_term[rows] = c.velocity_terms(kin, q, t)
        return VelocityTerms(jac, time_term)

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """gamma0; needs a full kinematics update at (q, v)."""
        gamma = np.zeros(self.rows)
        for c in self.constraints:
            gamma[self.slices[c.name]] = c.drift(kin, q, v, t)
        return gamma

    def values(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float, with_drift: bool) -> ConstraintValues:
        """Everything at (q, v, t); ``kin`` must have been updated at that state."""
        if not self.rows:  # nothing to read (a time-stepping run's bodies): empty rows, without a pass over none
            empty = np.zeros(0)
            return ConstraintValues(empty, np.zeros((0, self.nv)), empty, empty, empty if with_drift else None)
        phi = self.residual(kin, q, t)
        jac, time_term = self.velocity_terms(kin, q, t)
        drift = self.drift(kin, q, v, t) if with_drift else None
        return ConstraintValues(phi, jac, time_term, jac @ v + time_term, drift)

    def enforced_positions(self, phi: np.ndarray) -> np.ndarray:
        """The rows whose position residual a projection drives to zero: the holonomic rows, but not a
        unilateral row that is open (phi > 0, a gap)."""
        if not self._has_unilateral:
            return self.holonomic_mask
        return self.holonomic_mask & ~(self.layout.unilateral & (phi > 0.0))

    def enforced_velocities(self, values: ConstraintValues, touching: float = 0.0) -> np.ndarray:
        """The rows whose velocity residual a projection drives to zero: every row, but not a
        unilateral row that is open (phi > ``touching`` [m or rad], the gap a position solve leaves as rounding)
        or separating (g >= 0)."""
        if not self._has_unilateral:
            return self._every_row
        unilateral = self.layout.unilateral
        return ~(unilateral & ((values.phi > touching) | (values.velocity_residual >= 0.0)))

    def violation(self, values: ConstraintValues) -> Violation:
        """The violation at ``values``: max ``|phi|``, ``|g|`` over the rows, where a unilateral row counts
        only its penetration (phi < 0) and its approach (g < 0) [m or rad, m/s or rad/s]."""
        phi, rate = values.phi, values.velocity_residual
        if self._has_unilateral:
            one_sided = self.layout.unilateral
            phi = np.where(one_sided, np.minimum(phi, 0.0), phi)
            rate = np.where(one_sided, np.minimum(rate, 0.0), rate)
        return Violation(float(np.max(np.abs(phi), initial=0.0)), float(np.max(np.abs(rate), initial=0.0)))

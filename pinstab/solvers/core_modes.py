"""The contact modes evaluated by the compiled core: a run of closures with joint limits, joint frictions and plane
contacts keeps its unilateral treatment in Python (which limits and frictions are held, which mode each contact is in,
impacts, events: :mod:`pinstab.integration.events`), and each evaluation in a mode is one call of the core kernel
(:class:`~pinstab.paths.core.CoreDynamics`: kinematics, rows and forces compiled) instead of
:class:`~pinstab.solvers.contact_modes.ModeDynamics`' Pinocchio passes and dense numpy solves. The closures with the
limits and sticking frictions held as equality rows (:class:`~pinstab.constraints.joint_limits.ActiveLimit`) are the
kernel's rows; without contacts its KKT solve gives the accelerations, with them its contacts' solve
(``cpp/contact_modes.hpp``: the rows eliminated through their own factorization, then the modes' force system, the
rules of ModeDynamics, the contacts' rows ``cpp/plane_contacts.hpp``'s) in place of it, for contacts on a plane fixed in
the world or carried by a body, without rotational friction; others (a round pair, torsion or rolling) are
ModeDynamics', and so is an evaluation with a sliding contact slower than
:data:`~pinstab.solvers.contact_modes.GRAZING_SPEED` (a grazing slip, whose direction ModeDynamics slaves to its slip
acceleration). The rows are the event path's: their drift without a stabilization term (its closures are assembled
and its error control keeps them).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..constraints.joint_limits import ActiveLimit, JointLimit
from ..contact.modes import Mode
from ..forces.joint_friction import JointFriction
from ..model import ConstrainedModel
from ..paths.core import CoreDynamics, CoreTerm
from ..runinfo import SolverStatistics
from .base import ACCEPTED_RESIDUAL
from .contact_modes import (
    GRAZING_SPEED,
    HELD_RANK_TOLERANCE,
    RANK_TOLERANCE,
    SLIP_FLOOR,
    Bilateral,
    ContactKinematics,
    ModeDynamics,
    ModeSolution,
    PlaneContactGeometry,
    plane_arrays,
)
from .proxsuite_ import DIRECT_PIVOT

CORE_STATUS = "contact modes, core"  # the solver status of an evaluation the core kernel solved
MODE_CODES = {Mode.STICKING: 0, Mode.SLIDING: 1, Mode.SEPARATED: 2}  # cpp/contact_modes.hpp ContactMode
CONTACT_SETTINGS = {
    "held_rank": HELD_RANK_TOLERANCE,
    "rank_tolerance": RANK_TOLERANCE,
    "slip_floor": SLIP_FLOOR,
    "grazing_speed": GRAZING_SPEED,  # a grazing slip (its direction slaved to its slip acceleration) is ModeDynamics'
}


def compiled_contact(contact: PlaneContactGeometry) -> bool:
    """Whether the core evaluates ``contact``'s modes: a point (or sphere) on a plane fixed in the world or carried by a
    body (not a round pair's), without rotational friction."""
    return contact.core is None and not contact.torsion and not contact.rolling


class CoreModeDynamics(ModeDynamics):
    """:class:`ModeDynamics` whose evaluations in a mode are each solved by the core kernel (one kernel per set of held
    one-row entries, built at its first use; a slipping joint friction's torque passed in as an applied force; the
    contacts set on it whenever their layout changes). An evaluation the kernel does not accept (its residual, see
    :class:`~pinstab.paths.core.CoreDynamics`, a grazing slip, or contacts it does not take: :func:`compiled_contact`)
    is solved by :class:`ModeDynamics`' own, which names what fails; the statistics count the core's under
    :data:`CORE_STATUS`, the others under ``contact modes``.

    Args:
        model, contacts, limits, statistics, joint_frictions: as :class:`ModeDynamics`'.
    """

    def __init__(
        self,
        model: ConstrainedModel,
        contacts: list[PlaneContactGeometry],
        limits: list[JointLimit] | None = None,
        statistics: SolverStatistics | None = None,
        joint_frictions: list[JointFriction] | None = None,
    ) -> None:
        super().__init__(model, contacts, limits, statistics, joint_frictions)
        self._kernels: dict[tuple[tuple[bool, ...], ...], CoreDynamics] = {}
        self._layout = 0  # counts the contacts' layouts (rearrange)
        self._compiles = all(compiled_contact(contact) for contact in contacts)
        self._layouts: dict[int, int] = {}  # per kernel (by id): the layout set on it
        self._codes: dict[int, tuple[int, ...] | None] = {}  # per kernel: its modes, none sliding (else None)
        self._no_contacts = ContactKinematics(
            np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, model.nv)), np.zeros(0)
        )

    def mode_kernel(self) -> CoreDynamics:
        """The core evaluation of the closures with the one-row entries held now (built at first use)."""
        key = (tuple(self.active), tuple(self.stuck))
        if key not in self._kernels:
            held = [ActiveLimit(entry) for entry in self.one_rows()]
            scene = self.model.scene
            model = ConstrainedModel(dataclasses.replace(scene, constraints=[*scene.constraints, *held]))
            rows = model.constraints.rows
            self._kernels[key] = CoreDynamics(
                model, CoreTerm(0.0, np.zeros(rows), False), DIRECT_PIVOT, ACCEPTED_RESIDUAL
            )
        return self._kernels[key]

    def rearrange(self, contacts: list[PlaneContactGeometry]) -> list[int | None]:
        """:meth:`ModeDynamics.rearrange`; the kernels take the new layout at their next use."""
        places = super().rearrange(contacts)
        self._layout += 1
        self._compiles = all(compiled_contact(contact) for contact in self.contacts)
        return places

    def _contact_kernel(self, modes: list[Mode]) -> CoreDynamics | None:
        """The kernel of the one-row entries held now with the contacts set on it in ``modes`` (with a sliding one:
        the slip directions and continued slips of :meth:`slip_direction`), or None: contacts the core does not take."""
        if not self._compiles:
            return None
        core = self.mode_kernel()
        kernel, k = core.kernel, len(self.contacts)
        if self._layouts.get(id(core)) != self._layout:
            frames, plane_frames, radii, bases, origins = plane_arrays(self.contacts)[1]  # all: none is a round pair
            mus = np.array([c.mu for c in self.contacts])
            kernel.set_contacts(frames, plane_frames, bases, origins, radii, mus, CONTACT_SETTINGS)
            self._layouts[id(core)], self._codes[id(core)] = self._layout, None
        codes = tuple(MODE_CODES[mode] for mode in modes)
        sliding = MODE_CODES[Mode.SLIDING] in codes
        if sliding or self._codes[id(core)] != codes:  # without a sliding contact no direction is read
            references, flags = np.zeros((k, 2)), np.zeros(k, dtype=np.int32)
            for i, reference in enumerate([] if self.continued is None else self.continued[:k]):
                if reference is not None:
                    references[i], flags[i] = reference, 1
            directions = np.array(self.directions[:k])
            kernel.set_contact_modes(np.array(codes, dtype=np.int32), directions, references, flags)
            self._codes[id(core)] = None if sliding else codes
        return core

    def _core_acceleration(self, q: np.ndarray, v: np.ndarray, t: float, modes: list[Mode]) -> np.ndarray | None:
        """The core's accelerations at (q, v, t) in ``modes`` [m/s^2, rad/s^2], or None (not solved there)."""
        core = self._contact_kernel(modes)
        if core is None:
            return None
        tau = self.slip_torque() if self.joint_frictions else core.force(self.model, q, v, t)
        acceleration = core.acceleration(q, v, tau, t)
        if core.unusable:
            return None
        self.statistics.record(CORE_STATUS, 0, np.nan, np.nan)
        return acceleration

    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        modes: list[Mode] | None = None,
        spin_modes: list[Mode] | None = None,
    ) -> ModeSolution:
        """:meth:`ModeDynamics.solve`, by the core kernel where it takes the contacts."""
        if not self.contacts:
            return super().solve(q, v, t, modes, spin_modes)
        modes = self.modes if modes is None else modes
        acceleration = self._core_acceleration(q, v, t, modes)
        if acceleration is None:
            return super().solve(q, v, t, modes, spin_modes)
        kernel = self.mode_kernel().kernel
        forces, free, mobility, *rows, residual = kernel.contact_solution()
        self.statistics.worst_primal_residual = max(self.statistics.worst_primal_residual, residual)
        contacts = ContactKinematics(*rows)  # gaps, points, local points, velocities, Jacobian, drift
        return ModeSolution(acceleration, forces, free, mobility, contacts, np.array(kernel.multipliers()))

    def acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        """The accelerations at (q, v, t) in the current modes [m/s^2, rad/s^2] (the integrators' call)."""
        if self.contacts:
            acceleration = self._core_acceleration(q, v, t, self.modes)
            if acceleration is not None:
                return acceleration
        return self.solve(q, v, t).acceleration

    def _unforced(
        self, q: np.ndarray, v: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray, ContactKinematics, Bilateral | None]:
        """The accelerations and the bilateral rows' reactions (closure rows, then the held one-row entries) at
        (q, v, t) from the core kernel without contacts, no response to contact forces (with contacts: ModeDynamics',
        for the evaluations the core does not solve)."""
        if self.contacts:
            return super()._unforced(q, v, t)
        key = (t, q.tobytes(), v.tobytes(), self.mode_key())
        if key == self._state:
            return self._unforced_terms
        core = self.mode_kernel()
        force = core.force(self.model, q, v, t)
        acceleration = core.acceleration(q, v, force + self.slip_torque() if self.joint_frictions else force, t)
        if core.unusable:
            return super()._unforced(q, v, t)
        self.statistics.record(CORE_STATUS, 0, np.nan, np.nan)
        reactions = np.array(core.kernel.multipliers())
        bilateral = Bilateral(reactions, np.zeros((reactions.size, 0)))
        mobility = np.zeros((self.model.nv, 0))
        self._state, self._unforced_terms = key, (acceleration, mobility, self._no_contacts, bilateral)
        return self._unforced_terms

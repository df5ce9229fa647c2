"""The joint limits' modes evaluated by the compiled core: a run of closures and joint limits without plane contacts
(the event path a held run that leaves a limit is restarted on) keeps its unilateral treatment in Python (which limits
are held, impacts, events: :mod:`pinstab.integration.events`), and each evaluation in a mode, the closures with the
limits held as equality rows (:class:`~pinstab.constraints.joint_limits.ActiveLimit`), is one call of the core kernel
(:class:`~pinstab.paths.core.CoreDynamics`: kinematics, rows, forces and the KKT solve compiled) instead of
:class:`~pinstab.solvers.contact_modes.ModeDynamics`' Pinocchio passes and dense numpy solves. The rows are the
event path's: their drift without a stabilization term (its closures are assembled and its error control keeps them).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..constraints.joint_limits import ActiveLimit, JointLimit
from ..forces.joint_friction import JointFriction
from ..model import ConstrainedModel
from ..paths.core import CoreDynamics, CoreTerm
from ..runinfo import SolverStatistics
from .base import ACCEPTED_RESIDUAL
from .contact_modes import Bilateral, ContactKinematics, ModeDynamics
from .proxsuite_ import DIRECT_PIVOT

CORE_STATUS = "contact modes, core"  # the solver status of an evaluation the core kernel solved


class CoreModeDynamics(ModeDynamics):
    """:class:`ModeDynamics` of a model without plane contacts whose held joint limits' and joint frictions' modes are
    each solved by the core kernel (one kernel per set of held one-row entries, built at its first use; a slipping
    friction's torque passed in as an applied force). An evaluation the kernel does not
    accept (its residual, see :class:`~pinstab.paths.core.CoreDynamics`) is solved by :class:`ModeDynamics`' own; the
    statistics count the core's under :data:`CORE_STATUS`, the others under ``contact modes``.

    Args:
        model, limits, statistics, joint_frictions: as :class:`ModeDynamics`' (no contacts).
    """

    def __init__(
        self,
        model: ConstrainedModel,
        limits: list[JointLimit],
        statistics: SolverStatistics | None = None,
        joint_frictions: list[JointFriction] | None = None,
    ) -> None:
        super().__init__(model, [], limits, statistics, joint_frictions)
        self._kernels: dict[tuple[tuple[bool, ...], ...], CoreDynamics] = {}
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

    def _unforced(
        self, q: np.ndarray, v: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray, ContactKinematics, Bilateral | None]:
        """The accelerations and the bilateral rows' reactions (closure rows, then the held one-row entries) at
        (q, v, t) from the core kernel; no contacts, so no response to contact forces."""
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

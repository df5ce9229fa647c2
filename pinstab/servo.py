"""Dynamics with prescribed constraints (servoconstraints) realized by controls (docs/mathematics.md section 5).

At a state, with the real constraint rows G (reactions lambda), the prescribed rows S (no reaction: the
controls realize them) and the actuation B, solve for (a, lambda, u):

    M a - G^T lambda - B u = f,    G a = rhs_G,    S a = rhs_S.

The real constraints alone give a = a0 + N B u (N = M^-1 - M^-1 G^T (G M^-1 G^T)^+ G M^-1, the motions they
allow); the prescribed rows then ask D u = rhs_S - S a0 of the decoupling matrix D = S N B (p x k). D's rank
below p means some direction of the prescribed rows no control reaches at this state:
:class:`~pinstab.errors.ServoInfeasibleError` names the constraints along it, before any solve fails. With
more controls than prescribed rows the excess is resolved by the least effort (min |u|^2), and when the
controls have limits by a ProxSuite QP that respects them (infeasible: the error says which limit).

This is the general path's solve. Its part up to the controls (a0 + N B u, D, the demand, the reactions) is the
compiled :func:`pinstab.kernels.servo_parts` (``cpp/servo_kernel.cpp``), which the compiled servo kernel of
:mod:`pinstab.paths.servo` runs too (with no real rows) on prescribed joint relations alone; that kernel hands this
solver the states where D loses rank, changes sign or a control meets its bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .actuation import Actuation
from .errors import ServoInfeasibleError
from .kernels import ServoParts, controls_within, least_norm, servo_parts, servo_realizability
from .proxqp import proxsuite

# singular values of D with each entry over its row's and its control's sizes (D_ij / (|S_i| |N b_j|), cosines)
# below this times the largest (or 1) count as zero: the rank of S N B whatever the units of each row and control
RANK_TOLERANCE = 1e-9
_SOLVED = (proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED,)


def _when(t: float) -> str:
    """When a servo failed, in its message: t = 0 s is the scene's initial state (the table ``initial``)."""
    return "at t = 0 s (the scene's initial state)" if t == 0.0 else f"at t = {t:.6g} s"


@dataclass
class ServoSolution:
    """(a [m/s^2, rad/s^2], multipliers with zeros on the prescribed rows [N, N m], controls u [N m or N])."""

    acceleration: np.ndarray
    multipliers: np.ndarray
    controls: np.ndarray


class ServoSolver:
    """Solves the dynamics with prescribed rows for a fixed row layout.

    Args:
        prescribed: mask of the prescribed rows. row_names: the constraint of each row. actuation: B and limits.
    """

    def __init__(self, prescribed: np.ndarray, row_names: tuple[str, ...], actuation: Actuation) -> None:
        self.prescribed, self.real = prescribed, ~prescribed
        self.row_names = row_names
        self.actuation = actuation
        self._last_sign: tuple[float, float] | None = None  # (time [s], sign of det D) of the last solve

    def follow(self, last_sign: tuple[float, float] | None) -> None:
        """Continue from a solve made elsewhere (the compiled servo kernel's): its (time [s], sign of det D), so that
        the next solve sees a sign change since then."""
        if last_sign is not None:
            self._last_sign = last_sign

    def decoupling(self, mass_matrix: np.ndarray, jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(D = S N B, N B) at a state (M [kg, kg m^2], the stacked rows' Jacobian)."""
        parts = self._parts(mass_matrix, np.zeros(len(mass_matrix)), jacobian, np.zeros(len(jacobian)))
        return parts.decoupling, parts.moved

    def _parts(
        self, mass_matrix: np.ndarray, free_force: np.ndarray, jacobian: np.ndarray, rhs: np.ndarray
    ) -> ServoParts:
        """The solve up to the controls (:func:`pinstab.kernels.servo_parts`) with this layout's real and prescribed
        rows."""
        real, prescribed = self.real, self.prescribed
        matrix = self.actuation.matrix
        return servo_parts(
            mass_matrix, free_force, jacobian[real], jacobian[prescribed], matrix, rhs[real], rhs[prescribed]
        )

    def solve(
        self,
        mass_matrix: np.ndarray,
        free_force: np.ndarray,
        jacobian: np.ndarray,
        rhs: np.ndarray,
        state: tuple[float, np.ndarray, np.ndarray],
    ) -> ServoSolution:
        """Solve at the state ``(t, q, v)`` (named in errors).

        Raises:
            ServoInfeasibleError: the decoupling matrix loses rank, or the limits leave no control.
        """
        parts = self._parts(mass_matrix, free_force, jacobian, rhs)
        self._check_rank(parts.decoupling, jacobian[self.prescribed], parts.moved, state)
        controls = self._controls(parts.decoupling, parts.demand, state)
        acceleration, reactions = parts.finish(controls)
        multipliers = np.zeros(len(rhs))
        multipliers[self.real] = reactions
        return ServoSolution(acceleration, multipliers, controls)

    def _check_rank(self, decoupling: np.ndarray, rows: np.ndarray, moved: np.ndarray, state: tuple) -> None:
        """Raise when D = S N B (``rows`` S, ``moved`` N B) has rank below p here, free of the units of each row and
        control, or (square D) when its determinant changed sign since the last usable solve: D was singular in
        between, where a step may have passed it by. The verdict, and which solve's sign is remembered (a usable
        one's only), are :func:`pinstab.kernels.servo_realizability`'s, the compiled servo path's rule."""
        count = decoupling.shape[0]
        last = None if self._last_sign is None else self._last_sign[1]
        unit, rank, sign, crossed, usable = servo_realizability(decoupling, rows, moved, RANK_TOLERANCE, last)
        if usable:
            if decoupling.shape[1] == count:
                self._last_sign = (state[0], sign)
            return
        since = ""
        if crossed:
            since = f"; its determinant changed sign since t = {self._last_sign[0]:.6g} s: it was singular in between"
            rank = count - 1
        # the least reached combination y of the unit rows S_i / |S_i|, as a unit combination of the rows S_i
        sizes = np.linalg.norm(rows, axis=1)
        direction = np.linalg.svd(unit)[0][:, -1] / np.where(sizes > 0.0, sizes, 1.0)
        direction /= np.linalg.norm(direction)
        names = [n for n, keep in zip(self.row_names, self.prescribed, strict=True) if keep]
        involved = sorted({names[i] for i in np.flatnonzero(np.abs(direction) > 1e-6)})
        along = " + ".join(f"{direction[i]:+.3g} * {names[i]}[{i}]" for i in np.flatnonzero(np.abs(direction) > 1e-6))
        t, q, v = state
        raise ServoInfeasibleError(
            f"servo {', '.join(repr(n) for n in involved)} cannot be realized {_when(t)}: no control reaches "
            f"the direction {along} of the prescribed rows (decoupling matrix S N B of rank {rank} < {count}{since}; "
            f"controls: {', '.join(self.actuation.names)}); state q = {np.round(q, 6).tolist()}, "
            f"v = {np.round(v, 6).tolist()}",
            involved,
            t,
            q,
            v,
            direction,
        )

    def _controls(self, decoupling: np.ndarray, demand: np.ndarray, state: tuple) -> np.ndarray:
        """The least-effort controls with D u = demand, within the limits (D of full row rank here)."""
        least = least_norm(decoupling, demand)  # the compiled path's: no cutoff drops a control of small columns
        actuation = self.actuation
        if controls_within(least, actuation.lower, actuation.upper):  # the compiled path's test: NaN is outside
            return least
        finite = bool(np.all(np.isfinite(least)))
        if finite:
            solved = self._bounded(decoupling, demand)
            if solved is not None:
                return solved
        t, q, v = state
        over = [
            f"{name} = {value:.4g} outside [{low:g}, {high:g}]"
            for name, value, low, high in zip(actuation.names, least, actuation.lower, actuation.upper, strict=True)
            if not low <= value <= high
        ]
        reason = "within the control limits" if finite else "by finite controls"
        names = sorted({n for n, keep in zip(self.row_names, self.prescribed, strict=True) if keep})
        raise ServoInfeasibleError(
            f"servo {', '.join(repr(n) for n in names)} cannot be realized {_when(t)} {reason}: it needs "
            f"{'; '.join(over)}; state q = {np.round(q, 6).tolist()}, v = {np.round(v, 6).tolist()}",
            names,
            t,
            q,
            v,
        )

    def _bounded(self, decoupling: np.ndarray, demand: np.ndarray) -> np.ndarray | None:
        """The least-effort controls with D u = demand within the limits (a ProxSuite QP), or None: none exist."""
        actuation = self.actuation
        count = actuation.count
        qp = proxsuite.proxqp.dense.QP(count, decoupling.shape[0], count)
        qp.settings.eps_abs = 1e-12
        qp.settings.verbose = False
        qp.settings.max_iter, qp.settings.max_iter_in = 500, 500
        lower = np.where(np.isfinite(actuation.lower), actuation.lower, -1e30)
        upper = np.where(np.isfinite(actuation.upper), actuation.upper, 1e30)
        qp.init(np.eye(count), np.zeros(count), decoupling, demand, np.eye(count), lower, upper)
        qp.solve()
        return np.array(qp.results.x) if qp.results.info.status in _SOLVED else None

"""Series derived from a run's samples, computed when first asked for (not while stepping): constraint
drift, energy, multipliers and the spectral radius of the deviation dynamics."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from scipy.integrate import cumulative_simpson

from .constraints import RowKind
from .errors import DivergenceError, ServoInfeasibleError, SolverError
from .forces.base import Sample
from .kernels import SchemeStep, closure_series
from .model import ConstrainedModel
from .solvers.base import ACCEPTED_RESIDUAL
from .system import ConstrainedSystem
from .zero_dynamics import zero_dynamics_report

# what ConstrainedSystem.dynamics raises at a finite state where the dynamics cannot be had: non-finite (a diverged
# run's last finite state, whose next step failed), controls that do not exist there, contacts that cannot hold, a
# KKT solve that fails there (a run that diverged when its solves failed at a state it reached)
NO_DYNAMICS = (DivergenceError, ServoInfeasibleError, SolverError)
ROUGH_SHARE = 1e-6  # an interval whose Simpson and trapezoid works differ by more than this share of the energy scale
FLOW_AGREEMENT = 1e-2  # ... is integrated along the flow, substeps doubled until two works agree to this share of that
MAX_SUBSTEPS = 256  # substeps at most per interval ...
FLOW_BUDGET = 4  # ... and over the run per sample: the flow costs at most as many evaluations as a run of RK4 x 4
FLOW_WEIGHTS = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0  # the weights of the flow's stages (classical RK4)


class ClosureSeries:
    """The drift and energy series of a scene whose constraints all have compiled rows (closures, joint closures, joint
    relations, fingertip contacts; see :meth:`of`) and whose force elements store no energy (motors, dampers, loads:
    the energy is the mechanism's), by the compiled kernel
    (``closure_series``, ``cpp/series.cpp``) over the constraints' compiled rows
    (:meth:`~pinstab.constraints.base.Constraint.compiled_rows`): one kinematics pass per sample. The position drift
    and the energy are the Python pass's to the last bit (the same row functions and Pinocchio sums); the velocity
    drift is ``G v + g_t`` formed without G (``block_rate``), equal to rounding.

    Args:
        model: the scene's model (see :meth:`of`).
    """

    def __init__(self, model: ConstrainedModel) -> None:
        self.model = model
        self.blocks = [constraint.compiled_rows() for constraint in model.constraints.constraints]

    @classmethod
    def of(cls, model: ConstrainedModel) -> ClosureSeries | None:
        """The compiled series of ``model``, or None when a force element stores energy (a spring's potential), a
        joint has an armature (rotor inertia: the compiled energy is Pinocchio's sum), a constraint has no compiled
        rows (its rows are Python's) or is not holonomic, or a row is unilateral (its violation counts one side
        only)."""
        constraints = model.constraints
        if any(element.stores_energy for element in model.forces) or constraints.layout.unilateral.any():
            return None
        if np.asarray(model.model.armature).any():  # Pinocchio's sum is wrong with rotors (model.kinetic_energy)
            return None
        if any(c.compiled_rows() is None or not c.holonomic for c in constraints.constraints):
            return None
        return cls(model)

    def drift_and_energy(self, q: np.ndarray, v: np.ndarray, t: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`StateSeries.drift_and_energy` at the samples (rows of q, v at times t [s]) [m, m/s, J]."""
        position, velocity, energy = closure_series(
            self.model.model, self.model.scratch, self.blocks, q, v, np.asarray(t, dtype=float)
        )
        return {"position_drift": position, "velocity_drift": velocity, "energy": energy}


class StateSeries:
    """Computes a trajectory's derived series from its samples with the system that produced them.

    Args:
        system: the bound system of the run.
        flow: the classical RK4's step on the system's configuration group (``cpp/stepping.cpp``), with which the
            energy balance integrates the elements' power where the samples do not resolve it; None: it does not.
    """

    def __init__(self, system: ConstrainedSystem, flow: SchemeStep | None = None) -> None:
        self.system = system
        self.flow = flow
        self._closures = ClosureSeries.of(system.model)

    def drift_and_energy(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
        """Position drift max |phi| [m or rad], velocity drift max |g| [m/s or rad/s] and total energy
        [J] per sample; NaN at non-finite samples. Compiled (:class:`ClosureSeries`) for a scene of compiled rows
        whose force elements store no energy, else a pass over the constraints per sample."""
        if self._closures is not None:
            return self._closures.drift_and_energy(q, v, t)
        model = self.system.model
        n = len(t)
        position, velocity, energy = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        for k in np.flatnonzero(finite):
            position[k], velocity[k] = model.violation(q[k], v[k], float(t[k]))  # leaves placements current
            energy[k] = model.energy(q[k], v[k])
        return {"position_drift": position, "velocity_drift": velocity, "energy": energy}

    def energy_balance(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, energy: np.ndarray, events: bool = False
    ) -> dict[str, float]:
        """For a scene with force elements: the work W [J] of their non-conservative parts (dampers, motors,
        applied loads; Simpson's rule over the samples, and along the flow where they do not resolve the power:
        :meth:`_resolved`) and how far ``E(t) - E(0) - W(t)`` strays from zero:
        ``max_energy_balance_error`` [J], and relative to max(|E(0)|, max |W|); empty without force elements
        or finite samples, under a tilting gravity (its work is not counted), and where constraint forces do
        work that W leaves out: unilateral or cone rows (plane contacts: friction, impacts) and runs with
        ``events`` (contact or joint-limit switches and impacts). Equality rows held (closures, grasps held
        sticking) do no work."""
        model = self.system.model
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1) & np.isfinite(energy)
        contacts = any(c.row_kind is not RowKind.EQUALITY for c in model.constraints.constraints)
        if not model.forces or model.scene.tilt is not None or not finite.all() or contacts or events:
            return {}
        power = np.array([self._power(q[k], v[k], float(t[k])) for k in range(len(t))])
        work = cumulative_simpson(power, x=t, initial=0.0) if len(t) > 2 else np.zeros(len(t))
        scale = max(abs(float(energy[0])), float(np.max(np.abs(work))))
        work = self._resolved(t, q, v, power, work, ROUGH_SHARE * scale)
        error = float(np.max(np.abs(energy - energy[0] - work)))
        scale = max(abs(float(energy[0])), float(np.max(np.abs(work))))
        return {
            "force_work": float(work[-1]),
            "max_energy_balance_error": error,
            "energy_balance_relative": error / scale if scale > 0 else 0.0,
        }

    def _power(self, q: np.ndarray, v: np.ndarray, t: float) -> float:
        """The force elements' non-conservative power at (q, v, t) [W]."""
        model = self.system.model
        model.kin.update_jacobians(q)
        return sum(element.power(model.kin, v, t) for element in model.forces)

    def _resolved(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, power: np.ndarray, work: np.ndarray, bound: float
    ) -> np.ndarray:
        """``work`` [J] (Simpson's over the samples) with the share of each interval whose Simpson and trapezoid
        shares differ by more than ``bound`` [J] (a power the samples do not resolve: a stiff element's fast transient,
        stiff-fourbar's damper in its first milliseconds) replaced by the work along the motion's flow from the
        interval's first sample, the power integrated with the flow's own stages (:meth:`_flow_work`). The balance
        then counts on such an interval what the run's state lost to its step, E(end) - E(flow from the start), its
        energy error, not the quadrature's."""
        if self.flow is None or len(t) < 3:
            return work
        shares = np.diff(work)
        trapezoid = 0.5 * np.diff(t) * (power[1:] + power[:-1])
        roughness = np.abs(shares - trapezoid)
        rough = np.flatnonzero(roughness > bound)
        if not len(rough):
            return work
        budget = FLOW_BUDGET * len(t)
        for k in rough[np.argsort(-roughness[rough], kind="stable")]:  # the roughest first, within the budget
            if budget <= 0:
                break
            try:
                with np.errstate(over="ignore", invalid="ignore"):
                    flow, used = self._flow_work(q[k], v[k], float(t[k]), float(t[k + 1]), FLOW_AGREEMENT * bound)
            except (*NO_DYNAMICS, OverflowError):  # a state the flow cannot leave (a diverged run's): Simpson's share
                budget -= MAX_SUBSTEPS
                continue
            budget -= used
            if math.isfinite(flow):
                shares[k] = flow
        return np.concatenate([[0.0], np.cumsum(shares)])

    def _flow_work(self, q: np.ndarray, v: np.ndarray, start: float, end: float, tolerance: float) -> tuple[float, int]:
        """The elements' work [J] from (q, v) at ``start`` to ``end`` [s] along the flow: RK4 substeps, the power at
        their stages weighed as the states are (the work a state of the run integrates alongside), doubled until two
        works agree to ``tolerance`` [J] (at most :data:`MAX_SUBSTEPS`); and the substeps taken."""
        acceleration = self.system.acceleration
        stages: list[float] = []

        def evaluation(qs: np.ndarray, vs: np.ndarray, ts: float, stage: int) -> np.ndarray:
            stages.append(self._power(qs, vs, ts))
            return acceleration(qs, vs, ts, stage)

        previous, substeps, used = math.nan, 1, 0
        while True:
            step, work, qi, vi = (end - start) / substeps, 0.0, q, v
            for i in range(substeps):
                stages.clear()
                qi, vi = self.flow.step(evaluation, qi, vi, start + i * step, step)
                work += step * float(FLOW_WEIGHTS @ np.array(stages))
            used += substeps
            if abs(work - previous) <= tolerance or substeps >= MAX_SUBSTEPS or not math.isfinite(work):
                return work, used
            previous, substeps = work, 2 * substeps

    def multipliers(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The constraint multipliers per sample [N, N m]; NaN at non-finite samples and where the dynamics cannot be
        had (:data:`NO_DYNAMICS`: the last sample of a run that ended with ContactInfeasibleError, or the last finite
        state of one that diverged from it). On the native path where its compiled kernel takes the force elements
        (:attr:`~pinstab.paths.native.NativeDynamics.force_obstacle`: none, or all compiled), Pinocchio's solves at
        every sample in one compiled call (``NativeKernel.multipliers``), those that
        miss the check (:meth:`~pinstab.paths.native.NativeDynamics.residual`) taken again one by one as
        :meth:`~pinstab.system.ConstrainedSystem.multipliers` takes them."""
        system = self.system
        out = np.full((len(t), system.model.constraints.rows), np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        native = system.native
        if native is not None and system.banded is None and native.force_obstacle is None:
            forces, residuals = native.kernel().multipliers(t, q, v, system.model.no_force, native.rows)
            passed = finite & (residuals <= ACCEPTED_RESIDUAL)
            out[passed] = forces[passed]
            finite &= ~passed
        with np.errstate(over="ignore", invalid="ignore"):
            for k in np.flatnonzero(finite):
                try:
                    out[k] = system.multipliers(q[k], v[k], float(t[k]))
                except NO_DYNAMICS:
                    continue
        return out

    def spectral_radius(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """rho(R(tau W)) per sample [-]; NaN for methods without a stabilization term."""
        stabilizer, model = self.system.stabilizer, self.system.model
        if stabilizer.constant_gains:
            radius = stabilizer.spectral_radius(model, q[0], v[0], float(t[0]))
            return np.full(len(t), math.nan if radius is None else radius)
        out = np.full(len(t), np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        for k in np.flatnonzero(finite):
            radius = stabilizer.spectral_radius(model, q[k], v[k], float(t[k]))
            out[k] = math.nan if radius is None else radius
        return out

    def contact_figures(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, multipliers: Callable[[], np.ndarray]
    ) -> dict[str, Any]:
        """Over the samples, for a scene with contacts: the smallest normal force [N], friction-cone
        margin mu f_n - |f_t| [N] and torsion margin [N m] (>= 0: held), the largest slip of a sticking
        contact's material points [m], overall and per contact; empty without contacts."""
        model = self.system.model
        limited = model.constraints.force_limited
        sticking = [c for c in model.constraints.constraints if c.slip(model.kin) is not None]
        if not limited and not sticking:
            return {}
        forces = multipliers()
        per_contact: dict[str, dict[str, float]] = {}
        finite = np.flatnonzero(np.isfinite(forces).all(axis=1))
        for constraint, rows in limited:
            margins = [constraint.margins(forces[k, rows]) for k in finite]
            for key in margins[0] if margins else ():
                label = "min_normal_force" if key == "normal" else f"min_{'cone' if key == 'friction' else key}_margin"
                per_contact.setdefault(constraint.name, {})[label] = min(m[key] for m in margins)
        for k in finite:
            model.kin.update_positions(q[k])
            for constraint in sticking:
                entry = per_contact.setdefault(constraint.name, {})
                entry["max_slip"] = max(entry.get("max_slip", 0.0), constraint.slip(model.kin))
        figures: dict[str, Any] = {}
        for label in ("min_normal_force", "min_cone_margin", "min_torsion_margin"):
            values = [entry[label] for entry in per_contact.values() if label in entry]
            if values:
                figures[label] = min(values)
        slips = [entry["max_slip"] for entry in per_contact.values() if "max_slip" in entry]
        if slips:
            figures["max_contact_slip"] = max(slips)
        figures["contacts"] = per_contact
        return figures

    def force_figures(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, multipliers: Callable[[], np.ndarray]
    ) -> dict[str, Any]:
        """The figures the scene's force elements report on the run (a controller's tracking error and
        internal force: :meth:`~pinstab.forces.base.ForceElement.run_figures`), per element under
        ``controllers``, and each ``max_`` figure's largest value over the elements; empty when none reports."""
        per_element = {}
        for element in self.system.model.forces:
            figures = element.run_figures(self._samples(t, q, v, multipliers))
            if figures:
                per_element[element.name] = figures
        if not per_element:
            return {}
        largest: dict[str, float] = {}
        for figures in per_element.values():
            for key, value in figures.items():
                if key.startswith("max_") and isinstance(value, int | float):
                    largest[key] = max(largest.get(key, -math.inf), value)
        return {**largest, "controllers": per_element}

    def _samples(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, multipliers: Callable[[], np.ndarray]
    ) -> Iterator[Sample]:
        """The finite samples, the kinematics updated at each; the multipliers computed when first asked for."""
        model = self.system.model
        forces = multipliers()
        slices = model.constraints.slices
        for k in np.flatnonzero(np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)):
            model.kin.update(q[k], v[k])
            yield Sample(model.kin, v[k], float(t[k]), {name: forces[k, rows] for name, rows in slices.items()})

    def servo_figures(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, Any]:
        """For a scene with prescribed constraints: per sample the controls u [N m or N] and the largest
        prescribed-row residual: |sigma| [m or rad] on holonomic rows, the velocity residual [m/s or rad/s]
        on Pfaffian ones; NaN at a sample that is not finite or whose dynamics cannot be had (:data:`NO_DYNAMICS`:
        the last finite state of a run that diverged from it); empty otherwise, and when no sample has them."""
        system = self.system
        if system.servo is None:
            return {}
        model = system.model
        constraints = model.constraints
        holonomic = constraints.prescribed_mask & constraints.holonomic_mask
        pfaffian = constraints.prescribed_mask & ~constraints.holonomic_mask
        controls = np.full((len(t), system.servo.actuation.count), np.nan)
        error = np.full(len(t), np.nan)
        with np.errstate(over="ignore", invalid="ignore"):
            for k in np.flatnonzero(np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)):
                try:
                    evaluation = system.dynamics(q[k], v[k], float(t[k]))  # its values are those at (q, v, t) too
                except NO_DYNAMICS:
                    continue
                controls[k], values = evaluation.controls, evaluation.values
                residual = np.concatenate([values.phi[holonomic], values.velocity_residual[pfaffian]])
                error[k] = float(np.max(np.abs(residual), initial=0.0))
        if np.isnan(error).all():
            return {}
        return {"controls": controls, "servo_error": error}

    def zero_dynamics(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, Any]:
        """For a scene with prescribed constraints: the free coordinates, the eigenvalues of the zero dynamics
        at the start and the free coordinates' speeds (:func:`~pinstab.zero_dynamics.zero_dynamics_report`);
        empty otherwise, and when the dynamics cannot be had at the start (:data:`NO_DYNAMICS`: a run that diverged
        at its first step), where they are linearized."""
        if self.system.servo is None:
            return {}
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                return zero_dynamics_report(self.system, t, q, v)
        except NO_DYNAMICS:
            return {}

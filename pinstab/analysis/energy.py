"""Where a run's energy went: the change of the total energy E(t) - E(0) split into the work of what is meant to
change it (force elements' non-conservative parts: dampers, motors, applied loads; the servo controls; the impulses
of impacts) and the remainder ``E(t) - E(0) - W(t)``: the energy the integration, the stabilization and the solver
made or lost, plus any work this budget does not count (listed in :attr:`EnergyBudget.uncounted`).

The works are computed from the run's samples: a force element's power (:meth:`~pinstab.forces.base.ForceElement.
power`) and the controls' ``(B u) . v`` by Simpson's rule over the samples (the trapezoidal rule across impacts, where
the velocities jump); an impact's work is the one its event records (``work`` [J], exact at the impact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_simpson, cumulative_trapezoid

from ..contact.modes import Mode
from ..errors import PinstabError
from ..model import ConstrainedModel
from ..scene import Scene, load_scene
from ..trajectory import Trajectory

IMPACTS, CONTROLS = "impacts", "servo controls"  # names of the budget's terms besides the force elements'
EVENT_SLACK = 1e-12  # [s] an impact this close after a sample is at it (the run keeps the state after it there)


@dataclass(frozen=True)
class EnergyBudget:
    """A run's energy change and the work that explains it, at its samples.

    Attributes:
        t: the sample times (n,) [s]. change: E(t) - E(0) (n,) [J].
        work: the cumulative work of each counted term (n,) [J] by name: each force element with a non-conservative
            part (by its name), ``servo controls``, ``impacts``; only the terms the run has.
        uncounted: what did work this budget leaves in the remainder, in words (empty when everything is counted).
    """

    t: np.ndarray
    change: np.ndarray
    work: dict[str, np.ndarray]
    uncounted: list[str]

    @property
    def counted(self) -> np.ndarray:
        """The total counted work W(t) (n,) [J]."""
        return sum(self.work.values(), np.zeros_like(self.change))

    @property
    def remainder(self) -> np.ndarray:
        """E(t) - E(0) - W(t) (n,) [J]: the energy error of the run (and any uncounted work)."""
        return self.change - self.counted


def energy_budget(trajectory: Trajectory, scene: Scene | None = None) -> EnergyBudget:
    """The energy budget of ``trajectory``, a run of ``scene`` (None: the bundled scene of the run's name and
    parameters, reloaded; when that fails the force elements' work is listed as uncounted).

    Raises:
        PinstabError: ``scene`` is not the run's (another number of coordinates).
    """
    t = trajectory.t
    info = trajectory.info
    energy = trajectory.energy
    uncounted: list[str] = []
    work: dict[str, np.ndarray] = {}
    events = info.contact_events
    impacts = [event for event in events if "work" in event]
    jumps = bool(impacts)
    model = _model(trajectory, scene, uncounted)
    if model is not None:
        for element, power in zip(model.forces, _powers(model, trajectory).T, strict=True):
            if np.any(power != 0.0):  # conservative elements (springs) have no such part
                work[element.name] = _integral(power, t, jumps)
        if model.scene.tilt is not None:
            uncounted.append("the turning gravity ([tilt])")
    controls = trajectory.servo_figures.get("controls")
    if controls is not None and model is not None and model.scene.actuation is not None:
        power = np.einsum("ij,ij->i", controls @ model.scene.actuation.matrix.T, trajectory.v)
        work[CONTROLS] = _integral(power, t, jumps)
    elif info.controls:
        uncounted.append("the servo controls (not kept with a saved run)")
    if impacts:
        times = np.array([event["t"] for event in impacts])
        cumulative = np.cumsum([event["work"] for event in impacts])
        reached = np.searchsorted(times, t + EVENT_SLACK, side="right")
        work[IMPACTS] = np.concatenate([[0.0], cumulative])[reached]
    elif any(event.get("to") == "closing" for event in events):
        uncounted.append("the impacts (a run saved before their work was recorded)")
    if any(event.get("to") == Mode.SLIDING.value for event in events):
        uncounted.append("sliding friction")
    if info.path == "contact-stepping":
        uncounted.append("the contact impulses of time-stepping")
    change = energy - energy[0]
    return EnergyBudget(t, change, work, uncounted)


def _model(trajectory: Trajectory, scene: Scene | None, uncounted: list[str]) -> ConstrainedModel | None:
    """The run's model: of ``scene``, or of its bundled scene reloaded (None, noted in ``uncounted``, when it has
    none or another size)."""
    info = trajectory.info
    if scene is None:
        try:
            scene = load_scene(info.scene, **info.scene_parameters)
        except PinstabError:
            uncounted.append(f"the force elements (scene {info.scene!r} not found to compute them)")
            return None
        if scene.model.nq != trajectory.q.shape[1]:
            uncounted.append(f"the force elements (the bundled scene {info.scene!r} is not the run's)")
            return None
    elif scene.model.nq != trajectory.q.shape[1]:
        raise PinstabError(
            f"scene {scene.name} has {scene.model.nq} coordinates, the run of {info.scene} {trajectory.q.shape[1]}"
        )
    return ConstrainedModel(scene)


def _powers(model: ConstrainedModel, trajectory: Trajectory) -> np.ndarray:
    """(n, m) the power [W] of each force element's non-conservative part at each sample (NaN at non-finite ones)."""
    kin = model.kin
    q, v, t = trajectory.q, trajectory.v, trajectory.t
    powers = np.full((len(t), len(model.forces)), np.nan)
    for k in np.flatnonzero(np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)):
        kin.update_jacobians(q[k])
        powers[k] = [element.power(kin, v[k], float(t[k])) for element in model.forces]
    return powers


def _integral(power: np.ndarray, t: np.ndarray, jumps: bool) -> np.ndarray:
    """The cumulative integral of ``power`` [W] over the sample times ``t`` [s] [J]: Simpson's rule, the trapezoidal
    rule where the velocities jump (impacts) or over fewer than three samples."""
    if len(t) < 2:
        return np.zeros(len(t))
    if jumps or len(t) < 3:
        return cumulative_trapezoid(power, t, initial=0.0)
    return cumulative_simpson(power, x=t, initial=0.0)

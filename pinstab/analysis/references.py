"""References a run is compared with: a scene's exact motion (registered per scene) or a saved run."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import PinstabError
from ..integration.dense import Segment
from ..model import ConstrainedModel
from ..registry import Registry
from ..scene import Scene
from ..trajectory import Trajectory

EXACT_TOLERANCE = 1e-13  # rtol = atol of SciPy's DOP853 on an exact ODE: 1e-12 rad from 1e-14 over 1 s (fourbar)
TIME_SLACK = 1e-9  # [s] a run's sample within this of a reference's sample is taken at it


@dataclass(frozen=True)
class Reference:
    """A reference motion at a run's sample times.

    Attributes:
        kind: what it is, in words (shown in the JSON and on the chart).
        q: configurations (n, nq) at the run's sample times.
        default_of: the coordinates compared when none are named (joint or frame names).
    """

    kind: str
    q: np.ndarray
    default_of: tuple[str, ...]


ExactMotion = Callable[[Scene, np.ndarray, np.ndarray, np.ndarray], Reference]
EXACT_REFERENCES: Registry[Reference] = Registry("exact reference")


def exact_reference(scene: Scene, q0: np.ndarray, v0: np.ndarray, times: np.ndarray) -> Reference:
    """The scene's exact motion from (q0, v0) at ``times`` [s] (from times[0]).

    Raises:
        PinstabError: the scene has no exact reference (naming the scenes that have one), or its start
            is outside the reference's assumptions.
    """
    if exact_name(scene) is None:
        raise PinstabError(
            f"scene {scene.name!r} has no exact reference; scenes with one: {', '.join(EXACT_REFERENCES)} "
            "(or give a saved run: --reference FILE.npz)"
        )
    return EXACT_REFERENCES.entry(exact_name(scene)).factory(scene, q0, v0, np.asarray(times, dtype=float))


def exact_name(scene: Scene) -> str | None:
    """The name the scene's exact reference is registered under (its generator's, else its own), or None."""
    for name in (scene.generator, scene.name):
        if name in EXACT_REFERENCES:
            return name
    return None


def solve_exact(
    rate: Callable[[float, np.ndarray], np.ndarray],
    start: np.ndarray,
    times: np.ndarray,
    method: str = "DOP853",
    tolerance: float = EXACT_TOLERANCE,
    jacobian: Callable[[float, np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """A small ODE y' = rate(t, y) from ``start`` at times[0], integrated by SciPy's ``method`` (DOP853, or an
    implicit one such as Radau with its ``jacobian`` d rate / dy) at rtol = atol = ``tolerance`` (default
    :data:`EXACT_TOLERANCE`); returns y at ``times`` (n, len(start)).

    Raises:
        PinstabError: the integration failed (its message).
    """
    if len(times) == 1 or times[-1] == times[0]:
        return np.tile(start, (len(times), 1))
    options = {} if jacobian is None else {"jac": jacobian}
    solution = solve_ivp(
        rate,
        (times[0], times[-1]),
        start,
        method=method,
        t_eval=times,
        rtol=tolerance,
        atol=tolerance,
        **options,
    )
    if not solution.success:
        raise PinstabError(f"the exact reference's {method} integration failed: {solution.message}")
    return solution.y.T


def saved_reference(reference: Trajectory, scene: Scene, times: np.ndarray, label: str = "a saved run") -> Reference:
    """A saved run of the same scene at ``times`` [s]: its own samples where a time falls on one, else
    its motion between the two samples around it (cubic Hermite in the tangent space, from their q and v).

    Raises:
        PinstabError: a run of another scene or parameters, or one that ends before ``times`` does.
    """
    info = reference.info
    if info.scene != scene.name or dict(info.scene_parameters) != dict(scene.parameters):
        raise PinstabError(
            f"the reference {label} is a run of {_described(info.scene, info.scene_parameters)}, this run is of "
            f"{_described(scene.name, scene.parameters)}: compare runs of one scene"
        )
    t = reference.t
    if len(times) and times[-1] > t[-1] + TIME_SLACK:
        raise PinstabError(
            f"the reference {label} ends at t = {t[-1]:g} s, before this run's last sample at {times[-1]:g} s: "
            "save a reference at least as long as the run"
        )
    model = ConstrainedModel(scene)
    q = np.empty((len(times), scene.model.nq))
    for i, time in enumerate(times):
        k = int(np.clip(np.searchsorted(t, time), 0, len(t) - 1))
        near = k if abs(t[k] - time) <= TIME_SLACK else k - 1 if k and abs(t[k - 1] - time) <= TIME_SLACK else None
        if near is not None:
            q[i] = reference.q[near]
            continue
        a, b = max(k - 1, 0), k
        span = Segment(model, t[a], reference.q[a], reference.v[a], None, t[b], reference.q[b], reference.v[b], None)
        q[i] = span.state(time)[0]
    kind = f"{label}: {info.method} + {info.integrator}, dt = {info.dt:g} s"
    return Reference(kind, q, ())


def reference_for(spec: str | Path | Trajectory, scene: Scene, run: Trajectory) -> Reference:
    """The reference ``spec`` at the run's sample times: ``"exact"`` (the scene's exact motion from the run's
    first sample), a saved run's path (``.npz``), or a :class:`~pinstab.trajectory.Trajectory`.

    Raises:
        PinstabError: see :func:`exact_reference`, :func:`saved_reference`, :meth:`Trajectory.load`.
    """
    if isinstance(spec, Trajectory):
        return saved_reference(spec, scene, run.t)
    if str(spec) == "exact":
        return exact_reference(scene, run.q[0], run.v[0], run.t)
    return saved_reference(Trajectory.load(spec), scene, run.t, label=str(spec))


def check_reference(spec: str | Path, scene: Scene) -> None:
    """Refuse a reference before a run: ``exact`` for a scene without one, or a missing or unreadable file.

    Raises:
        PinstabError: naming the scenes with an exact reference, or the file's problem.
    """
    if str(spec) == "exact":
        if exact_name(scene) is None:
            exact_reference(scene, scene.q0, scene.v0, np.zeros(1))
        return
    Trajectory.load(spec)


def _described(name: str, parameters: dict) -> str:
    listed = ", ".join(f"{key}={value}" for key, value in sorted(parameters.items()))
    return f"{name!r}" + (f" ({listed})" if listed else "")


def wrapped_like(angles: np.ndarray, start: float) -> np.ndarray:
    """Continuous angles [rad] (unwrapped) shifted by whole turns to begin at ``start``'s winding."""
    angles = np.unwrap(angles, axis=0)
    return angles + 2 * math.pi * np.round((start - angles[0]) / (2 * math.pi))

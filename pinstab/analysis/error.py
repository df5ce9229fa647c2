"""The trajectory error of a run: the largest deviation of named coordinates from a reference over time."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import PinstabError
from ..scene import Scene, load_scene
from ..trajectory import Comparison, Trajectory
from .references import reference_for

ERROR_OF_JOINTS = "joints"  # the coordinate name meaning every joint (the largest of their errors)

Measure = Callable[[np.ndarray, np.ndarray], float]  # (q of the run, q of the reference) -> error


def trajectory_error(
    trajectory: Trajectory,
    reference: str | Path | Trajectory = "exact",
    of: Sequence[str] | None = None,
    scene: Scene | None = None,
) -> Comparison:
    """Compare a run with a reference at each of its samples.

    Args:
        trajectory: the run.
        reference: ``"exact"`` (the scene's exact motion from the run's first sample), a saved run (its
            path or the loaded :class:`~pinstab.trajectory.Trajectory`) of the same scene.
        of: coordinates to compare: joint names (error ``|q (-) q_ref|`` of that joint [rad or m]), frame
            names (distance of the frame origins [m]), or ``"joints"`` (the largest joint error). Default:
            the exact reference's natural coordinate (fourbar: ``crank``; nfourbar: ``crank0_joint``),
            else ``joints``.
        scene: the run's scene (default: loaded again from the run's scene name and parameters).

    Returns:
        The error of each coordinate at each sample (:class:`~pinstab.trajectory.Comparison`).

    Raises:
        PinstabError: an unknown coordinate (listing the joints), a reference that does not fit the run.
    """
    scene = scene or load_scene(trajectory.info.scene, **trajectory.info.scene_parameters)
    if of:
        check_coordinates(scene.model, of)
    expected = reference_for(reference, scene, trajectory)
    names = list(of or expected.default_of or (ERROR_OF_JOINTS,))
    measures = [coordinate_measure(scene.model, name) for name in names]
    error = np.array(
        [[measure(q, q_ref) for measure, _ in measures] for q, q_ref in zip(trajectory.q, expected.q, strict=True)]
    )
    return Comparison(expected.kind, names, [unit for _, unit in measures], error.reshape(len(trajectory.t), -1))


def check_coordinates(model: pin.Model, names: Sequence[str]) -> None:
    """Refuse coordinate names that are neither a joint, a frame nor ``joints`` (before a run).

    Raises:
        PinstabError: see :func:`coordinate_measure`.
    """
    for name in names:
        coordinate_measure(model, name)


def coordinate_measure(model: pin.Model, name: str) -> tuple[Measure, str]:
    """How to measure the error of coordinate ``name`` and its unit.

    Raises:
        PinstabError: no joint or frame of that name (listing the joints).
    """
    if name == ERROR_OF_JOINTS:
        return (lambda q, q_ref: float(np.max(np.abs(pin.difference(model, q_ref, q))))), "rad or m"
    if model.existJointName(name):
        joint = model.joints[model.getJointId(name)]
        start, stop = joint.idx_v, joint.idx_v + joint.nv
        kind = joint.shortname()
        unit = "m" if kind.startswith("JointModelP") and not kind.startswith("JointModelPlanar") else "rad"
        return (lambda q, q_ref: float(np.linalg.norm(pin.difference(model, q_ref, q)[start:stop]))), unit
    if model.existFrame(name):
        frame = model.getFrameId(name)
        data = pin.Data(model)

        def distance(q: np.ndarray, q_ref: np.ndarray) -> float:
            pin.forwardKinematics(model, data, q)
            position = pin.updateFramePlacement(model, data, frame).translation.copy()
            pin.forwardKinematics(model, data, q_ref)
            return float(np.linalg.norm(position - pin.updateFramePlacement(model, data, frame).translation))

        return distance, "m"
    joints = ", ".join(model.names[j] for j in range(1, model.njoints))
    raise PinstabError(
        f"no joint or frame named {name!r} to measure the error of; joints: {joints} (or a frame name, or "
        f"{ERROR_OF_JOINTS!r} for all joints)"
    )

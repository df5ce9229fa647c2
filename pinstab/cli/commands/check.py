"""``pinstab check``: assemble a scene and report its constraint structure and its joint limits (each limited
joint's [lower, upper], and why the others are unlimited); a start that ``run`` refuses (outside the joint limits) is
refused here too, and only what ``run`` refuses: like a run with its default contacts, a scene of plane contacts only
(event-driven contacts) starts as given, its contacts not assembled (a corner a hair inside its plane is no error);
a scene with servos is evaluated at its assembled start as ``run`` and ``servo --check`` evaluate it
(:func:`servo_at_start`): a servo the controls cannot realize at t = 0 is refused here too."""

from __future__ import annotations

import argparse
import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np

from ..options import (
    DEFAULT_METHOD,
    assembly_argument,
    assembly_tolerance,
    limits_argument,
    scene_arguments,
    scene_options,
)
from .base import Command, register

if TYPE_CHECKING:
    from ...scene import Scene


def servo_at_start(scene: Scene, method: str, tolerance: float | None) -> dict[str, Any]:
    """The servos of ``scene`` at its assembled start (t = 0 s), solved by the dynamics a run of ``method`` starts
    with: the singular values of the decoupling matrix S N B (each row and control's units) and the controls at the
    start [N or N m].

    Raises:
        ServoInfeasibleError: the controls cannot realize the servos at t = 0 s (the run's refusal, its message).
    """
    from ...assembly import assemble
    from ...system import build_system

    system = build_system(scene, method)
    start = assemble(system.model, scene.q0, scene.v0, tolerance=tolerance)
    evaluation = system.dynamics(start.q, start.v, 0.0)  # raises ServoInfeasibleError when it cannot
    decoupling = system.servo.decoupling(system.model.kin.mass_matrix, evaluation.values.jacobian)[0]
    return {
        "realizable": True,
        "decoupling_singular_values": np.linalg.svd(decoupling, compute_uv=False).tolist(),
        "controls_at_start": dict(zip(scene.actuation.names, evaluation.controls.tolist(), strict=True)),
    }


def check(args: argparse.Namespace) -> dict[str, Any]:
    from ...assembly import assemble
    from ...constraints.joint_limits import joint_limits
    from ...model import ConstrainedModel
    from ...scene import load_scene
    from ...simulate.choice import default_contacts
    from ...simulate.contacts import event_contacts
    from ...simulate.held import refuse_separating_contacts
    from ...simulate.limits import held_limits

    scene = load_scene(args.scene, **scene_options(args))
    held_limits(scene, scene.q0, not args.ignore_limits)
    servos = (
        servo_at_start(scene, DEFAULT_METHOD, assembly_tolerance(args))
        if any(c.prescribed for c in scene.constraints)
        else None
    )
    model = ConstrainedModel(scene)
    kept = set(event_contacts(scene)[1])  # event-driven contacts are not assembled; closures beside them are
    held = [c for c in scene.constraints if c.name in kept]
    event = default_contacts(scene) != "held"
    assembled = ConstrainedModel(dataclasses.replace(scene, constraints=held)) if event else model
    report = assemble(assembled, scene.q0, scene.v0, tolerance=assembly_tolerance(args))
    if assembled is model:  # contacts held as rows (the scene's default): a start they cannot hold, as run refuses
        refuse_separating_contacts(model, report.q, report.v, scene.name)
    values = model.constraint_values(report.q, report.v, 0.0)
    limits = joint_limits(scene.model)
    rows = model.constraints.rows
    if rows:
        singular_values = np.linalg.svd(values.jacobian, compute_uv=False)
        rank = int(np.sum(singular_values > 1e-9 * max(singular_values[0], 1.0)))
    else:
        rank = 0
    return {
        "scene": scene.name,
        "nq": scene.model.nq,
        "nv": scene.model.nv,
        "rows": rows,
        "rank": rank,
        "redundant": rows - rank,
        "mobility": scene.model.nv - rank,
        "assembly_residual": report.residual,
        "assembly_tolerance": report.tolerance,
        "mechanism_size": report.size,
        "assembly_iterations": report.iterations,
        "assembly_velocity_residual": report.velocity_residual,
        "constraints": {
            c.name: {
                "rows": c.rows,
                "holonomic": c.holonomic,
                "kind": c.row_kind.value,
                "scene_kind": getattr(c, "kind", None),  # the kind the scene (or robot file) names: point, weld, ...
                "frame": c.force_frame,
            }
            for c in scene.constraints
        },
        "locked_joints": scene.locked_joints,
        "robot_format": scene.robot.format if scene.robot is not None else None,
        "robot_notes": scene.robot.notes if scene.robot is not None else [],
        "overlaps": [  # robot links inside objects beyond the tolerance, at the assembled start
            {"link": o.link, "shape": o.shape, "object": o.item, "depth_mm": o.depth * 1e3}
            for o in ([] if scene.collisions is None else scene.collisions.overlaps(report.q))
        ],
        "joint_limits": limits.ranges(),
        "unlimited_joints": limits.unlimited,
        **({} if servos is None else {"servo_at_start": servos}),
    }


def arguments(parser: argparse.ArgumentParser) -> None:
    """The scene, ``--ignore-limits`` and ``--assembly-tol``."""
    scene_arguments(parser)
    limits_argument(parser)
    assembly_argument(parser)


register(Command("check", "assemble a scene and report its constraint structure", arguments, check, order=0))

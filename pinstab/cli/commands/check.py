"""``pinstab check``: assemble a scene and report its constraint structure and its joint limits (each limited
joint's [lower, upper], and why the others are unlimited)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..options import parameters, scene_arguments
from .base import Command, register


def check(args: argparse.Namespace) -> dict[str, Any]:
    from ...assembly import assemble
    from ...constraints.joint_limits import joint_limits
    from ...model import ConstrainedModel
    from ...scene import load_scene

    scene = load_scene(args.scene, **parameters(args.param))
    model = ConstrainedModel(scene)
    report = assemble(model, scene.q0, scene.v0)
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
        "assembly_iterations": report.iterations,
        "assembly_velocity_residual": report.velocity_residual,
        "constraints": {
            c.name: {"rows": c.rows, "holonomic": c.holonomic, "kind": c.row_kind.value, "frame": c.force_frame}
            for c in scene.constraints
        },
        "locked_joints": scene.locked_joints,
        "joint_limits": limits.ranges(),
        "unlimited_joints": limits.unlimited,
    }


register(Command("check", "assemble a scene and report its constraint structure", scene_arguments, check, order=0))

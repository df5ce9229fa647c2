"""``pinstab grasp``: grasp map, hand Jacobian, force closure, quality, the load a grasp holds."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ..options import scene_arguments, scene_options, vector_argument
from .base import Command, register


def arguments(grasp: argparse.ArgumentParser) -> None:
    """The scene, ``--facets``, ``--squeeze``, ``--tilt-axis``."""
    scene_arguments(grasp)
    grasp.add_argument(
        "--facets", type=int, default=8, help="sides of the pyramids that linearize the friction cones (default: 8)"
    )
    grasp.add_argument(
        "--squeeze",
        type=float,
        help="largest normal force per contact [N] for the largest load and tilt (default: the scene's grasp-hold)",
    )
    vector_argument(
        grasp,
        "--tilt-axis",
        "world axis of the hand's tilt, e.g. --tilt-axis=-1,0,0 or --tilt-axis -1 0 0 (default: the two horizontal "
        "world axes)",
    )


def grasp(args: argparse.Namespace) -> dict[str, Any]:
    """The figures of every grasped object (:class:`~pinstab.grasp.report.ObjectGrasp`), and without ``--squeeze``
    under the scene's ``[tilt]`` when it has one (``under_scene_tilt``,
    :func:`~pinstab.grasp.report.slips_under_tilt`): when its first contact slips and its grasp-hold lets go."""
    from ...grasp.report import analyse_scene_grasps, slips_under_tilt
    from ...scene import load_scene

    scene = load_scene(args.scene, **scene_options(args))
    grasps = analyse_scene_grasps(scene, facets=args.facets, squeeze=args.squeeze, tilt_axis=args.tilt_axis)
    objects = {name: grasp.to_json() for name, grasp in grasps.items()}
    if args.squeeze is None:  # under the scene's own tilt and hold (a squeeze given is another grasp's)
        for name, slips in slips_under_tilt(scene, args.facets).items():
            objects[name]["under_scene_tilt"] = slips
    return {"scene": scene.name, "objects": objects}


def grasp_text(result: dict[str, Any]) -> str:
    """``pinstab grasp`` without ``--json``: each object's figures as lines a person reads."""
    return "\n".join(_object_grasp_text(name, figures) for name, figures in result["objects"].items())


def _object_grasp_text(name: str, figures: dict[str, Any]) -> str:
    rows, columns = figures["grasp_map_shape"]
    unresisted = figures["unresisted_wrench"]
    closure = "yes" if figures["force_closure"] else f"no (unresisted wrench {np.round(unresisted, 3).tolist()})"
    lines = [
        f"object {name}: {len(figures['contacts'])} contacts "
        + ", ".join(f"{c} ({v['model']})" for c, v in figures["contacts"].items()),
        f"  grasp map G: {rows} x {columns}, rank {figures['grasp_map_rank']}, "
        f"smallest singular value {figures['smallest_singular_value']:.4g}",
        f"  hand Jacobian J_h: {' x '.join(map(str, figures['hand_jacobian_shape']))}, rank "
        f"{figures['hand_jacobian_rank']}, manipulable: {'yes' if figures['manipulable'] else 'no'}",
        f"  force closure: {closure}",
        f"  internal forces: dimension {figures['internal_force_dimension']}",
        f"  quality (Ferrari-Canny, length {figures['quality_length_m']:.4g} m): {figures['quality']:.4g} N",
        *_capacity_text(figures),
    ]
    return "\n".join(lines)


def _capacity_text(figures: dict[str, Any]) -> list[str]:
    """The squeeze the weight needs, the largest load and the tilts, as lines (JSON nulls: none holds)."""
    need = figures["squeeze_needed_n"]
    lines = [
        f"  weight {figures['load_n']:.4g} N: "
        + ("no contact forces inside the cones hold it" if need is None else f"squeeze needed {need:.4g} N per contact")
    ]
    if figures["squeeze_n"] is not None:
        largest = figures["largest_load_n"]
        tilts = ", ".join(
            f"{axis} {'any' if tilt is None else f'{tilt:.4g}'}"
            for axis, tilt in figures["first_slip_tilt_deg"].items()
        )
        lines.append(
            f"  at squeeze {figures['squeeze_n']:.4g} N: largest load "
            + ("unbounded" if largest is None else f"{largest:.4g} N")
            + f"; first slip at tilt [deg] {tilts}"
        )
    slips = figures.get("under_scene_tilt")
    if slips:
        lines.append(
            "  under the scene's [tilt]: "
            + "; ".join(_slip_text(slips, key) for key in _SLIPS if f"{key}_t_s" in slips)
        )
    return lines


_SLIPS = {"first_slip": "the first contact leaves its cone", "hold_lets_go": "its grasp-hold lets go"}


def _slip_text(slips: dict[str, Any], key: str) -> str:
    """One line's part: what happens (``_SLIPS``) at which tilt [deg] and time [s], or never."""
    tilt, time = slips[f"{key}_tilt_deg"], slips[f"{key}_t_s"]
    at = "never" if time is None else f"at {tilt:.7g} deg, t = {time:.7g} s"
    return f"{_SLIPS[key]} {at}"


register(
    Command(
        "grasp",
        "analyse a scene's grasps: grasp map, hand Jacobian, force closure, quality",
        arguments,
        grasp,
        text=grasp_text,
        order=1,
    )
)

"""Grasps: their analysis (grasp map, internal forces, force closure, quality), the hand controllers that
hold or move a grasped object (force kinds ``grasp-hold`` and ``grasp-control``, registered on import),
and the report of a scene's grasps. They use the scene and the dynamics: they sit above them."""

from .analysis import GraspAnalysis, GraspContact, analyse_grasp, grasp_map
from .control import GraspControl
from .hold import GraspHold
from .report import (
    ControlSeries,
    ObjectGrasp,
    analyse_scene_grasps,
    control_series,
    slips_under_tilt,
    tilt_at_first_slip,
)

__all__ = [
    "ControlSeries",
    "GraspAnalysis",
    "GraspContact",
    "GraspControl",
    "GraspHold",
    "ObjectGrasp",
    "analyse_grasp",
    "analyse_scene_grasps",
    "control_series",
    "grasp_map",
    "slips_under_tilt",
    "tilt_at_first_slip",
]

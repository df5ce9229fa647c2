"""Standalone HTML recordings of a trajectory, written headless: meshcat's viewer inlined, the scene
and an animation embedded as meshcat commands. No server, display or browser is needed to write one,
nor a network to open one.

The recording is built by driving Pinocchio's MeshcatVisualizer against a window object that keeps
the commands instead of sending them to a server; the same overlay code serves the live viewer.
Overlays (:class:`Overlay`) draw extra objects per frame — here the loop-closure point pairs,
coloured by their drift; later ones (contact forces, prescribed paths) plug in the same way.
"""

from __future__ import annotations

import base64
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import umsgpack
from meshcat.animation import Animation, AnimationFrameVisualizer
from pinocchio.visualize import MeshcatVisualizer

from ..constraints import FrameClosure
from ..errors import PinstabError
from ..files import atomic_output
from ..model import ConstrainedModel
from ..scene import Scene
from ..trajectory import Trajectory, configurations_at
from .geometry import visual_model

ROOT = "pinstab"
VIEWER_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
# drift colour scale [m]: green at or below the first, red at or above the second (log-interpolated)
DRIFT_GOOD, DRIFT_BAD = 1e-10, 1e-4


class CommandRecorder:
    """A meshcat 'window' that keeps the msgpack-encoded commands it is sent."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        self.commands.append(umsgpack.packb(command.lower()))


def drift_color(drift: float) -> tuple[float, float, float]:
    """Green (small drift) to red (large drift), log scale between DRIFT_GOOD and DRIFT_BAD [m]."""
    if not math.isfinite(drift):
        return (1.0, 0.0, 0.0)
    level = (math.log10(max(drift, 1e-300)) - math.log10(DRIFT_GOOD)) / (math.log10(DRIFT_BAD) - math.log10(DRIFT_GOOD))
    level = min(max(level, 0.0), 1.0)
    return (level, 0.75 * (1.0 - level) + 0.1, 0.1)


class Overlay(Protocol):
    """Extra objects drawn over the robot, updated every frame."""

    def load(self, viewer: meshcat.Visualizer) -> None:
        """Create the objects."""

    def update(self, frame, q: np.ndarray, t: float) -> None:
        """Place them for configuration q at time t [s] (``frame`` is a meshcat node or animation frame)."""


class ClosurePoints:
    """The two points of every frame closure (or the point and its world anchor), as spheres coloured
    by that closure's position residual at the frame: green at 1e-10 m, red at 1e-4 m and above."""

    def __init__(self, model: ConstrainedModel, radius: float) -> None:
        self.model = model
        self.radius = radius
        self.closures = [c for c in model.constraints.constraints if isinstance(c, FrameClosure)]

    def _path(self, name: str, side: str) -> str:
        return f"{ROOT}/closures/{name}/{side}"

    def load(self, viewer) -> None:
        for closure in self.closures:
            for side in ("a", "b"):
                material = mg.MeshLambertMaterial(color=0x22BB33, opacity=0.85, transparent=True)
                viewer[self._path(closure.name, side)].set_object(mg.Sphere(self.radius), material)

    def update(self, frame, q: np.ndarray, t: float) -> None:
        kin = self.model.kin
        kin.update_positions(q)
        for closure in self.closures:
            residual = float(np.max(np.abs(closure.residual(kin, q, t)), initial=0.0))
            color = list(drift_color(residual))
            points = {"a": kin.placement(closure.frame_a).translation}
            points["b"] = (
                closure.world_placement_b if closure.frame_b is None else kin.placement(closure.frame_b)
            ).translation
            for side, point in points.items():
                node = frame[self._path(closure.name, side)]
                node.set_transform(pin.SE3(np.eye(3), point).homogeneous)
                if isinstance(node, AnimationFrameVisualizer):
                    node.set_property("material.color", "color", color)
                else:
                    node.set_property("color", [*color, 0.85])


@dataclass
class Recording:
    """What :func:`write_recording` wrote: file [path], size [bytes], frames and their rate [1/s]."""

    path: Path
    size_bytes: int
    frames: int
    fps: float


class ScenePlayer:
    """The robot of a scene in a meshcat viewer (recording or live), with overlays."""

    def __init__(self, model: ConstrainedModel, viewer: meshcat.Visualizer) -> None:
        scene = model.scene
        self.scene, self.viewer = scene, viewer
        self.robot = MeshcatVisualizer(scene.model, None, visual_model(scene))
        self.robot.initViewer(viewer=viewer)
        self.robot.loadViewerModel(rootNodeName=ROOT)
        self.overlays: list[Overlay] = [ClosurePoints(model, radius=_marker_radius(scene))]
        for overlay in self.overlays:
            overlay.load(viewer)

    def frame_camera(self, states: np.ndarray) -> None:
        """Turn the scene so that its gravity points down in the viewer, and place the camera so that
        the region the joints sweep over ``states`` is in view."""
        gravity = self.scene.model.gravity.linear
        turn = _rotation_onto(
            gravity / np.linalg.norm(gravity) if np.linalg.norm(gravity) > 0 else -np.eye(3)[2], -np.eye(3)[2]
        )
        self.viewer[ROOT].set_transform(pin.SE3(turn, np.zeros(3)).homogeneous)
        data = self.scene.model.createData()
        points = []
        for q in states[:: max(1, len(states) // 50)]:
            pin.forwardKinematics(self.scene.model, data, q)
            points.extend(turn @ placement.translation for placement in data.oMi)
        points = np.array(points)
        low, high = points.min(axis=0), points.max(axis=0)
        centre, extent = (low + high) / 2, max(float(np.max(high - low)), 0.2)
        # the viewer's orbit target stays at the origin; the camera sits in front (-y), a little to the
        # side and above the swept region. Its object lives in three.js's y-up frame: (x, y, z) -> (x, z, -y)
        position = centre + extent * np.array([0.9, -2.2, 0.7])
        self.viewer["/Cameras/default/rotated/<object>"].set_property(
            "position", [position[0], position[2], -position[1]]
        )

    def pose(self, frame, q: np.ndarray, t: float) -> None:
        """Place every visual and overlay for configuration q in ``frame`` (a viewer or an animation frame)."""
        robot = self.robot
        pin.forwardKinematics(robot.model, robot.data, q)
        pin.updateGeometryPlacements(robot.model, robot.data, robot.visual_model, robot.visual_data)
        for index, visual in enumerate(robot.visual_model.geometryObjects):
            transform = robot.visual_data.oMg[index].homogeneous @ np.diag([*visual.meshScale, 1.0])
            frame[robot.getViewerNodeName(visual, pin.GeometryType.VISUAL)].set_transform(transform)
        for overlay in self.overlays:
            overlay.update(frame, q, t)


def _rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a onto unit vector b."""
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis), float(a @ b)
    if sine < 1e-12:
        if cosine > 0:
            return np.eye(3)
        # opposite: half a turn about any axis perpendicular to a
        other = np.eye(3)[int(np.argmin(np.abs(a)))]
        perpendicular = np.cross(a, other) / np.linalg.norm(np.cross(a, other))
        return pin.exp3(np.pi * perpendicular)
    return pin.exp3(axis / sine * math.atan2(sine, cosine))


def _marker_radius(scene: Scene) -> float:
    """Closure markers sized to the mechanism: 2 % of the largest joint-placement distance [m]."""
    spans = [np.linalg.norm(p.translation) for p in scene.model.jointPlacements]
    return max(0.01, 0.02 * max(spans, default=0.5) * 2)


def frame_states(trajectory: Trajectory, model: pin.Model, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Configurations resampled at ``fps`` [1/s] (interpolated on the configuration group)."""
    if not (math.isfinite(fps) and fps > 0):
        raise PinstabError(f"fps must be a positive number, got {fps}")
    times = np.arange(0.0, trajectory.t[-1] + 0.5 / fps, 1.0 / fps)
    times = times[times <= trajectory.t[-1] + 1e-12]
    return times, configurations_at(trajectory.t, trajectory.q, model, times)


def write_recording(model: ConstrainedModel, trajectory: Trajectory, path: str | Path, fps: float = 30.0) -> Recording:
    """Write a standalone HTML file replaying ``trajectory`` of ``model`` at ``fps`` frames per second.

    Opening ``file.html#t=1.5`` shows the motion paused at 1.5 s (used by the browser test).
    """
    scene = model.scene
    times, states = frame_states(trajectory, scene.model, fps)
    recorder = CommandRecorder()
    viewer = meshcat.Visualizer(window=recorder)
    player = ScenePlayer(model, viewer)
    player.frame_camera(states)
    player.pose(viewer, states[0], float(times[0]))
    animation = Animation(default_framerate=fps)
    for index, (t, q) in enumerate(zip(times, states, strict=True)):
        with animation.at_frame(viewer, index) as frame:
            player.pose(frame, q, float(t))
    viewer.set_animation(animation, play=True, repetitions=0)
    html = _page(scene.name, recorder.commands)
    with atomic_output(path, ".html", "recording") as temp:
        Path(temp).write_text(html, encoding="utf-8")
    return Recording(Path(path), Path(path).stat().st_size, len(times), fps)


def _page(title: str, commands: list[bytes]) -> str:
    encoded = ",\n".join(f'"{base64.b64encode(c).decode("ascii")}"' for c in commands)
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>pinstab: {title}</title>
<style>body {{ margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}</style>
</head>
<body>
<div id="meshcat-pane"></div>
<script>
{VIEWER_JS.read_text(encoding="utf-8")}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var commands = [
{encoded}
];
for (const command of commands) {{
  const bytes = Uint8Array.from(atob(command), c => c.charCodeAt(0));
  viewer.handle_command_bytearray(bytes);
}}
const seek = /[#&]t=([0-9.eE+-]+)/.exec(window.location.hash);
if (seek) {{
  viewer.animator.pause();
  viewer.animator.seek(parseFloat(seek[1]));
}}
document.title = "pinstab ready: {title}";
</script>
</body>
</html>
"""


def play_live(model: ConstrainedModel, trajectory: Trajectory, fps: float = 30.0, viewer=None) -> str:
    """Stream the motion of ``model`` in real time to a meshcat server (started on 127.0.0.1 unless
    ``viewer`` is given); returns the viewer's URL."""
    times, states = frame_states(trajectory, model.model, fps)
    if viewer is None:
        viewer = meshcat.Visualizer()
        print(f"pinstab record: live viewer at {viewer.window.web_url}", file=sys.stderr, flush=True)
    player = ScenePlayer(model, viewer)
    player.frame_camera(states)
    start = time.perf_counter()
    for t, q in zip(times, states, strict=True):
        delay = t - (time.perf_counter() - start)
        if delay > 0:
            time.sleep(delay)
        player.pose(viewer, q, float(t))
    return getattr(viewer.window, "web_url", "")

"""Standalone HTML recordings of a trajectory, written headless: meshcat's viewer inlined, the scene
and an animation embedded as meshcat commands. No server, display or browser is needed to write one,
nor a network to open one.

The recording is built by driving Pinocchio's MeshcatVisualizer against a window object that keeps
the commands instead of sending them to a server; the same overlay code serves the live viewer.
Overlays (:class:`Overlay`) draw extra objects per frame — the loop-closure point pairs, coloured by
their drift, and the contact forces with their friction cones (:mod:`pinstab.viz.contacts`); later
ones (prescribed paths) plug in the same way.
"""

from __future__ import annotations

import base64
import contextlib
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import umsgpack
from meshcat.animation import Animation
from pinocchio.visualize import MeshcatVisualizer

from ..constraints import FrameClosure
from ..errors import PinstabError
from ..files import atomic_output
from ..memory import new_data
from ..model import ConstrainedModel
from ..scene import Scene
from ..trajectory import Trajectory, configurations_at
from .contacts import ContactForces
from .geometry import visual_model
from .nodes import ROOT, rotation_onto, set_color, set_pose

VIEWER_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
# drift colour scale [m]: green at or below the first, red at or above the second (log-interpolated)
DRIFT_GOOD, DRIFT_BAD = 1e-10, 1e-4
MIN_EXTENT = 0.1  # [m] the smallest region the camera frames
GRID_MIN_EXTENT = 0.5  # [m] smaller regions hide meshcat's grid (0.5 m cells) and axes, which would cross them
# where the camera sits by default, from the centre of the swept region, in units of its extent: in
# front (-y), a little to the side and above
CAMERA_OFFSET = (0.9, -2.2, 0.7)
LIVE_PAUSE = 1.0  # [s] a live viewer holds the last frame this long before replaying
MAX_FRAMES = 100_000  # frames of a recording (55 min at 30 fps; about 1 kB of HTML each)


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

    OPACITY = 0.85

    def __init__(self, model: ConstrainedModel, radius: float) -> None:
        self.model = model
        self.radius = radius
        self.closures = [c for c in model.constraints.constraints if isinstance(c, FrameClosure)]

    def _path(self, name: str, side: str) -> str:
        return f"{ROOT}/closures/{name}/{side}"

    def load(self, viewer) -> None:
        for closure in self.closures:
            for side in ("a", "b"):
                material = mg.MeshLambertMaterial(color=0x22BB33, opacity=self.OPACITY, transparent=True)
                viewer[self._path(closure.name, side)].set_object(mg.Sphere(self.radius), material)

    def update(self, frame, q: np.ndarray, t: float) -> None:
        kin = self.model.kin
        kin.update_positions(q)
        for closure in self.closures:
            residual = float(np.max(np.abs(closure.residual(kin, q, t)), initial=0.0))
            color = drift_color(residual)
            points = {"a": kin.placement(closure.frame_a).translation}
            points["b"] = (
                closure.world_placement_b if closure.frame_b is None else kin.placement(closure.frame_b)
            ).translation
            for side, point in points.items():
                node = frame[self._path(closure.name, side)]
                set_pose(node, pin.SE3(np.eye(3), point))
                set_color(node, color, self.OPACITY)


@dataclass
class Recording:
    """What :func:`write_recording` wrote: file [path], size [bytes], frames and their rate [1/s], and
    the contact arrows' scale [N/m] (an arrow is ``|f| / force_scale`` long; None without contacts)."""

    path: Path
    size_bytes: int
    frames: int
    fps: float
    force_scale: float | None = None


@dataclass
class Region:
    """Where a motion happens: ``turn`` (rotation putting gravity down in the viewer), and the centre
    [m] and extent [m] (largest side, at least MIN_EXTENT) of the box the joints sweep, turned."""

    turn: np.ndarray
    centre: np.ndarray
    extent: float


def swept_region(model: pin.Model, states: np.ndarray) -> Region:
    """The region the joint origins of ``model`` sweep over ``states`` (50 of them at most)."""
    gravity = model.gravity.linear
    down = -np.eye(3)[2]
    turn = rotation_onto(gravity / np.linalg.norm(gravity) if np.linalg.norm(gravity) > 0 else down, down)
    data = new_data(model)
    points = []
    for q in states[:: max(1, len(states) // 50)]:
        pin.forwardKinematics(model, data, q)
        points.extend(turn @ placement.translation for placement in data.oMi)
    points = np.array(points)
    low, high = points.min(axis=0), points.max(axis=0)
    return Region(turn, (low + high) / 2, max(float(np.max(high - low)), MIN_EXTENT))


class ScenePlayer:
    """The robot of a scene in a meshcat viewer (recording or live), with overlays, for the frames
    ``times`` [s], ``states`` of ``trajectory``."""

    def __init__(
        self,
        model: ConstrainedModel,
        viewer: meshcat.Visualizer,
        trajectory: Trajectory,
        times: np.ndarray,
        states: np.ndarray,
    ) -> None:
        scene = model.scene
        self.scene, self.viewer = scene, viewer
        self.region = swept_region(scene.model, states)
        self.robot = MeshcatVisualizer(scene.model, None, visual_model(scene))
        self.robot.initViewer(viewer=viewer)
        self.robot.loadViewerModel(rootNodeName=ROOT)
        self.forces = ContactForces(model, trajectory, times, self.region.extent)
        self.overlays: list[Overlay] = [ClosurePoints(model, radius=_marker_radius(scene)), self.forces]
        for overlay in self.overlays:
            overlay.load(viewer)

    def frame_camera(self, offset: Sequence[float] = CAMERA_OFFSET) -> None:
        """Turn the scene so that its gravity points down in the viewer, move the centre of the swept
        region to the viewer's orbit target (the origin; grid and axes move along, or hide in a small
        region), and place the camera at ``offset`` from it, in units of the region's extent (turned
        world axes: z up)."""
        region = self.region
        self.viewer[ROOT].set_transform(pin.SE3(region.turn, -region.centre).homogeneous)
        for helper in ("/Grid", "/Axes"):
            self.viewer[helper].set_transform(pin.SE3(np.eye(3), -region.centre).homogeneous)
            if region.extent < GRID_MIN_EXTENT:
                self.viewer[helper].set_property("visible", False)
        # the camera object lives in three.js's y-up frame: (x, y, z) -> (x, z, -y)
        position = region.extent * np.asarray(offset, dtype=float)
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


def _marker_radius(scene: Scene) -> float:
    """Closure markers sized to the mechanism: 2 % of the largest joint-placement distance [m]."""
    spans = [np.linalg.norm(p.translation) for p in scene.model.jointPlacements]
    return max(0.01, 0.02 * max(spans, default=0.5) * 2)


def check_frames(duration: float, fps: float) -> None:
    """Refuse (PinstabError) an ``fps`` [1/s] that is not a positive number, or that makes more than
    :data:`MAX_FRAMES` frames over ``duration`` [s] (checked before the run and again on its samples)."""
    if not (math.isfinite(fps) and fps > 0):
        raise PinstabError(f"fps must be a positive number, got {fps}")
    if not duration * fps < MAX_FRAMES:
        raise PinstabError(
            f"fps {fps:g} over {duration:g} s makes {duration * fps:.3g} frames, more than the {MAX_FRAMES:,} a "
            f"recording holds; use --fps {MAX_FRAMES / duration:.3g} or less (the default is 30), or a shorter run"
        )


def frame_states(trajectory: Trajectory, model: pin.Model, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Configurations resampled at ``fps`` [1/s] (interpolated on the configuration group).

    Raises:
        PinstabError: ``fps`` not a positive number, or more than :data:`MAX_FRAMES` frames.
    """
    check_frames(float(trajectory.t[-1]), fps)
    times = np.arange(0.0, trajectory.t[-1] + 0.5 / fps, 1.0 / fps)
    times = times[times <= trajectory.t[-1] + 1e-12]
    return times, configurations_at(trajectory.t, trajectory.q, model, times)


def write_recording(
    model: ConstrainedModel,
    trajectory: Trajectory,
    path: str | Path,
    fps: float = 30.0,
    camera: Sequence[float] = CAMERA_OFFSET,
) -> Recording:
    """Write a standalone HTML file replaying ``trajectory`` of ``model`` at ``fps`` frames per second,
    seen from ``camera`` (offset from the centre of the motion, in units of its extent, z up).

    Opening ``file.html#t=1.5`` shows the motion paused at 1.5 s (used by the browser test).
    """
    scene = model.scene
    times, states = frame_states(trajectory, scene.model, fps)
    recorder = CommandRecorder()
    viewer = meshcat.Visualizer(window=recorder)
    player = ScenePlayer(model, viewer, trajectory, times, states)
    player.frame_camera(camera)
    player.pose(viewer, states[0], float(times[0]))
    animation = Animation(default_framerate=fps)
    for index, (t, q) in enumerate(zip(times, states, strict=True)):
        with animation.at_frame(viewer, index) as frame:
            player.pose(frame, q, float(t))
    viewer.set_animation(animation, play=True, repetitions=0)
    html = _page(scene.name, recorder.commands)
    with atomic_output(path, ".html", "recording") as temp:
        Path(temp).write_text(html, encoding="utf-8")
    return Recording(Path(path), Path(path).stat().st_size, len(times), fps, player.forces.scale)


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


def live_viewer() -> meshcat.Visualizer:
    """A meshcat viewer whose server this process starts on 127.0.0.1 (it ends with the process); its URL printed on
    stderr."""
    with contextlib.redirect_stdout(sys.stderr):  # meshcat prints its URL on stdout, where --json goes
        viewer = meshcat.Visualizer()
    print(f"pinstab record: live viewer at {viewer.url()}", file=sys.stderr, flush=True)
    return viewer


def play_live(
    model: ConstrainedModel,
    trajectory: Trajectory,
    fps: float = 30.0,
    viewer=None,
    *,
    hold: bool = False,
    pause: float = LIVE_PAUSE,
) -> str:
    """Stream the motion of ``model`` in real time to a meshcat server (started on 127.0.0.1 unless ``viewer`` is
    given; its URL printed on stderr); returns the viewer's URL once the motion has played.

    With ``hold``, it never returns: the motion is replayed, each replay after ``pause`` [s] on its last frame, until
    the process is interrupted (KeyboardInterrupt: Ctrl-C, or SIGTERM under ``pinstab``), so that the viewer's page
    stays served (the server ends with the process).
    """
    times, states = frame_states(trajectory, model.model, fps)
    viewer = live_viewer() if viewer is None else viewer
    player = ScenePlayer(model, viewer, trajectory, times, states)
    player.frame_camera()
    _play(player, viewer, times, states)
    if not hold:
        return getattr(viewer.window, "web_url", "")
    print(f"pinstab record: replaying every {times[-1] + pause:.3g} s until Ctrl-C", file=sys.stderr, flush=True)
    while True:
        time.sleep(pause)
        _play(player, viewer, times, states)


def _play(player: ScenePlayer, viewer, times: np.ndarray, states: np.ndarray) -> None:
    """Pose the frames ``states`` in ``viewer`` at their ``times`` [s] from now, in real time."""
    start = time.perf_counter()
    for t, q in zip(times, states, strict=True):
        delay = t - (time.perf_counter() - start)
        if delay > 0:
            time.sleep(delay)
        player.pose(viewer, q, float(t))

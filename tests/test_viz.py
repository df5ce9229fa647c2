"""Recordings and charts written headless: sizes, frames, units on the axes, errors on bad input; the
contact-force arrows and friction cones measured in the recorded animation."""

from __future__ import annotations

import base64
import json
import math
import re
import signal
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pinocchio as pin
import pytest
import umsgpack

import pinstab
from conftest import interruptible
from pinstab.cli import main
from pinstab.errors import SceneError
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict
from pinstab.trajectory import configurations_at
from pinstab.viz import contacts
from pinstab.viz.geometry import visual_model
from pinstab.viz.plots import trajectory_figure
from pinstab.viz.recording import CommandRecorder, drift_color, frame_states, play_live, swept_region, write_recording

CONTACTS = ("index", "middle", "ring", "thumb")
FPS = 100.0  # frames at 0, 0.01, ..., 0.05 s


def test_record_cli_reports_size_and_frames(capsys, tmp_path):
    out = tmp_path / "fourbar.html"
    assert main(["record", "fourbar", "-o", str(out), "--duration", "1", "--fps", "20", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["frames"] == 21 and result["size_bytes"] == out.stat().st_size
    page = out.read_text()
    assert "MeshCat.Viewer" in page and "pinstab ready: fourbar" in page


def test_panda_anchor_embeds_its_meshes_under_20_mb(capsys, tmp_path):
    out = tmp_path / "panda.html"
    assert main(["record", "panda-anchor", "-o", str(out), "--duration", "2", "--fps", "30", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["frames"] == 61
    assert 5e6 < result["size_bytes"] < 20e6  # the DAE meshes (11 MB) are inside
    assert result["max_position_drift"] < 1e-6


def test_frames_interpolate_on_the_configuration_group():
    scene = pinstab.load_scene("fourbar")
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=0.1)
    times, states = frame_states(trajectory, scene.model, fps=25)
    np.testing.assert_allclose(times, [0.0, 0.04, 0.08])
    np.testing.assert_allclose(states[1], trajectory.q[40], atol=1e-12)


def test_drift_colours_run_from_green_to_red():
    good, bad = drift_color(1e-12), drift_color(1e-2)
    assert good[1] > good[0] and bad[0] > bad[1]
    assert drift_color(float("nan")) == (1.0, 0.0, 0.0)


def test_live_mode_streams_every_frame_to_the_viewer():
    import meshcat

    scene = pinstab.load_scene("fourbar")
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=0.2)
    window = CommandRecorder()
    play_live(ConstrainedModel(scene), trajectory, fps=50, viewer=meshcat.Visualizer(window=window))
    transforms = sum(command.count(b"set_transform") for command in window.commands)
    assert transforms >= 11 * 3  # 11 frames x 3 links at least


@pytest.mark.parametrize(("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_live_record_keeps_serving_after_the_motion_until_interrupted(signum, code):
    """``record --live``: the viewer's page is still served after the 0.2 s motion has played (HTTP 200), the
    figures are on stdout as one JSON object with the URL, and Ctrl-C or SIGTERM ends it with 130 or 143, no
    traceback."""
    argv = ["record", "fourbar", "--live", "--duration", "0.2", "--fps", "10", "--json", "--quiet"]
    process = subprocess.Popen([sys.executable, "-m", "pinstab.cli", *argv], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, preexec_fn=interruptible)  # fmt: skip
    try:
        lines = []
        while not lines or "replaying" not in lines[-1]:  # printed once the motion has played
            lines.append(process.stderr.readline())
            assert lines[-1], f"the command ended early: {''.join(lines)}"
        (url,) = {match for line in lines for match in re.findall(r"live viewer at (\S+)", line)}
        time.sleep(0.5)  # past the motion's end (0.2 s), holding its last frame
        with urllib.request.urlopen(url, timeout=10) as response:
            assert response.status == 200 and b"<html" in response.read().lower()
        assert process.poll() is None
        process.send_signal(signum)
        out, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == code
    assert json.loads(out)["live_url"] == url
    assert "Traceback" not in err and ("interrupted" if signum == signal.SIGINT else "SIGTERM") in err


def test_plot_axes_carry_units(tmp_path):
    trajectory = pinstab.simulate("fourbar", dt=1e-3, duration=0.2)
    figure = trajectory_figure(trajectory)
    labels = [axis.get_ylabel() for axis in figure.axes] + [figure.axes[-1].get_xlabel()]
    for unit in ("[m]", "[m/s]", "[J]", "[N]", "[s]"):
        assert any(unit in label for label in labels), unit
    path = tmp_path / "run.npz"
    trajectory.save(path)
    assert main(["plot", str(path), "-o", str(tmp_path / "drift.png")]) == 0
    assert (tmp_path / "drift.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["record", "fourbar"], "give -o OUT.html"),
        (["record", "fourbar", "-o", "/nonexistent/x.html"], "does not exist"),
        (["record", "fourbar", "-o", "x.png"], "must be a .html file"),
        (["plot", "missing.npz", "-o", "x.png"], "the trajectory file does not exist"),
        (["run", "fourbar", "--plot", "x.svg"], "must be a .png file"),
    ],
)
def test_bad_outputs_are_refused(capsys, argv, message):
    assert main(argv) == 2
    assert message in capsys.readouterr().err


# -- contact forces: the allegro-sphere recording, decoded ------------------------------------------------
@pytest.fixture(scope="module")
def allegro(tmp_path_factory):
    """(scene, model, trajectory, recording, commands) of a 0.05 s allegro-sphere run at dt = 1 ms."""
    scene = pinstab.load_scene("allegro-sphere")
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=0.05)
    model = ConstrainedModel(scene)
    recording = write_recording(model, trajectory, tmp_path_factory.mktemp("allegro") / "allegro.html", fps=FPS)
    return scene, model, trajectory, recording, _commands(recording.path.read_text())


def _commands(page: str) -> list[dict]:
    """The meshcat commands a recording embeds, decoded."""
    start = page.index("var commands = [")
    listing = page[start : page.index("];", start)]
    return [umsgpack.unpackb(base64.b64decode(text)) for text in re.findall(r'"([A-Za-z0-9+/=]+)"', listing)]


def _tracks(commands: list[dict]) -> dict[str, dict[str, list]]:
    """Animation node path -> track name -> its value at every frame."""
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    return {
        item["path"]: {track["name"]: [key["value"] for key in track["keys"]] for track in item["clip"]["tracks"]}
        for item in animation["animations"]
    }


def _node(name: str, part: str) -> str:
    return f"/meshcat/{contacts.ContactForces.path(name, part)}"


def _forces_at(trajectory, name: str, time_s: float) -> np.ndarray:
    """A contact's multipliers at ``time_s`` [s], linear between the samples (np.interp per row)."""
    block = trajectory.multipliers_of(name)
    return np.array([np.interp(time_s, trajectory.t, block[:, row]) for row in range(block.shape[1])])


def test_allegro_recording_draws_the_ball_and_an_arrow_and_a_cone_per_contact(allegro):
    """The ball is a sphere of radius 35 mm; each of the 4 contacts has one shaft, one head and one cone, the
    cone's base radius / height = mu = 0.8 (half-angle atan(mu)); the scale is stated in the result."""
    *_, recording, commands = allegro
    objects = {c["path"]: c["object"]["geometries"][0] for c in commands if c["type"] == "set_object"}
    ball = objects["/meshcat/pinstab/visuals/ball/shape"]
    assert ball["type"] == "SphereGeometry" and ball["radius"] == pytest.approx(0.035, abs=1e-15)
    for part in ("arrow/shaft", "arrow/head", "cone"):
        assert sorted(path for path in objects if path.endswith(part) and "/contacts/" in path) == sorted(
            _node(name, part) for name in CONTACTS
        )
    for name in CONTACTS:
        cone = objects[_node(name, "cone")]
        assert cone["radiusTop"] == 0.0 and cone["radiusBottom"] / cone["height"] == pytest.approx(0.8, abs=1e-12)
    assert recording.frames == 6 and recording.force_scale > 0


def test_arrows_measure_the_trajectory_forces_in_the_contact_frame(allegro):
    """At every frame and contact: arrow length = |f| / force_scale (f the multipliers interpolated at the
    frame time) within 1e-9 m, its direction = R_C f / |f| within 1e-9, its tip at the contact point within
    1e-9 m; the longest arrow of the recording is FORCE_FRACTION x the scene's extent."""
    scene, model, trajectory, recording, commands = allegro
    tracks = _tracks(commands)
    times, states = frame_states(trajectory, scene.model, FPS)
    np.testing.assert_allclose(states, configurations_at(trajectory.t, trajectory.q, scene.model, times))
    constraints = {c.name: c for c in model.constraints.constraints}
    lengths = []
    for frame, (time_s, q) in enumerate(zip(times, states, strict=True)):
        model.kin.update_positions(q)
        for name in CONTACTS:
            force = _forces_at(trajectory, name, float(time_s))
            contact = model.kin.placement(constraints[name].object_frame)
            arrow, shaft = tracks[_node(name, "arrow")], tracks[_node(name, "arrow/shaft")]
            length = -(shaft[".position"][frame][1] - shaft[".scale"][frame][1] / 2)  # tail below the tip
            assert abs(length - np.linalg.norm(force) / recording.force_scale) < 1e-9
            x, y, z, w = arrow[".quaternion"][frame]
            direction = pin.Quaternion(w, x, y, z).toRotationMatrix()[:, 1]
            assert np.abs(direction - contact.rotation @ force / np.linalg.norm(force)).max() < 1e-9
            assert np.abs(np.array(arrow[".position"][frame]) - contact.translation).max() < 1e-9
            lengths.append(length)
    extent = swept_region(scene.model, states).extent
    assert max(lengths) == pytest.approx(contacts.FORCE_FRACTION * extent, abs=1e-9)


def test_a_contact_inside_its_cone_at_the_start_is_coloured_inside(allegro):
    """At t = 0 every contact force is inside its friction cone (margins > 0, |f_t| / (mu f_n) < 1) and its
    arrow has the colour of that usage: green-dominant, not the outside red."""
    _, model, trajectory, _, commands = allegro
    tracks = _tracks(commands)
    constraints = {c.name: c for c in model.constraints.constraints}
    for name in CONTACTS:
        force = _forces_at(trajectory, name, 0.0)
        assert min(constraints[name].margins(force).values()) > 0
        usage = math.hypot(force[0], force[1]) / (0.8 * force[2])
        color = tracks[f"{_node(name, 'arrow/shaft')}/<object>"][".material.color"][0]
        assert usage < 1 and np.abs(np.array(color) - contacts.usage_color(usage)).max() < 1e-12
        assert color[1] > color[0] + 0.2 and tuple(color) != contacts.RED


def test_usage_colours_turn_red_outside_the_cone_or_pulling(allegro):
    """Green along the normal, amber on the cone, red past it, pulling or unknown; a grasp contact's usage
    is |f_t| / (mu f_n), infinite when it pulls."""
    _, model, *_ = allegro
    view = contacts.GraspView(model.constraints.constraints[0])
    assert view.usage(np.array([0.3, 0.4, 1.0])) == pytest.approx(0.5 / 0.8, abs=1e-15)
    assert view.usage(np.array([0.0, 0.0, -1.0])) == math.inf
    assert contacts.usage_color(0.0) == pytest.approx(tuple(contacts.GREEN), abs=1e-15)
    assert contacts.usage_color(1.0) == pytest.approx(tuple(contacts.AMBER), abs=1e-15)
    for usage in (1.01, math.inf, math.nan):
        assert contacts.usage_color(usage) == contacts.RED


def test_plane_contacts_get_arrows_along_their_multipliers(tmp_path):
    """box-push held as rows: each plane contact's arrow is (t1, t2, n) force rows of length |f| / force_scale
    (1e-9 m), pointing along the plane's push (+z mostly) at the first frame."""
    scene = pinstab.load_scene("box-push")
    trajectory = pinstab.simulate(scene, contacts="held", dt=1e-3, duration=0.02)
    recording = write_recording(ConstrainedModel(scene), trajectory, tmp_path / "box.html", fps=FPS)
    tracks = _tracks(_commands(recording.path.read_text()))
    for name in ("front-left", "front-right", "back-left", "back-right"):
        force = trajectory.multipliers_of(name)[0]  # (n, t1, t2) force on the box
        shaft = tracks[_node(name, "arrow/shaft")]
        length = -(shaft[".position"][0][1] - shaft[".scale"][0][1] / 2)
        assert abs(length - np.linalg.norm(force) / recording.force_scale) < 1e-9
        x, y, z, w = tracks[_node(name, "arrow")][".quaternion"][0]
        assert pin.Quaternion(w, x, y, z).toRotationMatrix()[2, 1] > 0.99  # pushed up by the table


def test_visual_model_adds_the_objects_and_finds_package_meshes_of_urdf_text(tmp_path):
    """The ball's visual is in the geometry model on the ball's joint; a URDF given as text finds its
    package:// mesh through scene.package_dirs (SceneError naming the mesh without them)."""
    scene = pinstab.load_scene("allegro-sphere")
    (ball,) = [g for g in visual_model(scene).geometryObjects if g.name == "ball/shape"]
    assert ball.parentJoint == scene.objects[0].joint and ball.geometry.radius == 0.035
    (tmp_path / "tinypkg").mkdir()
    (tmp_path / "tinypkg" / "tri.stl").write_text(
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
        "endfacet\nendsolid t\n"
    )
    urdf = (
        "<robot name='r'><link name='base'><inertial><mass value='1'/><inertia ixx='1' iyy='1' izz='1' ixy='0' "
        "ixz='0' iyz='0'/></inertial><visual><geometry><mesh filename='package://tinypkg/tri.stl'/></geometry>"
        "</visual></link></robot>"
    )
    scene = scene_from_dict({"robot": {"urdf_text": urdf, "free_flyer": True}})
    scene.package_dirs = []
    with pytest.raises(SceneError, match="package://tinypkg/tri.stl"):
        visual_model(scene)
    scene.package_dirs = [str(tmp_path)]
    (mesh,) = visual_model(scene).geometryObjects
    assert mesh.meshPath == str(tmp_path / "tinypkg" / "tri.stl")


# -- contact modes: event-driven runs, decoded ---------------------------------------------------------------
def _event_recording(tmp_path, name: str, fps: float, **parameters):
    """(scene, trajectory, recording, tracks, objects, frame times, frame states) of an event-driven run."""
    scene = pinstab.load_scene(name, **parameters)
    trajectory = pinstab.simulate(scene, dt=0.01, duration=2.0 if name == "bouncing-ball" else 0.5, contacts="event")
    recording = write_recording(ConstrainedModel(scene), trajectory, tmp_path / f"{name}.html", fps=fps)
    commands = _commands(recording.path.read_text())
    objects = {c["path"]: c["object"]["geometries"][0] for c in commands if c["type"] == "set_object"}
    return scene, trajectory, recording, _tracks(commands), objects, *frame_states(trajectory, scene.model, fps)


def _arrow_length(tracks, name: str, frame: int) -> float:
    """[m] from the tip to the shaft's tail (a shaft of TINY length, shorter arrows' head only, counts as 0)."""
    shaft = tracks[_node(name, "arrow/shaft")]
    scale = shaft[".scale"][frame][1]
    return -shaft[".position"][frame][1] + (scale if scale > contacts.TINY else 0.0) / 2


def test_incline_slide_recording_shows_sliding_points_and_arrows_at_the_weight_scale(tmp_path):
    """Sliding incline (theta = 0.5, mu = 0.3), 6 frames: every corner's point and arrow take the sliding
    colour; the scale is m g / (FORCE_FRACTION x extent) [N/m]; each arrow points along (-mu, 0, 1) / |.|
    (friction against the slip down +x) with its tip at the corner (Pinocchio's frame placement), and the
    arrows' lengths sum to m g cos theta sqrt(1 + mu^2) / scale (1e-9 m); the cones have radius / height = mu
    and the points a sphere of POINT_RADIUS x the longest arrow."""
    theta, mu, weight = 0.5, 0.3, 9.81
    scene, _, recording, tracks, objects, times, states = _event_recording(
        tmp_path, "incline", 10.0, theta=theta, mu=mu
    )
    longest = contacts.FORCE_FRACTION * swept_region(scene.model, states).extent
    assert recording.frames == 6 and recording.force_scale == pytest.approx(weight / longest, rel=1e-12)
    names = [c.name for c in scene.constraints]
    sliding = contacts.MODE_COLORS["sliding"]
    along = np.array([-mu, 0.0, 1.0]) / math.hypot(mu, 1.0)
    data = scene.model.createData()
    for name in names:
        cone, point = objects[_node(name, "cone")], objects[_node(name, "point")]
        assert cone["radiusBottom"] / cone["height"] == pytest.approx(mu, abs=1e-12)
        assert point["type"] == "SphereGeometry" and point["radius"] == pytest.approx(contacts.POINT_RADIUS * longest)
    for frame, q in enumerate(states):
        pin.framesForwardKinematics(scene.model, data, q)
        total = 0.0
        for contact in scene.constraints:
            name = contact.name
            for part in ("point", "arrow/shaft", "arrow/head"):
                assert tracks[f"{_node(name, part)}/<object>"][".material.color"][frame] == pytest.approx(sliding)
            corner = data.oMf[contact.frame_a].translation
            assert np.abs(np.array(tracks[_node(name, "point")][".position"][frame]) - corner).max() < 1e-9
            assert np.abs(np.array(tracks[_node(name, "arrow")][".position"][frame]) - corner).max() < 1e-9
            x, y, z, w = tracks[_node(name, "arrow")][".quaternion"][frame]
            assert np.abs(pin.Quaternion(w, x, y, z).toRotationMatrix()[:, 1] - along).max() < 1e-9
            total += _arrow_length(tracks, name, frame)
        expected = weight * math.cos(theta) * math.hypot(1.0, mu) / recording.force_scale
        assert abs(total - expected) < 1e-9


def test_bouncing_ball_recording_turns_from_separated_to_sticking_at_rest(tmp_path):
    """Bouncing ball (h = 1 m, e = 0.5), 11 frames over 2 s: grey (separated) with a zero-length arrow before
    the rest time t0 (1 + e) / (1 - e) = 1.355 s, blue (sticking) with an arrow of m g (FORCE_FRACTION x the
    extent, 1e-9 m) after it; the point at the ball's lowest point, z = centre - 0.05 m."""
    scene, trajectory, recording, tracks, _, times, states = _event_recording(tmp_path, "bouncing-ball", 5.0)
    rest = math.sqrt(2 / 9.81) * 3
    longest = contacts.FORCE_FRACTION * swept_region(scene.model, states).extent
    node = _node("ground", "point")
    for frame, (time_s, q) in enumerate(zip(times, states, strict=True)):
        mode = "separated" if time_s < rest else "sticking"
        assert tracks[f"{node}/<object>"][".material.color"][frame] == pytest.approx(contacts.MODE_COLORS[mode])
        assert tracks[node][".position"][frame] == pytest.approx([*q[:2], q[2] - 0.05], abs=1e-12)
        length = _arrow_length(tracks, "ground", frame)
        assert abs(length - (0.0 if time_s < rest else longest)) < 1e-9, (time_s, length)
    assert sum(times > rest) == 4  # 1.4, 1.6, 1.8, 2 s


def test_plot_of_an_event_run_draws_the_mode_spans_and_the_closed_form_forces(tmp_path):
    """sphere-spin (v0 = 2, omega0 = 5, mu = 0.3, r = 0.1): the mode bar is two spans whose ends are the
    events' times exactly (sliding from 0 to the rolling event, sticking from it to 1 s) in the mode
    colours; the normal force is m g (1e-12 relative) and the friction force mu m g before
    t* = 2 (v0 + r omega0) / (7 mu g), 0 after it. Saved and plotted by ``pinstab plot`` (the bundled scene
    reloaded by name); without a loadable scene the forces are those of the events."""
    mu, weight = 0.3, 9.81
    run = pinstab.simulate("sphere-spin", dt=0.01, duration=1.0, contacts="event")
    figure = trajectory_figure(run)
    force_axis, mode_axis = figure.axes[2], figure.axes[-1]
    (rolling,) = [e["t"] for e in run.info.contact_events if e["to"] == "sticking"]
    bars = [(bar.get_x(), bar.get_x() + bar.get_width(), tuple(bar.get_facecolor()[:3])) for bar in mode_axis.patches]
    assert bars == [(0.0, rolling, contacts.MODE_COLORS["sliding"]), (rolling, 1.0, contacts.MODE_COLORS["sticking"])]
    lines = {line.get_label(): line for line in force_axis.get_lines()}
    np.testing.assert_allclose(lines["ground normal"].get_ydata(), weight, rtol=1e-12)
    t_star = 2 * (2.0 + 0.1 * 5.0) / (7 * mu * weight)
    expected = np.where(run.t < t_star, mu * weight, 0.0)
    np.testing.assert_allclose(lines["ground friction"].get_ydata(), expected, atol=1e-12)
    path = tmp_path / "spin.npz"
    run.save(path)
    assert main(["plot", str(path), "-o", str(tmp_path / "spin.png")]) == 0
    run.info.scene = "not-bundled"
    force_axis = trajectory_figure(run).axes[2]
    assert force_axis.get_ylabel() == "contact force at the events [N]"
    times = [e["t"] for e in run.info.contact_events]
    assert list(force_axis.get_lines()[0].get_xdata()) == times


def test_plot_marks_the_bouncing_balls_impacts_at_the_event_times():
    run = pinstab.simulate("bouncing-ball", dt=0.01, duration=2.0, contacts="event")
    mode_axis = trajectory_figure(run).axes[-1]
    (marks,) = [line for line in mode_axis.get_lines() if line.get_marker() == "v"]  # the rest: event markers
    assert list(marks.get_xdata()) == [e["t"] for e in run.info.contact_events if e["to"] == "closing"]
    (rest,) = [e["t"] for e in run.info.contact_events if e["to"] == "sticking"]
    assert [(bar.get_x(), bar.get_x() + bar.get_width()) for bar in mode_axis.patches] == [(0.0, rest), (rest, 2.0)]

"""Recordings and charts written headless: sizes, frames, units on the axes, errors on bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pinstab
from pinstab.cli import main
from pinstab.model import ConstrainedModel
from pinstab.viz.plots import trajectory_figure
from pinstab.viz.recording import CommandRecorder, drift_color, frame_states, play_live


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
        (["plot", "missing.npz", "-o", "x.png"], "not a pinstab trajectory file"),
        (["run", "fourbar", "--plot", "x.svg"], "must be a .png file"),
    ],
)
def test_bad_outputs_are_refused(capsys, argv, message):
    assert main(argv) == 2
    assert message in capsys.readouterr().err

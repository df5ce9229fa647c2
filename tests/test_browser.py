"""A recording opened in a real browser, offline: every command runs without a console message, the canvas
shows the scene (the four-bar's links; the Allegro hand's ball and contact-force arrows) and the motion moves.

Needs headless Chromium (Debian package ``chromium``, installed by .ci/run); skipped without it.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.image import imread

import pinstab
from pinstab.model import ConstrainedModel
from pinstab.viz.browser import chromium, open_page, screenshot
from pinstab.viz.recording import write_recording

ALLEGRO_CAMERA = (1.3, -0.3, 0.65)  # in front of the palm, as docs/recording-allegro-sphere.png
# meshcat's viewer warns once per mesh that pinocchio's mesh-file format is deprecated
MESH_WARNING = "_meshfile is deprecated"

pytestmark = pytest.mark.skipif(chromium() is None, reason="headless Chromium not installed (apt-get install chromium)")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    scene = pinstab.load_scene("fourbar")
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=1.0)
    path = tmp_path_factory.mktemp("recording") / "fourbar.html"
    return write_recording(ConstrainedModel(scene), trajectory, path, fps=30)


def test_recording_is_self_contained(recording):
    page = recording.path.read_text()
    assert recording.frames == 31
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=", page)  # viewer and scene inlined


def test_two_animation_times_render_different_nonblank_frames(recording, tmp_path):
    early = imread(screenshot(recording.path, tmp_path / "early.png", 0.1))[..., :3]
    late = imread(screenshot(recording.path, tmp_path / "late.png", 0.7))[..., :3]
    for image in (early, late):
        red, green, blue = image[..., 0], image[..., 1], image[..., 2]
        # the background is a blue gradient: the red crank and the green rocker must show on it
        assert np.count_nonzero((red > green + 0.15) & (red > blue + 0.15)) > 20
        assert np.count_nonzero((green > red + 0.15) & (green > blue + 0.05)) > 20
    changed = np.abs(early - late).max(axis=2) > 0.1
    assert changed.sum() > 200  # the linkage moved between the two frames


def test_recording_runs_without_console_messages(recording):
    """Every command applied: the title is set after the last one, nothing reached the console (the drift
    colour tracks bind to the closure spheres' materials)."""
    page = open_page(recording.path, 0.3)
    assert page.title == "pinstab ready: fourbar" and page.console == []


@pytest.fixture(scope="module")
def allegro(tmp_path_factory):
    scene = pinstab.load_scene("allegro-sphere")
    trajectory = pinstab.simulate(scene, dt=1e-3, duration=0.2)
    path = tmp_path_factory.mktemp("recording") / "allegro.html"
    return write_recording(ConstrainedModel(scene), trajectory, path, fps=30, camera=ALLEGRO_CAMERA)


def test_allegro_recording_draws_the_ball_and_the_force_arrows(allegro, tmp_path):
    """No console message but the meshes' deprecation warning; the orange ball (> 5000 px) and the green
    arrows (> 1000 px, drawn over the fingertips) show on the canvas."""
    page = open_page(allegro.path, 0.1)
    assert page.title == "pinstab ready: allegro-sphere"
    assert [message for message in page.console if not message.startswith(MESH_WARNING)] == []
    image = imread(screenshot(allegro.path, tmp_path / "allegro.png", 0.1))[..., :3]
    red, green, blue = image[..., 0], image[..., 1], image[..., 2]
    assert np.count_nonzero((red > 0.7) & (green > 0.25) & (green < 0.6) & (blue < 0.2)) > 5000
    assert np.count_nonzero((green > red + 0.3) & (green > blue + 0.3)) > 1000

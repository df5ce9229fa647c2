"""A recording opened in a real browser, offline: the canvas shows the scene and the motion moves.

Needs headless Chromium (Debian package ``chromium``, installed by .ci/run); skipped without it.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.image import imread

import pinstab
from pinstab.model import ConstrainedModel
from pinstab.viz.browser import chromium, screenshot
from pinstab.viz.recording import write_recording

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

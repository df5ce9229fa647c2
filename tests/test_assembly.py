"""Assembly: closed configurations from inconsistent guesses, clear failure when lengths cannot close."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROBOTS
from pinstab import AssemblyError, ConstrainedModel, assemble, load_scene
from pinstab.scene import scene_from_dict


def coupler_gap(q):
    """Independent geometry of the bundled four-bar: distance between coupler tip and rocker tip [m]."""
    crank, coupler, rocker = q
    tip = 0.2 * np.array([np.cos(crank), np.sin(crank)]) + 0.6 * np.array(
        [np.cos(crank + coupler), np.sin(crank + coupler)]
    )
    rocker_tip = np.array([0.6, 0.0]) + 0.5 * np.array([np.cos(rocker), np.sin(rocker)])
    return np.linalg.norm(tip - rocker_tip)


def test_fourbar_assembles_from_its_guess():
    scene = load_scene("fourbar")
    system = ConstrainedModel(scene)
    assert coupler_gap(scene.q0) > 1e-2
    report = assemble(system, scene.q0, scene.v0)
    assert coupler_gap(report.q) < 1e-12
    assert report.residual < 1e-12 and report.velocity_residual < 1e-12
    assert 0 < report.iterations < 20


def test_a_closed_configuration_is_left_alone():
    scene = load_scene("fourbar")
    system = ConstrainedModel(scene)
    closed = assemble(system, scene.q0, scene.v0)
    again = assemble(system, closed.q, closed.v)
    assert again.iterations == 0
    np.testing.assert_allclose(again.q, closed.q, atol=0)
    np.testing.assert_allclose(again.v, closed.v, atol=1e-14)


@pytest.mark.parametrize("name", ["slider-crank", "fivebar", "delta", "nfourbar", "box-push", "bricard"])
def test_bundled_scenes_assemble(name):
    scene = load_scene(name)
    report = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    assert report.residual < 1e-12
    assert report.velocity_residual < 1e-10


def test_lengths_that_cannot_close_raise_with_the_residual():
    data = {
        "robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
        "closures": [
            {
                "name": "too-long",
                "kind": "planar-point",
                "plane": "xy",
                "frame_a": "coupler",
                "offset_a": [2.0, 0, 0],
                "frame_b": "rocker",
                "offset_b": [0.5, 0, 0],
            }
        ],
    }
    scene = scene_from_dict(data)
    with pytest.raises(AssemblyError, match="too-long") as info:
        assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    # the best the linkage can do: coupler 2 m from B, rocker 0.5 m from D, |BD| <= 0.8 m -> gap >= 0.7 m
    assert info.value.residual > 0.4

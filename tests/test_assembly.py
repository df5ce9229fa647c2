"""Assembly: closed configurations from inconsistent guesses, clear failure when lengths cannot close."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import ROBOTS, kicked_cassie, pinocchio_closure_residuals
from pinstab import AssemblyError, ConstrainedModel, SceneError, assemble, load_scene, simulate
from pinstab.assembly import DEFAULT_TOLERANCE, mechanism_size
from pinstab.cli import main
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


TOO_LONG = {  # the bundled four-bar's closure with its coupler 2 m long: no configuration closes it
    "name": "too-long",
    "kind": "planar-point",
    "plane": "xy",
    "frame_a": "coupler",
    "offset_a": [2.0, 0, 0],
    "frame_b": "rocker",
    "offset_b": [0.5, 0, 0],
}


def test_lengths_that_cannot_close_raise_with_the_residual():
    data = {"robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")}, "closures": [TOO_LONG]}
    scene = scene_from_dict(data)
    with pytest.raises(AssemblyError, match="too-long") as info:
        assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    # the best the linkage can do: coupler 2 m from B, rocker 0.5 m from D, |BD| <= 0.8 m -> gap >= 0.7 m
    assert info.value.residual > 0.4


def fourbar_out_of_plane(gap: float, tolerance: float | None = None) -> dict:
    """The bundled four-bar closed by a 3-row point closure whose offset is off by ``gap`` [m] along z, out of
    the plane of its joints' motion: no configuration closes the z row, whose residual is ``gap`` exactly."""
    data = {
        "robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
        "closures": [
            {
                "name": "coupler-rocker",
                "kind": "point",
                "frame_a": "coupler",
                "offset_a": [0.6, 0.0, 0.0],
                "frame_b": "rocker",
                "offset_b": [0.5, 0.0, gap],
            }
        ],
        "initial": {"q": {"crank": 1.0, "coupler": -0.9, "rocker": 1.6}},
    }
    if tolerance is not None:
        data["assembly"] = {"tolerance": tolerance}
    return data


def test_the_mechanism_size_is_the_diagonal_of_its_joints_and_frames():
    scene = load_scene("fourbar")
    model = ConstrainedModel(scene)
    q = assemble(model, scene.q0, scene.v0).q
    crank, coupler, _ = q
    # joints and frames in the plane: ground pins A (0, 0) and D (0.6, 0), crank tip B, coupler tip C (= rocker tip)
    b = 0.2 * np.array([np.cos(crank), np.sin(crank)])
    c = b + 0.6 * np.array([np.cos(crank + coupler), np.sin(crank + coupler)])
    points = np.array([[0.0, 0.0], [0.6, 0.0], b, c])
    expected = np.linalg.norm(points.max(axis=0) - points.min(axis=0))
    assert mechanism_size(model, q) == pytest.approx(expected, rel=1e-12)


def test_a_loop_closed_to_2e_11_assembles_with_the_default_tolerance():
    gap = 2e-11
    scene = scene_from_dict(fourbar_out_of_plane(gap))
    model = ConstrainedModel(scene)
    report = assemble(model, scene.q0, scene.v0)
    assert report.residual == pytest.approx(gap, rel=1e-4)  # the z row, which no configuration changes
    assert coupler_gap(report.q) < 1e-12  # in the plane the loop closes to rounding
    assert report.tolerance == pytest.approx(DEFAULT_TOLERANCE * mechanism_size(model, scene.q0), rel=1e-12)
    assert report.residual < report.tolerance
    # a run reports the residual and the tolerance (without stabilization: a gain on the z row, which no
    # acceleration changes, would make the rows inconsistent)
    trajectory = simulate(scene, method="none", duration=0.01)
    assert trajectory.summary()["assembly_residual"] == pytest.approx(gap, rel=1e-4)
    assert trajectory.summary()["assembly_tolerance"] == pytest.approx(report.tolerance, rel=1e-12)


@pytest.mark.parametrize("where", ["scene", "argument", "simulate"])
def test_a_residual_above_the_tolerance_names_the_closure_residual_and_tolerance(where):
    gap, tolerance = 2e-11, 1e-12
    scene = scene_from_dict(fourbar_out_of_plane(gap, tolerance if where == "scene" else None))
    model = ConstrainedModel(scene)
    accepted = tolerance * mechanism_size(model, scene.q0)
    with pytest.raises(AssemblyError, match="coupler-rocker") as info:
        if where == "simulate":
            simulate(scene, method="none", duration=0.01, assembly_tol=tolerance)
        else:
            assemble(model, scene.q0, scene.v0, tolerance=tolerance if where == "argument" else None)
    assert info.value.residual == pytest.approx(gap, rel=1e-4)
    assert f"residual {info.value.residual:.3g}" in str(info.value)
    assert f"tolerance {accepted:.3g}" in str(info.value)


@pytest.mark.parametrize("value", [-1e-10, 0.0, float("nan"), float("inf"), 1.0, True, "1e-10"])
def test_bad_assembly_tolerances_are_refused_by_name(value):
    with pytest.raises(SceneError, match=r"assembly\.tolerance must be a relative tolerance"):
        scene_from_dict(fourbar_out_of_plane(0.0, value))
    scene = load_scene("fourbar")
    with pytest.raises(SceneError, match="assembly tolerance must be"):
        assemble(ConstrainedModel(scene), scene.q0, scene.v0, tolerance=value)
    with pytest.raises(SceneError, match="assembly_tol must be"):
        simulate(scene, duration=0.01, assembly_tol=value)


def test_the_assembly_table_takes_only_a_tolerance():
    data = fourbar_out_of_plane(0.0)
    data["assembly"] = {"tolerence": 1e-9}
    with pytest.raises(SceneError, match="unknown key 'tolerence'; valid keys: tolerance"):
        scene_from_dict(data)


def test_check_takes_the_tolerance_and_reports_it(tmp_path, capsys):
    urdf = ROBOTS / "urdf" / "fourbar.urdf"
    (tmp_path / "gap.toml").write_text(
        f'[robot]\nurdf = "{urdf}"\n[[closures]]\nname = "coupler-rocker"\nkind = "point"\nframe_a = "coupler"\n'
        'offset_a = [0.6, 0.0, 0.0]\nframe_b = "rocker"\noffset_b = [0.5, 0.0, 2e-11]\n'
        "[initial]\nq = { crank = 1.0, coupler = -0.9, rocker = 1.6 }\n"
    )
    assert main(["check", str(tmp_path / "gap.toml"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["assembly_residual"] == pytest.approx(2e-11, rel=1e-4)
    assert result["assembly_tolerance"] == pytest.approx(DEFAULT_TOLERANCE * result["mechanism_size"], rel=1e-12)
    assert main(["check", str(tmp_path / "gap.toml"), "--assembly-tol", "1e-12"]) == 2
    assert "largest on closure 'coupler-rocker'" in capsys.readouterr().err
    assert main(["check", str(tmp_path / "gap.toml"), "--assembly-tol", "-1"]) == 2
    assert "--assembly-tol must be a relative tolerance" in capsys.readouterr().err


def test_a_start_on_near_singular_closures_keeps_no_velocity_residual():
    """Cassie with its left knee motor kicked to 1 rad/s (benchmarks/cassie_implicit.py): its shin and heel-spring
    closures are near-singular at the start (the square root of G M^-1 G^T has singular values down to 9e-9 of its
    largest, which G M^-1 G^T's pseudo-inverse drops), so the start's velocity projection is refined: Pinocchio's frame
    velocities of every closure and the gearbox relations vanish to 1e-12 of the largest joint velocity (before: 5e-6
    m/s, 6e-7 of it)."""
    system = ConstrainedModel(kicked_cassie())
    report = assemble(system, system.scene.q0, system.scene.v0)
    phi, residual = pinocchio_closure_residuals(system, report.q, report.v)
    assert len(residual) == system.constraints.rows
    assert np.abs(phi).max() <= 1e-14
    assert np.abs(residual).max() <= 1e-12 * np.abs(report.v).max()
    assert report.velocity_residual <= 1e-12 * np.abs(report.v).max()

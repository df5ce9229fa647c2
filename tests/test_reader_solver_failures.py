"""Reader and KKT-solver failures the reader fuzzer found (issue 34): an SDF inertia a rounding below positive
semidefinite that Pinocchio refused with a raw RuntimeError, and a redundant SDF closure whose run failed mid-way
with exit 2 (bad input) and, repeated in one process, alternated between two outcomes."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from fuzzing import cli
from test_fuzz_readers import REDUNDANT_SDF

import pinstab
from pinstab.errors import SceneError
from pinstab.readers import example_robot_data_dir, sdf_tree
from pinstab.readers.inertia import INERTIA_TOLERANCE, rotated
from pinstab.scene import scene_from_dict

CASSIE = (
    None if example_robot_data_dir() is None else example_robot_data_dir() / "cassie_description/robots/cassie_v2.sdf"
)


def _scene(folder: Path, sdf: str, free_flyer: bool = False) -> Path:
    (folder / "robot.sdf").write_text(sdf, encoding="utf-8")
    scene = folder / "scene.toml"
    scene.write_text(
        f'gravity = [0.0, 0.0, -9.81]\n[robot]\nsdf = "robot.sdf"\nfree_flyer = {str(free_flyer).lower()}\n',
        encoding="utf-8",
    )
    return scene


# -- an inertia a rounding below positive semidefinite -------------------------------------------------------------
@pytest.mark.skipif(CASSIE is None or not CASSIE.is_file(), reason="example-robot-data's Cassie is not installed")
@pytest.mark.parametrize("ixx", ["0", "1e-300"])
def test_cassie_rod_with_no_ixx_is_named(tmp_path: Path, ixx: str) -> None:
    """Cassie's 'left-plantar-rod' with ixx = 0 beside ixy = -2.34e-8, ixz = -8.1e-9, iyy = 1.774e-3: its smallest
    principal moment is about -ixy^2 / iyy - ixz^2 / izz = -3.46e-13 kg m^2 (2e-10 of the largest, beyond a
    rounding): refused by name, where Pinocchio ended ``pinstab check`` with "The 3d inertia should be positive."."""
    root = ET.parse(CASSIE).getroot()
    link = next(link for link in root.iter("link") if link.get("name") == "left-plantar-rod")
    link.find("inertial/inertia/ixx").text = ixx
    outcome = cli(["check", str(_scene(tmp_path, ET.tostring(root, encoding="unicode")))])
    expected = -(2.34e-8**2) / 1.774e-3 - 8.1e-9**2 / 1.775e-3  # second-order perturbation of the zero moment
    assert outcome.code == 2, outcome
    assert "robot.sdf" in outcome.message and "sdf link 'left-plantar-rod'" in outcome.message, outcome
    assert "not positive semidefinite" in outcome.message and "ixy -2.34e-08" in outcome.message, outcome
    smallest = float(outcome.message.split("principal moments [")[1].split(",")[0])
    assert smallest == pytest.approx(expected, rel=1e-4)


@pytest.mark.skipif(CASSIE is None or not CASSIE.is_file(), reason="example-robot-data's Cassie is not installed")
def test_cassie_loads_with_the_same_inertias(monkeypatch: pytest.MonkeyPatch) -> None:
    """Cassie's SDF as published loads; its bodies' inertias through :func:`rotated` are the plain R I R^T's to a
    rounding (1e-14 of each body's largest entry: the eigendecomposition's few dozen roundings; measured 1.4e-15)."""
    robot = {"robot": {"sdf": str(CASSIE), "free_flyer": False}}
    ours = scene_from_dict(robot, name="cassie").model
    monkeypatch.setattr(sdf_tree, "rotated", lambda inertia, rotation: rotation @ inertia @ rotation.T)
    plain = scene_from_dict(robot, name="cassie").model
    assert ours.njoints == plain.njoints > 20
    for mine, theirs in zip(ours.inertias, plain.inertias, strict=True):
        assert mine.mass == theirs.mass and np.array_equal(mine.lever, theirs.lever)
        scale = np.abs(theirs.inertia).max()
        assert np.abs(mine.inertia - theirs.inertia).max() <= 1e-14 * scale


def _pendulum(smallest: float) -> str:
    """A link on a revolute joint (axis y, 0.5 m from its centre of mass) whose inertia has principal moments
    (smallest, 1, 1) kg m^2 about turned axes."""
    return (
        "<sdf version='1.6'><model name='m'><link name='base'><inertial><mass>1</mass></inertial></link>"
        "<link name='rod'><inertial><pose>0.5 0 0 0.3 -0.7 1.1</pose><mass>1</mass>"
        f"<inertia><ixx>{smallest!r}</ixx><iyy>1</iyy><izz>1</izz></inertia></inertial></link>"
        "<joint name='j' type='revolute'><parent>base</parent><child>rod</child><axis><xyz>0 1 0</xyz></axis></joint>"
        "</model></sdf>"
    )


def test_the_inertia_tolerance_boundary(tmp_path: Path) -> None:
    """A smallest moment of -INERTIA_TOLERANCE x the largest (a rounding) loads as the nearest inertia (moments
    0, 1, 1 in the turned frame Pinocchio gets) and runs; a little below it is refused by name."""
    robot = {"sdf": str(tmp_path / "m.sdf"), "free_flyer": False}
    (tmp_path / "m.sdf").write_text(_pendulum(-INERTIA_TOLERANCE), encoding="utf-8")
    scene = scene_from_dict({"gravity": [0.0, 0.0, -9.81], "robot": robot}, name="edge")
    body = scene.model.inertias[1]
    assert np.linalg.eigvalsh(body.inertia) == pytest.approx([0.0, 1.0, 1.0], abs=1e-15)
    assert body.mass == 1.0 and body.lever == pytest.approx([0.5, 0.0, 0.0])
    result = pinstab.simulate(scene, duration=0.01)
    assert np.isfinite(result.q).all() and result.q[-1, 0] != 0.0  # it swings under gravity
    (tmp_path / "m.sdf").write_text(_pendulum(-1.5 * INERTIA_TOLERANCE), encoding="utf-8")
    with pytest.raises(SceneError, match=r"sdf link 'rod': inertia is not positive semidefinite: .*\[-1.5e-14, "):
        scene_from_dict({"gravity": [0.0, 0.0, -9.81], "robot": robot}, name="edge")


def test_rotated_inertia_is_taken_by_pinocchio() -> None:
    """A rod's inertia (moments 0, 1e-3, 1e-3) turned back to the rod's axes: R I R^T computed as is has a
    diagonal entry a rounding below 0 about half the time (Pinocchio's Inertia refuses it); :func:`rotated` never,
    and equals R I R^T to a rounding."""
    rng = np.random.default_rng(0)
    refused = 0
    for _ in range(200):
        turn = pin.rpy.rpyToMatrix(*rng.uniform(-3.0, 3.0, 3))
        rod = turn @ np.diag([0.0, 1e-3, 1e-3]) @ turn.T
        rod = (rod + rod.T) / 2
        direct = turn.T @ rod @ turn
        refused += direct[0, 0] < 0
        matrix = rotated(rod, turn.T)
        assert np.diag(matrix).min() >= 0 and np.array_equal(matrix, matrix.T)
        assert np.abs(matrix - direct).max() < 1e-17
        pin.Inertia(1.0, np.zeros(3), matrix)  # raises RuntimeError on a diagonal entry below 0
    assert refused > 50  # the case is real: the direct product would have been refused


# -- a redundant SDF closure: rows that are rounding of zero rows --------------------------------------------------
FALL = 0.5 * 9.81 * 0.003**2  # [m] a free body's fall in 3 ms from rest (RK4 is exact for a constant acceleration)


def _redundant(folder: Path):
    return scene_from_dict(
        {"gravity": [0.0, 0.0, -9.81], "robot": {"sdf": str(_scene(folder, REDUNDANT_SDF, True).parent / "robot.sdf")}},
        name="redundant",
    )


def test_redundant_closure_runs_as_a_free_body(tmp_path: Path) -> None:
    """The closure 'b' locks joint 'a' (its slide's rows leave only a's motion across b: rank 1 of 5, the other rows
    zero but for rounding): the pair falls as one free body, z = -g t^2 / 2, joint 'a' at 0 (it ended in ProxQP's
    PRIMAL_INFEASIBLE at t = 0.001 s, exit 2: the rounding rows scaled to unit rows of noise)."""
    scene_file = _scene(tmp_path, REDUNDANT_SDF, True)
    checked = cli(["check", str(scene_file), "--json"])
    assert checked.code == 0 and '"rank": 1' in checked.out and '"redundant": 4' in checked.out, checked
    ran = cli(["run", str(scene_file), "--duration", "0.003", "--quiet", "--json"])
    assert ran.code == 0, ran
    run = pinstab.simulate(_redundant(tmp_path), duration=0.003)
    assert run.q[-1, 2] == pytest.approx(-FALL, rel=1e-12) and abs(run.q[-1, 7]) < 1e-15
    assert set(run.info.solver_statistics.status_counts) == {"core pseudo-inverse"}  # the rounding rows left out


def test_proxqp_scaling_keeps_rounding_rows_small(tmp_path: Path) -> None:
    """ProxQP itself (direct off) on the same scene: the rounding rows keep the largest row's scale (not their own,
    1e-17), so ProxQP solves every step; the fall is the free body's."""
    run = pinstab.simulate(_redundant(tmp_path), duration=0.003, solver_options={"direct": False})
    assert set(run.info.solver_statistics.status_counts) == {"PROXQP_SOLVED"}
    assert run.q[-1, 2] == pytest.approx(-FALL, rel=1e-12)


def test_repeated_runs_in_one_process_are_identical(tmp_path: Path) -> None:
    """Three runs of the scene in one process: bitwise the same trajectory (they alternated between a SolverError
    and a DivergenceError: ProxQP's answers on the rows of noise vary by rounding with the alignment of its memory,
    and the noise rows made those roundings decide feasibility)."""
    runs = [pinstab.simulate(_redundant(tmp_path), duration=0.003) for _ in range(3)]
    assert all(np.array_equal(run.q, runs[0].q) and np.array_equal(run.v, runs[0].v) for run in runs)

"""Assembly is invariant to the scale of each constraint row: a joint relation written with coefficients 1e9 next to
one written with 1 (the long fuzzer's homing_scaled.toml: z2 + 1e9 z1 = 0 beside y2 - y1 = 0 was refused, "residual
0.273 ... largest on closure 'homing-y'", the 1e9 row drowning the other)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from fuzzing import toml_document
from test_assembly import TOO_LONG

from conftest import ROBOTS
from pinstab import AssemblyError, ConstrainedModel, SceneError, assemble
from pinstab.cli import main
from pinstab.scene import scene_from_dict
from pinstab.trajectory import Trajectory

COORDINATES = ("x1", "y1", "z1", "x2", "y2", "z2")  # homing.urdf's prismatic joints, q's order


def homing(
    y_scale: float = 1.0, z_coefficients: tuple[float, float] = (1.0, -1.0), y1: float = 0.0, z1: float = 0.2
) -> dict:
    """robots/homing.toml with homing-y's coefficients {y2, y1} times ``y_scale``, homing-z's {z2, z1} =
    ``z_coefficients`` and initial y1, z1 [m] (homing_scaled.toml: y_scale 1, (1, 1e9), y1 0, z1 0.2)."""
    data = tomllib.loads((ROBOTS / "homing.toml").read_text(encoding="utf-8"))
    data["robot"]["urdf"] = str(ROBOTS / "urdf" / "homing.urdf")
    data["servos"][0]["joints"] = {"y2": y_scale, "y1": -y_scale}
    data["servos"][1]["joints"] = dict(zip(("z2", "z1"), z_coefficients, strict=True))
    data["initial"]["q"] |= {"y1": y1, "z1": z1}
    return data


def nearest_on_relations(q: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The orthogonal projection of q onto {q: rows q = 0} (the configuration nearest q meeting the linear relations,
    which minimum-norm steps reach)."""
    return q - rows.T @ np.linalg.solve(rows @ rows.T, rows @ q)


def assembled(data: dict) -> tuple[np.ndarray, float]:
    scene = scene_from_dict(data)
    report = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    return report.q, report.tolerance


def test_the_fuzzers_homing_scaled_assembles_to_the_nearest_configuration():
    data = homing(z_coefficients=(1.0, 1e9))
    q, tolerance = assembled(data)
    y1, y2, z1, z2 = (q[COORDINATES.index(name)] for name in ("y1", "y2", "z1", "z2"))
    assert abs(y2 - y1) <= tolerance and abs(z2 + 1e9 * z1) <= tolerance
    rows = np.zeros((2, 6))
    rows[0, [COORDINATES.index("y2"), COORDINATES.index("y1")]] = 1.0, -1.0
    rows[1, [COORDINATES.index("z2"), COORDINATES.index("z1")]] = 1.0, 1e9
    start = np.array([data["initial"]["q"][name] for name in COORDINATES])
    np.testing.assert_allclose(q, nearest_on_relations(start, rows), rtol=0, atol=1e-15)
    assert y1 == pytest.approx(0.2, abs=1e-15)  # y1 = y2 met halfway between 0 and 0.4
    # z moves along (z2, z1) = (1, 1e9) / |.|: z2 by 0.2 (1 + 1e9) / (1 + 1e18)
    assert z2 == pytest.approx(0.2 - 2e-10, abs=1e-15)


@pytest.mark.parametrize(
    ("y_scale", "z_scale"), [(1e-9, 1.0), (1e9, 1.0), (1.0, 1e-9), (1.0, 1e9), (1e-9, 1e9), (1e9, 1e-9), (1e12, 1e-12)]
)
def test_the_assembled_q_does_not_depend_on_the_scale_of_a_relation(y_scale, z_scale):
    """homing from y1 = 0, z1 = 0 (both relations open by 0.4 m and 0.2 m) with each relation's coefficients times a
    factor: the q assembled with coefficients 1, that is the configuration nearest the start."""
    reference, _ = assembled(homing(y1=0.0, z1=0.0))
    q, _ = assembled(homing(y_scale, (z_scale, -z_scale), y1=0.0, z1=0.0))
    np.testing.assert_allclose(q, reference, rtol=1e-12, atol=1e-12 * np.max(np.abs(reference)))
    assert reference[[COORDINATES.index("y1"), COORDINATES.index("z1")]] == pytest.approx([0.2, 0.1], abs=1e-12)


def test_relation_scaled_to_the_ceiling_runs_as_written_with_ones(tmp_path):
    """homing from y1 = 0 with homing-y written {y2 = 1e12, y1 = -1e12} (the largest coefficient allowed) and
    homing-z {z2 = 1e-9, z1 = -1e-9}: ``run`` exits 0 with the trajectory of the relations written with 1."""
    paths = []
    for name, data in (("ones", homing()), ("scaled", homing(1e12, (1e-9, -1e-9)))):
        scene = tmp_path / f"{name}.toml"
        scene.write_text(toml_document(data), encoding="utf-8")
        paths.append(tmp_path / f"{name}.npz")
        assert main(["run", str(scene), "--duration", "0.2", "--quiet", "--save", str(paths[-1])]) == 0
    ones, scaled = (Trajectory.load(path) for path in paths)
    assert ones.q[0, COORDINATES.index("y2")] == pytest.approx(0.2, abs=1e-12)  # assembled: y1 = y2 from 0, 0.4
    np.testing.assert_allclose(scaled.q, ones.q, rtol=0, atol=1e-12)


def test_a_coefficient_above_the_ceiling_is_refused_by_name():
    data = homing()
    data["servos"][0]["joints"]["y1"] = -1e13
    with pytest.raises(SceneError, match=r"\|servo 'homing-y'.joints.y1\| = 1e\+13 .* allowed range \[0, 1e\+12\]"):
        scene_from_dict(data)


def test_a_loop_that_cannot_close_is_named_beside_a_scaled_relation():
    """The bundled four-bar with a closure 1.4 m too long and a relation crank = rocker written with 1e9: the refusal
    names the loop (whose residual is the one that stays), not the relation."""
    data = {
        "robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
        "closures": [
            TOO_LONG,
            {"name": "gear", "kind": "joint-relation", "joints": {"crank": 1e9, "rocker": -1e9}, "value": 0.0},
        ],
    }
    scene = scene_from_dict(data)
    with pytest.raises(AssemblyError, match="largest on closure 'too-long'") as info:
        assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    assert info.value.residual > 0.4  # coupler 2 m from B, rocker 0.5 m from D, |BD| <= 0.8 m: gap >= 0.7 m

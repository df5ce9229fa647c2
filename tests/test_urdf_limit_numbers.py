"""A URDF joint's ``<limit>`` attributes are finite numbers, else refused by the joint and the attribute (issue 34:
urdfdom refused ``lower="nan"`` as "The XML stream does not contain a valid URDF model", naming nothing)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzzing import cli, toml_document

LIMIT = {"lower": "-1", "upper": "1", "effort": "100", "velocity": "100"}


def scene_file(folder: Path, **changed: str) -> Path:
    """A one-link pendulum whose joint ``hinge`` has the limit of :data:`LIMIT` with ``changed`` attributes."""
    attributes = " ".join(f'{key}="{value}"' for key, value in {**LIMIT, **changed}.items())
    urdf = (
        '<robot name="pendulum"><link name="base"/><link name="arm"><inertial><origin xyz="0.15 0 0"/>'
        '<mass value="1"/><inertia ixx="1e-4" ixy="0" ixz="0" iyy="0.0075" iyz="0" izz="0.0075"/></inertial></link>'
        '<joint name="hinge" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>'
        f"<limit {attributes}/></joint></robot>"
    )
    path = folder / "pendulum.toml"
    path.write_text(toml_document({"gravity": [0.0, -9.81, 0.0], "robot": {"urdf_text": urdf}}), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("key", "text"), [("lower", "nan"), ("upper", "inf"), ("effort", "-inf"), ("velocity", "fast"), ("upper", "1e400")]
)
def test_a_limit_attribute_not_a_finite_number_is_named(key: str, text: str, tmp_path: Path) -> None:
    outcome = cli(["check", str(scene_file(tmp_path, **{key: text}))])
    assert outcome.code == 2, outcome
    assert f"robot joint 'hinge': limit {key} {text!r} is not a finite number" in outcome.message, outcome
    assert "valid URDF model" not in outcome.err, outcome


def test_finite_limits_load_and_are_kept(tmp_path: Path) -> None:
    outcome = cli(["check", str(scene_file(tmp_path, lower="-1e-300", upper="1e6")), "--json"])
    assert outcome.code == 0, outcome
    assert '"hinge": [-1e-300, 1000000.0]' in outcome.out.replace("\n", ""), outcome.out

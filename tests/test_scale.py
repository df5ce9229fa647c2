"""Scale invariance: the four-bar built in millimetre-and-gram sizes (lengths x 1e-2, masses x 1e-3)
and in large sizes (x 1e2, x 1e3), gravity scaled with the lengths so that the motion keeps its time
scale, moves exactly like the bundled one: the joint angles agree within 1e-9 relative over 2 s, for
every solver and method (issue: ProxQP's absolute thresholds once stopped the small one)."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab import load_scene, simulate
from pinstab.scene import scene_from_dict

DURATION, DT = 2.0, 2e-3
SCALES = [(1e-2, 1e-3), (1e2, 1e3)]
COMBINATIONS = [
    (method, solver)
    for solver in ("proxsuite", "dense", "pinocchio")
    for method in ("none", "baumgarte", "mukharlyamov", "projection", "post", "pinocchio")
    if (method == "pinocchio") == (solver == "pinocchio") or (solver == "pinocchio" and method != "mukharlyamov")
]


def _scaled(value: str, factor: float) -> str:
    return " ".join(repr(float(x) * factor) for x in value.split())


def scaled_urdf(length: float, mass: float) -> str:
    """The bundled four-bar URDF with every length times ``length`` and every mass times ``mass``
    (inertias times mass length^2)."""
    tree = ElementTree.parse(ROBOTS / "urdf" / "fourbar.urdf")
    for origin in tree.iter("origin"):
        origin.set("xyz", _scaled(origin.get("xyz", "0 0 0"), length))
    for element in tree.iter("mass"):
        element.set("value", repr(float(element.get("value")) * mass))
    for inertia in tree.iter("inertia"):
        for key in inertia.attrib:
            inertia.set(key, repr(float(inertia.get(key)) * mass * length**2))
    for cylinder in tree.iter("cylinder"):
        for key in ("radius", "length"):
            cylinder.set(key, repr(float(cylinder.get(key)) * length))
    return ElementTree.tostring(tree.getroot(), encoding="unicode")


def scaled_fourbar(length: float, mass: float):
    """The bundled four-bar scene at another size (same angles, same angular velocities)."""
    bundled = load_scene("fourbar")
    closure = bundled.constraints[0]
    model = bundled.model
    offsets = {
        side: model.frames[frame].placement.translation
        for side, frame in (("a", closure.frame_a), ("b", closure.frame_b))
    }
    return scene_from_dict(
        {
            "robot": {"urdf_text": scaled_urdf(length, mass)},
            "gravity": list(model.gravity.linear * length),
            "closures": [
                {
                    "name": closure.name,
                    "kind": "planar-point",
                    "plane": "xy",
                    "frame_a": "coupler",
                    "offset_a": list(offsets["a"] * length),
                    "frame_b": "rocker",
                    "offset_b": list(offsets["b"] * length),
                }
            ],
            "initial": {"q": {"crank": 1.0, "coupler": -0.9, "rocker": 1.6}, "v": {"crank": 3.0}},
        },
        name=f"fourbar x{length:g}",
    )


def test_scaled_scene_is_the_bundled_one_at_another_size():
    """The generator itself: link lengths and mass matrix scale as they should."""
    bundled, small = load_scene("fourbar"), scaled_fourbar(1e-2, 1e-3)
    q = bundled.q0
    np.testing.assert_allclose(
        pin.crba(small.model, small.model.createData(), q),
        1e-7 * pin.crba(bundled.model, bundled.model.createData(), q),
        rtol=1e-12,
        atol=1e-20,
    )


@pytest.mark.parametrize(("length", "mass"), SCALES)
@pytest.mark.parametrize(("method", "solver"), COMBINATIONS)
def test_motion_is_independent_of_the_units(method, solver, length, mass):
    reference = simulate("fourbar", method=method, solver=solver, dt=DT, duration=DURATION)
    scaled = simulate(scaled_fourbar(length, mass), method=method, solver=solver, dt=DT, duration=DURATION)
    assert scaled.steps == reference.steps
    error = np.max(np.abs(scaled.q - reference.q)) / np.max(np.abs(reference.q))
    assert error <= 1e-9, f"{method} + {solver} at lengths x{length:g}: relative angle error {error:.3g}"
    # forces scale by mass length / time^2
    force_error = np.max(np.abs(scaled.multipliers / (mass * length) - reference.multipliers))
    assert force_error <= 1e-8 * np.max(np.abs(reference.multipliers)), f"relative force error {force_error:.3g}"

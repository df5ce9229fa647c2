"""Held contacts whose forces are pinned against a friction cone (issue 34, the table fuzzer's flipped plane): whether
they can hold is decided by a linear program, not by how far ProxQP gets.

The case: box-push (a 1 kg box, 0.2 x 0.1 x 0.05 m, pushed with 9 N along -x) with its front-right corner under a
plane facing down (a ceiling at the floor's height, mu 4.356) and its back-right corner on the floor with mu 5; the
left corners frictionless. Its centre (x = 0.005 m, y = 0) is outside the triangle of its three floor corners, so
without friction the ceiling corner would have to pull; with it the ceiling and the floor clamp the right edge, and
forces inside the cones exist (checked below by statics written out by hand): the box stays at rest. ProxQP never
met its tolerance on it (every solve 1,000 outer iterations, cold ones 700,000 inner ones): 32 s, then exit 5 at
t = 0.0025 s, or exit 2 or 3 depending on its inner iteration cap. With mu 0.5 at the right corners no forces hold
it: ContactInfeasibleError at t = 0 naming front-right."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fuzzing import cli, toml_document
from scipy.optimize import linprog

import pinstab.solvers.proxsuite_ as proxsuite_
from conftest import ROBOTS
from pinstab import ContactInfeasibleError, simulate
from pinstab.scene import scene_from_dict

CENTRE = np.array([0.005, 0.0, 0.025])  # the box's frame (its centre of mass) in the world [m]
PUSH = np.array([-9.0, 0.0, 0.0])  # at the centre [N]
WEIGHT = np.array([0.0, 0.0, -9.81])  # 1 kg [N]
FACETS = 8  # the inscribed pyramid of the held cones


def clamped(back_left_y: float = 0.05078550426963115, mu: tuple[float, float] = (4.356274337274866, 5.0)) -> dict:
    """The fuzzer's scene (/tmp/h6/flip.toml); ``mu``: front-right's and back-right's."""
    return {
        "description": "box",
        "gravity": WEIGHT.tolist(),
        "robot": {"urdf": str(ROBOTS / "urdf" / "box.urdf"), "free_flyer": True},
        "contacts": [
            {
                "name": "front-left",
                "kind": "plane-contact",
                "frame_a": "box",
                "offset_a": [0.09916248742484518, 0.049152951817251385, -0.025],
            },
            {
                "name": "front-right",
                "kind": "plane-contact",
                "frame_a": "box",
                "offset_a": [0.09979365349514736, -0.04909742507971861, -0.025],
                "mu": mu[0],
                "point": [-0.000266939526127162, -0.40605741312841226, 0.0],
                "normal": [0.0, 0.0, -1.0],
            },
            {"name": "back-left", "kind": "plane-contact", "frame_a": "box", "offset_a": [-0.101, back_left_y, -0.025]},
            {
                "name": "back-right",
                "kind": "plane-contact",
                "frame_a": "box",
                "offset_a": [-0.1, -0.05053614045543617, -0.025],
                "mu": mu[1],
            },
        ],
        "forces": [{"name": "push", "kind": "external-force", "frame": "box", "force": PUSH.tolist()}],
        "initial": {"q": {"root_joint": [*CENTRE.tolist(), 0.0, 0.0, 0.0, 1.0]}},
    }


def holds_at_rest(scene: dict) -> bool:
    """Whether contact forces keep the box at rest, by hand: each corner's force (normal along its plane's normal,
    the frictional ones inside the same 8-facet pyramid as the held rows) with the push and the weight sum to zero
    force and zero moment about the centre (a linear feasibility program)."""
    columns, pushing, cones = [], [], []  # unit wrenches of the unknowns; the normal ones (>= 0); (first, mu)
    for contact in scene["contacts"]:
        point = np.array(contact["offset_a"])  # from the centre (the box unrotated)
        normal = np.array(contact.get("normal", [0.0, 0.0, 1.0]))
        pushing.append(len(columns))
        if "mu" in contact:
            cones.append((len(columns), contact["mu"] * math.cos(math.pi / FACETS)))
        for direction in [normal] + ([np.eye(3)[0], np.eye(3)[1]] if "mu" in contact else []):
            columns.append(np.concatenate([direction, np.cross(point, direction)]))
    n = len(columns)
    limits = np.zeros((FACETS * len(cones), n))  # t . d_k <= mu cos(pi / 8) f_n, d_k every 45 degrees
    for c, (first, inscribed) in enumerate(cones):
        for k in range(FACETS):
            angle = 2 * math.pi * k / FACETS
            limits[FACETS * c + k, first : first + 3] = [-inscribed, math.cos(angle), math.sin(angle)]
    result = linprog(
        np.zeros(n),
        A_ub=limits,
        b_ub=np.zeros(len(limits)),
        A_eq=np.column_stack(columns),
        b_eq=-np.concatenate([PUSH + WEIGHT, np.zeros(3)]),  # both at the centre
        bounds=[(0.0, None) if i in pushing else (None, None) for i in range(n)],
    )
    return result.status == 0


@pytest.mark.parametrize("back_left_y", [0.05078550426963115, 0.04915])  # the fuzzer's, and a variant once exit 2
def test_a_clamped_corner_holds_the_box_at_rest(back_left_y: float) -> None:
    scene = clamped(back_left_y)
    assert holds_at_rest(scene)  # the right verdict, by hand
    run = simulate(scene_from_dict(scene, "clamped"), contacts="held", duration=0.12)
    assert run.t[-1] == pytest.approx(0.12)
    assert np.max(np.abs(run.q - run.q[0])) < 1e-12  # at rest
    forces = np.asarray(run.multipliers)
    assert np.ptp(forces, axis=0).max() < 1e-9  # the same forces throughout: the smallest inside the cones
    assert set(run.info.solver_statistics.status_counts) == {"PROXQP_SOLVED"}  # bounded work per solve


def test_the_verdict_does_not_depend_on_proxqps_inner_iterations(monkeypatch: pytest.MonkeyPatch) -> None:
    """The cap on ProxQP's inner iterations once chose between exit 3 (20), 0 (50) and 2 (100)."""
    scene = scene_from_dict(clamped(), "clamped")
    ends = []
    for cap in (20, 50, 300):
        monkeypatch.setattr(proxsuite_, "MAX_ITER_IN", cap)
        run = simulate(scene, contacts="held", duration=0.02)
        ends.append(np.concatenate([run.q[-1], np.asarray(run.multipliers)[-1]]))
    assert np.max(np.abs(np.array(ends) - ends[1])) < 1e-10


def test_a_corner_that_cannot_hold_is_named_at_the_start(tmp_path) -> None:
    scene = clamped(mu=(0.5, 0.5))
    assert not holds_at_rest(scene)
    with pytest.raises(ContactInfeasibleError, match="at t = 0 s: contact 'front-right' would need to pull") as info:
        simulate(scene_from_dict(scene, "slipping"), contacts="held", duration=0.12)
    assert info.value.contacts[0] == "front-right" and info.value.time == 0.0
    path = tmp_path / "slipping.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    outcome = cli(["run", str(path), "--contacts", "held", "--duration", "0.12"])
    assert outcome.code == 5 and "'front-right' would need to pull" in outcome.message, outcome

"""Plane contacts' modes evaluated by the compiled core (:class:`~pinstab.solvers.core_modes.CoreModeDynamics`,
``cpp/contact_modes.cpp``) against :class:`~pinstab.solvers.contact_modes.ModeDynamics`' numpy evaluation of the same
rules (SVD of the held rows, dense solves): the accelerations, contact forces, bilateral reactions, the accelerations
without contact forces, their response and the contacts' kinematics, in every kind of mode, on cassie-stand (16 loop
closures, four foot contacts) and on a four-bar with a contact on its coupler; contacts the core does not take are
ModeDynamics' own."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import pinstab
from pinstab.constraints.contacts import contact_basis
from pinstab.contact.modes import Mode
from pinstab.model import ConstrainedModel
from pinstab.scene import load_scene
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import GRAZING_SPEED, ModeDynamics, PlaneContactGeometry
from pinstab.solvers.core_modes import CORE_STATUS, CoreModeDynamics

STICK, SLIDE, APART = Mode.STICKING, Mode.SLIDING, Mode.SEPARATED
# relative, the accelerations to the largest free one, the others to their own largest entry: the two
# factorizations' rounding through Cassie's shin-spring triangles (2e-7 from singular) measured at most 6.3e-10; the
# four-bar's at 1e-15
CASSIE_TOLERANCE = 1e-8
FOURBAR_TOLERANCE = 1e-12


def _close(core: np.ndarray, numpy: np.ndarray, scale: float, tolerance: float) -> None:
    np.testing.assert_allclose(core, numpy, rtol=0, atol=tolerance * (1.0 + scale))


def _compare(model: ConstrainedModel, contacts, q, v, t, modes, tolerance: float, directions=None) -> None:
    """Solve (q, v, t) in ``modes`` both ways and compare every output."""
    numpy = ModeDynamics(model, contacts)
    core = CoreModeDynamics(model, contacts)
    for dynamics in (numpy, core):
        if directions is not None:
            dynamics.directions[: len(contacts)] = [np.array(d, dtype=float) for d in directions]
    expected, solved = numpy.solve(q, v, t, modes), core.solve(q, v, t, modes)
    speeds = np.hypot(*expected.contacts.velocities[:, 1:].T)
    slow = zip(modes, contacts, speeds, strict=True)
    if any(mode is SLIDE and c.mu > 0.0 and speed < GRAZING_SPEED for mode, c, speed in slow):
        assert core.statistics.status_counts == {"contact modes": 1}  # a grazing slip: ModeDynamics' own solve
        np.testing.assert_array_equal(solved.acceleration, expected.acceleration)
        return
    assert core.statistics.status_counts == {CORE_STATUS: 1}
    accelerations = float(np.abs(expected.free).max())
    for name in ("acceleration", "forces", "free", "mobility", "reactions"):
        value = getattr(expected, name)
        scale = accelerations if name in ("acceleration", "free") else float(np.abs(value).max(initial=0.0))
        _close(getattr(solved, name), value, scale, tolerance)
    for name in ("gaps", "positions", "local", "velocities", "jacobian", "drift"):
        value = getattr(expected.contacts, name)
        _close(getattr(solved.contacts, name), value, float(np.abs(value).max(initial=0.0)), 1e-14)
    np.testing.assert_array_equal(core.acceleration(q, v, t), core.solve(q, v, t).acceleration)


@pytest.fixture(scope="module")
def cassie():
    """cassie-stand's model, contacts and two states: its start at rest, and its start moving along its closures (a
    random velocity, 0.1 rad/s in scale, projected on the closures' null space: the feet move)."""
    scene = load_scene("cassie-stand")
    contacts, system, q, v, _ = contact_system(scene, scene.q0, np.zeros(scene.model.nv), closures=True)
    model = system.model
    model.kin.update(q, v)
    closures = model.constraints.values(model.kin, q, v, 0.0, with_drift=False).jacobian
    _, sigma, vt = np.linalg.svd(closures)
    null = vt[int(np.sum(sigma > 1e-9 * sigma[0])) :].T
    moving = null @ (null.T @ (0.1 * np.random.default_rng(7).standard_normal(v.size)))
    return model, contacts, [(q, v), (q, moving)]


@pytest.mark.parametrize(
    "modes",
    [[STICK] * 4, [SLIDE, STICK, STICK, APART], [APART, APART, STICK, STICK], [SLIDE] * 4, [APART] * 4],
)
def test_cassie_core_modes_are_numpy_modes(cassie, modes):
    """On cassie-stand's start, at rest and moving: the core's evaluation is numpy's to 1e-8 relative (its redundant
    loop rows and the squeeze along each foot between its two end caps: least-norm both ways)."""
    model, contacts, states = cassie
    for q, v in states:
        _compare(model, contacts, q, v, 0.0, modes, CASSIE_TOLERANCE)


def _coupler_contact(scene, **options) -> PlaneContactGeometry:
    """The four-bar coupler's frame on the plane y = 0.05 m (mu 0.4), in the world's axes or ``options``'."""
    frame = scene.model.getFrameId("coupler", pin.BODY)
    plane = np.array([0.0, 0.05, 0.0])
    return PlaneContactGeometry(
        "coupler/plane", frame, contact_basis(np.array([0.0, 1.0, 0.0])), plane, 0.4, 0.0, **options
    )


@pytest.mark.parametrize("carried", [False, True], ids=["world plane", "carried by the crank"])
@pytest.mark.parametrize("modes", [[STICK], [SLIDE], [APART]])
def test_fourbar_core_modes_are_numpy_modes(modes, carried):
    """A four-bar (a planar-point closure) whose coupler's frame touches a plane fixed in the world or carried by the
    crank: sticking (its out-of-plane row zero: least squares), sliding (along the slip; at rest a grazing slip,
    ModeDynamics' own) and separated, to 1e-12 relative."""
    scene = pinstab.load_scene("fourbar")
    model = ConstrainedModel(scene)
    options = {"plane_frame": scene.model.getFrameId("crank", pin.BODY)} if carried else {}
    contact = _coupler_contact(scene, **options)
    for v in (scene.v0, np.zeros(scene.model.nv)):
        _compare(model, [contact], scene.q0, v, 0.0, modes, FOURBAR_TOLERANCE, directions=[(0.0, 1.0)])


def test_contacts_the_core_does_not_take_are_numpy_modes():
    """A contact with rotational friction (torsion) is not the core's: the evaluation is ModeDynamics' own, counted
    under its status."""
    scene = pinstab.load_scene("fourbar")
    model = ConstrainedModel(scene)
    turning = _coupler_contact(scene, torsion=0.01)
    numpy, core = ModeDynamics(model, [turning]), CoreModeDynamics(model, [turning])
    solved = core.solve(scene.q0, scene.v0, 0.0, [STICK])
    np.testing.assert_array_equal(solved.acceleration, numpy.solve(scene.q0, scene.v0, 0.0, [STICK]).acceleration)
    assert set(core.statistics.status_counts) == {"contact modes"}


def test_cassie_stand_runs_on_the_core_to_the_last_bit():
    """cassie-stand's event-driven run (0.05 s) evaluates its modes on the core (all but the start's choice of modes,
    measured 142 and 1), and a second run gives the same trajectory to the last bit."""
    scene = load_scene("cassie-stand")
    first, second = (pinstab.simulate(scene, contacts="event", duration=0.05, progress=False) for _ in range(2))
    counts = first.info.solver_statistics.status_counts
    assert set(counts) <= {CORE_STATUS, "contact modes"} and counts[CORE_STATUS] >= 100
    assert counts.get("contact modes", 0) <= 1  # the start's choice, whose slips from rest graze: ModeDynamics'
    np.testing.assert_array_equal(first.q, second.q)
    np.testing.assert_array_equal(first.v, second.v)

"""Grasp analysis against the textbook cases [MLS ch. 5]: antipodal point and soft-finger contacts on a
sphere, three contacts at 120 degrees on its equator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pinstab import PinstabError
from pinstab.grasp import GraspContact, analyse_grasp

RADIUS = 0.05  # [m]


def on_sphere(name: str, outward: np.ndarray, model: str, mu: float = 0.5, torsion: float = 0.0) -> GraspContact:
    """A contact at radius * outward with its z axis the inward normal."""
    normal = -np.asarray(outward, float) / np.linalg.norm(outward)
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    x = np.cross(helper, normal)
    x /= np.linalg.norm(x)
    return GraspContact(name, model, RADIUS * -normal, np.column_stack([x, np.cross(normal, x), normal]), mu, torsion)


def equator(model: str, mu: float) -> list[GraspContact]:
    return [
        on_sphere(f"c{k}", np.array([math.cos(a), math.sin(a), 0.0]), model, mu)
        for k, a in enumerate(2 * math.pi * np.arange(3) / 3)
    ]


def test_antipodal_point_contacts_cannot_resist_a_moment_about_their_axis():
    contacts = [on_sphere("left", [-1, 0, 0], "point-friction"), on_sphere("right", [1, 0, 0], "point-friction")]
    analysis = analyse_grasp(contacts, length=RADIUS)
    assert analysis.grasp_map.shape == (6, 6) and analysis.rank == 5
    assert not analysis.force_closure and analysis.quality == 0.0 and analysis.smallest_singular_value == 0.0
    # the unresisted wrench is the moment about the contact axis x
    np.testing.assert_allclose(np.abs(analysis.unresisted), [0, 0, 0, 1, 0, 0], atol=1e-9)
    assert analysis.internal_forces.shape == (6, 1)  # the squeeze along x


def test_one_frictionless_contact_leaves_wrenches_it_cannot_push():
    """Fewer primitive wrenches than 6: the unresisted wrench is still orthogonal to all of them (its only
    one is the push along the normal +x at the contact point)."""
    analysis = analyse_grasp([on_sphere("alone", [-1, 0, 0], "frictionless")], length=RADIUS)
    assert not analysis.force_closure and analysis.rank == 1
    assert abs(analysis.unresisted[0]) < 1e-12 and np.linalg.norm(analysis.unresisted) == pytest.approx(1.0)


@pytest.mark.parametrize("mu", [0.05, 0.5, 2.0])
def test_antipodal_soft_fingers_are_force_closure_for_every_mu(mu):
    contacts = [
        on_sphere(name, outward, "soft-finger", mu, torsion=0.01)
        for name, outward in (("left", [-1, 0, 0]), ("right", [1, 0, 0]))
    ]
    analysis = analyse_grasp(contacts, length=RADIUS)
    assert analysis.grasp_map.shape == (6, 8) and analysis.rank == 6
    assert analysis.internal_forces.shape == (8, 2)
    np.testing.assert_allclose(analysis.grasp_map @ analysis.internal_forces, 0, atol=1e-12)
    assert analysis.force_closure and analysis.quality > 0 and analysis.unresisted is None


def test_three_contacts_on_the_equator_need_friction():
    with_friction = analyse_grasp(equator("point-friction", 0.3), length=RADIUS)
    assert with_friction.rank == 6 and with_friction.internal_forces.shape == (9, 3)
    assert with_friction.force_closure and with_friction.quality > 0
    without = analyse_grasp(equator("point-friction", 0.0), length=RADIUS)
    assert without.rank == 6 and not without.force_closure and without.quality == 0
    # with mu = 0 every force is normal, in the equator's plane through the centre: the forces span only
    # that plane, so the unresisted direction has no in-plane force component
    assert without.unresisted is not None and np.abs(without.unresisted[:2]).max() < 1e-9


def test_more_friction_makes_a_better_grasp():
    qualities = [analyse_grasp(equator("point-friction", mu), length=RADIUS).quality for mu in (0.2, 0.5, 1.0)]
    assert qualities[0] < qualities[1] < qualities[2]


def test_the_grasp_map_moves_a_contact_force_to_the_object_centre():
    """A unit normal force at (r, 0, 0) pushing inward (-x) exerts the wrench (-1, 0, 0; 0, 0, 0); a
    tangential force along z there exerts a moment r x f = (0, -r, 0)."""
    contact = on_sphere("c", [1, 0, 0], "point-friction")
    wrench = contact.grasp_map() @ np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(wrench, [-1, 0, 0, 0, 0, 0], atol=1e-12)
    tangential = contact.rotation.T @ np.array([0.0, 0.0, 1.0])  # z of O in contact coordinates
    wrench = contact.grasp_map() @ tangential
    np.testing.assert_allclose(wrench, [0, 0, 1, 0, -RADIUS, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("contact", "message"),
    [
        (dict(model="sticky"), "unknown contact model 'sticky'; models: frictionless, point-friction"),
        (dict(model="point-friction", mu=-0.1), r"contact 'tip'.mu must be a number in \[0, 10\] \[-\], got -0.1"),
        (dict(model="point-friction", rotation=np.ones((3, 3))), "rotation must be a 3 x 3 rotation matrix"),
    ],
)
def test_bad_contacts_are_named(contact, message):
    arguments = dict(name="tip", model="point-friction", position=np.zeros(3), rotation=np.eye(3)) | contact
    with pytest.raises(PinstabError, match=message):
        GraspContact(**arguments)


def test_bad_analysis_arguments_are_named():
    with pytest.raises(PinstabError, match="at least one contact"):
        analyse_grasp([])
    with pytest.raises(PinstabError, match="facets"):
        analyse_grasp(equator("point-friction", 0.3), facets=2)
    with pytest.raises(PinstabError, match="facets must be a whole number from 3 to 32, got 33"):
        analyse_grasp(equator("point-friction", 0.3), facets=33)

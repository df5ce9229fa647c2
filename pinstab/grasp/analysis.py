"""Grasp analysis [MLS ch. 5] (docs/mathematics.md section 4): the grasp map, internal forces,
force closure and grasp quality.

Frames: the object frame O (at the object's reference point); contact frame C_i at the contact point on
the object's surface, its z axis the normal pointing into the object. A contact model transmits the
wrench components its basis B_ci selects (force first, then moment, in C_i): ``frictionless`` 1,
``point-friction`` 3, ``soft-finger`` 4 (plus the torsion about the normal), ``rigid`` 6. The grasp map
``G = [Ad^T_{g_oc_i^-1} B_ci ...]`` takes the contact forces (in their contact frames [N, N m]) to the
wrench they exert on the object, in O [N, N m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..contact.coefficients import friction_coefficient
from ..contact.models import WRENCH_BASES
from ..errors import PinstabError, choices

RANK_TOLERANCE = 1e-10  # singular values below this times the largest count as zero
MAX_FACETS = 32  # the inscribed pyramid then holds cos(pi / 32) = 99.5 % of the cone; the 6-D hull of the
# quality grows steeply beyond (64 sides: 11 s, 128: 96 s and 1.2 GB on the Allegro sphere grasp)


@dataclass(frozen=True)
class GraspContact:
    """One fingertip contact on the object.

    Attributes:
        name: the contact's name. model: a key of :data:`~pinstab.contact.models.WRENCH_BASES`.
        position: the contact point in O [m]. rotation: C_i's axes in O (3 x 3, z the inward normal).
        mu: Coulomb friction coefficient [-], in [0, :data:`~pinstab.contact.coefficients.MAX_FRICTION`].
        torsion: the soft finger's torsional coefficient [m] (``|moment about the normal| <= torsion x normal
            force``).
    """

    name: str
    model: str
    position: np.ndarray
    rotation: np.ndarray
    mu: float = 0.0
    torsion: float = 0.0

    def __post_init__(self) -> None:
        if self.model not in WRENCH_BASES:
            raise PinstabError(
                f"contact {self.name!r}: unknown contact model {self.model!r}; models: {choices(WRENCH_BASES)}"
            )
        friction_coefficient(self.mu, f"contact {self.name!r}.mu")
        torsion = self.torsion
        if not (isinstance(torsion, int | float) and math.isfinite(torsion) and torsion >= 0):
            raise PinstabError(f"contact {self.name!r}: torsion must be a finite number >= 0, got {torsion!r}")
        rotation = np.asarray(self.rotation, dtype=float)
        if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9):
            raise PinstabError(f"contact {self.name!r}: rotation must be a 3 x 3 rotation matrix")

    @property
    def basis(self) -> np.ndarray:
        """B_c (6 x m)."""
        return WRENCH_BASES[self.model]

    def grasp_map(self) -> np.ndarray:
        """G_i = [[R, 0], [p^ R, R]] B_c (6 x m): contact forces in C_i to the object wrench in O."""
        rotation, position = np.asarray(self.rotation, float), np.asarray(self.position, float)
        adjoint = np.zeros((6, 6))
        adjoint[:3, :3] = rotation
        adjoint[3:, 3:] = rotation
        adjoint[3:, :3] = pin.skew(position) @ rotation
        return adjoint @ self.basis

    def cone_generators(self, facets: int) -> np.ndarray:
        """Generators of the linearized friction cone for a unit normal force, in basis coordinates
        (m x g): the edges of a pyramid with ``facets`` sides inscribed in the Coulomb cone (and the
        torsion bounds of a soft finger); a rigid contact's are +-e_i (it transmits any wrench)."""
        if self.model == "rigid":
            return np.hstack([np.eye(6), -np.eye(6)])
        if self.model == "frictionless":
            return np.ones((1, 1))
        angles = 2 * np.pi * np.arange(facets) / facets
        forces = np.vstack([self.mu * np.cos(angles), self.mu * np.sin(angles), np.ones(facets)])
        if self.model == "point-friction":
            return forces
        return np.hstack([np.vstack([forces, sign * self.torsion * np.ones(facets)]) for sign in (1.0, -1.0)])


def grasp_map(contacts: list[GraspContact]) -> np.ndarray:
    """G (6 x sum of basis columns), contacts in order [N, N m per unit contact force]."""
    if not contacts:
        raise PinstabError("a grasp needs at least one contact")
    return np.hstack([contact.grasp_map() for contact in contacts])


@dataclass(frozen=True)
class GraspAnalysis:
    """What a grasp can do.

    Attributes:
        grasp_map: G (6 x m). rank: rank of G. smallest_singular_value: its 6th singular value (0 when
            G is not onto) [N or N m per unit contact force].
        internal_forces: a basis of the null space of G (m x k): contact forces that load the object
            without moving it. force_closure: every object wrench can be resisted with forces inside
            the (linearized) cones. unresisted: a unit wrench direction in O that the grasp cannot
            resist (None in force closure): a moment about the contact axis for two point contacts.
        quality: Ferrari-Canny epsilon [N]: the largest object wrench (moments divided by
            ``length``) resisted in every direction with unit total normal force; 0 without force closure.
        length: the length [m] that makes moments comparable to forces in ``quality``.
    """

    grasp_map: np.ndarray
    rank: int
    smallest_singular_value: float
    internal_forces: np.ndarray
    force_closure: bool
    unresisted: np.ndarray | None
    quality: float
    length: float


def analyse_grasp(contacts: list[GraspContact], facets: int = 8, length: float = 1.0) -> GraspAnalysis:
    """Analyse a grasp: G, its rank and smallest singular value, internal forces, force closure with
    cones linearized by ``facets`` sides (inscribed: a closure found holds for the exact cones), an
    unresisted wrench direction when it fails, and the Ferrari-Canny quality with moments over
    ``length`` [m].

    Raises:
        PinstabError: no contacts, fewer than 3 or more than :data:`MAX_FACETS` facets, or a non-positive
            length.
    """
    if isinstance(facets, bool) or not isinstance(facets, int) or not 3 <= facets <= MAX_FACETS:
        raise PinstabError(
            f"facets must be a whole number from 3 to {MAX_FACETS}, got {facets!r} ({MAX_FACETS} sides already "
            f"cover {100 * math.cos(math.pi / MAX_FACETS):.1f} % of each friction cone)"
        )
    if not (isinstance(length, int | float) and math.isfinite(length) and length > 0):
        raise PinstabError(f"length must be a positive number [m], got {length!r}")
    matrix = grasp_map(contacts)
    _, singular, right = np.linalg.svd(matrix)
    threshold = RANK_TOLERANCE * max(float(singular[0]), 1.0)
    rank = int(np.count_nonzero(singular > threshold))
    internal = right[rank:].T
    smallest = float(singular[5]) if rank == 6 else 0.0
    scale = np.diag([1.0, 1.0, 1.0, 1.0 / length, 1.0 / length, 1.0 / length])
    primitive = scale @ np.hstack(
        [contact.grasp_map() @ contact.cone_generators(facets) for contact in contacts]
    )  # 6 x N
    closure, unresisted = _force_closure(primitive)
    if unresisted is not None:
        unresisted = scale @ unresisted
        unresisted = unresisted / np.linalg.norm(unresisted)
    return GraspAnalysis(
        matrix, rank, smallest, internal, closure, unresisted, _ferrari_canny(primitive) if closure else 0.0, length
    )


def _force_closure(primitive: np.ndarray) -> tuple[bool, np.ndarray | None]:
    """Whether the primitive wrenches positively span R^6 (they span it and a strictly positive
    combination of them is zero), else a direction u with u . w >= 0 for every primitive wrench w
    (so the disturbance u cannot be resisted)."""
    from scipy.optimize import linprog

    count = primitive.shape[1]
    left, singular, _ = np.linalg.svd(primitive, full_matrices=count < 6)  # all 6 left vectors, a small V
    if int(np.count_nonzero(singular > RANK_TOLERANCE * max(float(singular[0]), 1.0))) < 6:
        return False, left[:, -1]  # orthogonal to every primitive wrench
    positive = linprog(np.zeros(count), A_eq=primitive, b_eq=np.zeros(6), bounds=[(1.0, None)] * count)
    if positive.status == 0:
        return True, None
    # a separating direction: u . w >= 0 for all w, as large as the box |u| <= 1 allows
    separating = linprog(-primitive.sum(axis=1), A_ub=-primitive.T, b_ub=np.zeros(count), bounds=[(-1.0, 1.0)] * 6)
    return False, separating.x if separating.status == 0 else left[:, -1]


def _ferrari_canny(primitive: np.ndarray) -> float:
    """The distance from the origin to the nearest facet of the convex hull of the primitive wrenches."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(primitive.T)
    except QhullError:
        return 0.0
    return float(max(0.0, np.min(-hull.equations[:, -1])))

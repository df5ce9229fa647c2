"""The banded path: a long chain of point closures solved at a cost linear in its size.

Pinocchio's ``constraintDynamics`` factors the closures' rows densely: on the N-four-bar its cost per
call grows as N^2.2 (about 0.3 ms at N = 40, 2 ms at N = 80; ``benchmarks/chains.py``). A chain of loops
couples each loop with its neighbours only, so the KKT matrix of docs/mathematics.md eq. (3),

    [[M, G^T], [G, 0]] [a; -lambda] = [tau - h; -gamma0 - Kp phi - Kd G v],

has a narrow band once its rows are put in reverse Cuthill-McKee order (the pattern depends on the
tree and the closures, not on q: it is found once, here). The compiled kernel (``cpp/banded_kernel.cpp``,
``pinstab._compiled``) forms its entries from Pinocchio's ``crba`` in the world convention (also the joint
Jacobians and placements) and a Newton-Euler pass in the world frame over those Jacobian columns
(``cpp/world_bias.cpp``; Pinocchio's ``nonLinearEffects`` for joints whose motion subspace turns with q), and
factors it by LAPACK's unblocked banded LU with partial pivoting (``dgbtf2``/``dgbtrs``, what ``dgbsv`` runs
for a band below its block size): O(n b^2) for n unknowns and a band b.

It is the same equation as the native path's (Pinocchio's corrector ``-Kp phi - Kd G v`` on the
point rows), solved exactly instead of with a proximal term of 1e-12: both agree to rounding while
the constraint rows are independent. Near a singular configuration (rows losing rank) the LU meets a small
pivot: below :data:`PIVOT_TOLERANCE` of the largest its solution is refined (residuals summed in extended
precision, corrections from the same factors) until the last correction is at rounding; an exactly singular
matrix (a pivot ratio below 1e-12: redundant rows, the aligned configuration) or a refinement that does not
converge sets :attr:`BandedDynamics.singular`, and the caller uses the reference solve for that evaluation.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..constraints import FrameClosure, Violation
from ..errors import SolverError
from ..kernels import BandedKernel
from ..projection import Projector

PIVOT_TOLERANCE = 1e-6  # smallest |pivot| of the LU over the largest below which its solution is refined
MIN_CLOSURES = (
    6  # fewer: the band rule below keeps Pinocchio's solve (compiled, the banded solve is cheaper from N = 1)
)
MAX_BAND_FRACTION = 0.25  # a band wider than this fraction of the unknowns gains nothing over a dense solve


_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0


def _csr(rows: int, per_row: np.ndarray, indices: np.ndarray, data: np.ndarray) -> dict[str, np.ndarray]:
    """A CSR matrix of ``rows`` rows as the kernel takes it (``indptr``, ``indices``, ``data``): ``per_row`` entries in
    each row, ``indices`` and ``data`` row after row, columns increasing in each."""
    indptr = np.zeros(rows + 1, dtype=np.int32)
    np.cumsum(per_row, out=indptr[1:])
    return {"indptr": indptr, "indices": indices.astype(np.int32), "data": data}


def _reverse_cuthill_mckee(rows: np.ndarray, cols: np.ndarray, size: int) -> np.ndarray:
    """scipy's reverse Cuthill-McKee order of the symmetric pattern of ``size`` nodes with entries at (``rows``,
    ``cols``), repeats allowed, given in its canonical CSR form (columns sorted in a row, no repeats)."""
    keys = np.unique(rows * size + cols)
    indptr = np.zeros(size + 1, dtype=np.int32)
    np.cumsum(np.bincount(keys // size, minlength=size), out=indptr[1:])
    pattern = csr_matrix((np.ones(len(keys)), (keys % size).astype(np.int32), indptr), shape=(size, size))
    return np.asarray(reverse_cuthill_mckee(pattern, symmetric_mode=True), dtype=int)


def joint_supports(model: pin.Model) -> np.ndarray:
    """(joints, nv) bool: per joint, the velocity indices that move its body (its own and its ancestors'), from its
    parent's (a Pinocchio model lists parents before children); none for the world. Built as one bit set per joint."""
    parents, starts, widths = model.parents, model.idx_vs, model.nvs
    masks = [0]
    for joint in range(1, model.njoints):
        masks.append(masks[parents[joint]] | ((1 << widths[joint]) - 1) << starts[joint])
    width = (model.nv + 7) // 8
    packed = np.frombuffer(b"".join(mask.to_bytes(width, "little") for mask in masks), dtype=np.uint8)
    return np.unpackbits(packed.reshape(model.njoints, width), axis=1, count=model.nv, bitorder="little").view(bool)


class BandedDynamics:
    """The accelerations of a tree closed by ``point`` / ``planar-point`` closures, by a banded LU.

    The pattern (which entries exist, where they go in the band) is found here once; the compiled kernel
    (:attr:`kernel`, ``cpp/banded_kernel.cpp``) evaluates it.

    Args:
        model: the Pinocchio model. closures: point and planar-point closures.
        kp: corrector stiffness [1/s^2]. kd: corrector damping [1/s].
        data: a ``Data`` of the model for the kernel to compute in (shared with other computations: each evaluation
            recomputes what it reads), or None for one of its own; a ``Data`` of a long chain is costly
            (``benchmarks/data_creation.py``).

    Raises:
        SolverError: ``data`` is not a ``pin.Data`` of ``model``.

    Attributes:
        size: unknowns of the KKT system (accelerations and multipliers). band: its half-bandwidth.
        singular: the last solve met a pivot below :data:`PIVOT_TOLERANCE` that refinement did not overcome (its
            result is not to be used).
    """

    def __init__(
        self,
        model: pin.Model,
        closures: list[FrameClosure],
        kp: float = 0.0,
        kd: float = 0.0,
        data: pin.Data | None = None,
    ) -> None:
        self.model = model
        self.kp, self.kd = float(kp), float(kd)
        count = len(closures)
        # the points: side a of every closure, then side b; (joint, local point), joint 0: a fixed world point
        pairs = [closure.sides(model) for closure in closures]
        sides = [(joint, placement.translation) for side in (0, 1) for joint, placement in (p[side] for p in pairs)]
        points = 2 * count
        carried = [index for index, (joint, _) in enumerate(sides) if joint != 0]
        self._carried = np.array(carried, dtype=int)
        self._local = np.array([sides[index][1] for index in carried]).reshape(-1, 3)
        self._points = (
            np.array([point if joint == 0 else np.zeros(3) for joint, point in sides]).reshape(-1, 3).T.copy()
        )
        # closure rows: r = s_r . (T_b - T_a) over the per-point terms T (3, points), raveled by component: row r
        # holds -s_k at column k points + closure and s_k at k points + count + closure, k = 0, 1, 2
        row_closure = np.repeat(np.arange(count), [closure.selection.shape[0] for closure in closures]).astype(int)
        selection = np.vstack([closure.selection for closure in closures]).reshape(-1, 3)
        self.rows = len(row_closure)
        columns = np.arange(3)[None, :, None] * points + row_closure[:, None, None] + np.array([0, count])
        signed = selection[:, :, None] * np.array([-1.0, 1.0])
        self._row_map = _csr(self.rows, np.full(self.rows, 6), columns.ravel(), signed.ravel())
        # G entries e = (row, column): s . ((w_a - w_b) J_lin + J_ang x lever), lever = w_a p_a - w_b p_b,
        # i.e. J[:, column] . c_e with c_e = [(w_a - w_b) s; lever x s], the second half linear in the points;
        # a row's entries: the dofs moving either of its points, in increasing order
        supports = joint_supports(model)
        joints = np.array([joint for joint, _ in sides], dtype=int)
        moves_a, moves_b = supports[joints[row_closure]], supports[joints[count + row_closure]]
        self._g_row, self._g_col = np.nonzero(moves_a | moves_b)
        size = len(self._g_row)
        # per entry, the weight of each point: w_a (1 or 0) for side a, -w_b (-1 or -0) for side b
        weights = np.stack([moves_a[self._g_row, self._g_col], moves_b[self._g_row, self._g_col]], axis=1)
        weights = weights * np.array([1.0, -1.0])
        self._g_linear = ((weights[:, 0] + weights[:, 1])[:, None] * selection[self._g_row]).T
        # the lever part: (lever x s)_i = skew[i, j] lever_j, at row i size + e and column j points + point, where
        # neither the weight nor the skew entry is zero
        skew = np.einsum("ijk,rk->rij", _LEVI_CIVITA, selection)[self._g_row]  # (entries, i, j)
        terms = weights[:, None, None, :] * skew[:, :, :, None]  # (entries, i, j, point)
        kept = (weights != 0)[:, None, None, :] & (skew != 0)[:, :, :, None]
        point_columns = np.stack([row_closure[self._g_row], count + row_closure[self._g_row]], axis=1)
        columns = np.arange(3)[None, :, None] * points + point_columns[:, None, :]  # (entries, j, point)
        order = (1, 0, 2, 3)  # row-major by (i, e), columns increasing in a row
        kept, terms = kept.transpose(order), terms.transpose(order)
        columns = np.broadcast_to(columns[None], kept.shape)
        self._g_map = _csr(3 * size, kept.reshape(3 * size, 6).sum(axis=1), columns[kept], terms[kept])
        # M entries (upper triangle read from crba): dofs on one branch
        dof_joint = np.repeat(np.arange(model.njoints), [0, *model.nvs[1:]])
        branch = supports[dof_joint]
        m_upper = np.column_stack(np.nonzero(np.triu(branch | branch.T)))
        self._m_off = m_upper[:, 0] != m_upper[:, 1]
        self._build_band(m_upper)
        try:
            self.kernel = BandedKernel(
                model, self._pattern(sides, m_upper), self.band, self.kp, self.kd, PIVOT_TOLERANCE, data
            )
        except ValueError as error:  # the compiled kernel refused the Data
            raise SolverError(f"banded solve: {error}; give pin.Data(model) of this model, or None") from None
        self.singular = False

    def _pattern(self, sides: list[tuple[int, np.ndarray]], m_upper: np.ndarray) -> dict[str, np.ndarray]:
        """The arrays the compiled kernel evaluates from (see ``cpp/banded_kernel.hpp``)."""
        arrays = {
            "carried": self._carried,
            "joints": np.array([sides[index][0] for index in self._carried], dtype=int),
            "local": self._local,
            "fixed_points": self._points,
            "g_columns": self._g_col,
            "g_linear": self._g_linear,
            "m_rows": m_upper[:, 0],
            "m_cols": m_upper[:, 1],
            "m_off": np.flatnonzero(self._m_off),
            "scatter": self._scatter,
            "acceleration_slots": self._acceleration_slots,
            "row_slots": self._row_slots,
        }
        arrays.update(self._gram_pattern())
        for name, matrix in (("row_map", self._row_map), ("g_map", self._g_map)):
            arrays.update({f"{name}_{part}": array for part, array in matrix.items()})
        return {name: np.ascontiguousarray(array) for name, array in arrays.items()}

    def _gram_pattern(self) -> dict[str, np.ndarray]:
        """The banded Gram matrix G G^T of the closures' rows (reverse Cuthill-McKee order): its band, each G
        entry's row in that order and the products of entries that share a column with the slot each adds to
        (lower band storage, column-major: A[i, j] at [i - j, j], i >= j)."""
        # the entries column by column (columns in order of first appearance, entries in order), and every ordered
        # pair of entries in one column, column by column, first entry by first entry
        _, first_entry, group = np.unique(self._g_col, return_index=True, return_inverse=True)
        rank = np.empty(len(first_entry), dtype=int)
        rank[np.argsort(first_entry)] = np.arange(len(first_entry))
        entries = np.argsort(rank[group], kind="stable")
        widths = np.bincount(rank[group])
        starts = np.cumsum(widths) - widths
        repeats = widths[rank[group[entries]]]
        first = np.repeat(entries, repeats)
        within = np.arange(len(first)) - np.repeat(np.cumsum(repeats) - repeats, repeats)
        second = entries[np.repeat(starts[rank[group[entries]]], repeats) + within]
        rows = self._g_row
        order = _reverse_cuthill_mckee(rows[first], rows[second], self.rows)
        position = np.empty(self.rows, dtype=int)
        position[order] = np.arange(self.rows)
        low, high = position[rows[first]], position[rows[second]]
        kept = low >= high  # each product once, in the lower triangle
        band = int(np.max(low - high, initial=0))
        return {
            "gram_entry_rows": position[rows],
            "gram_pair_first": first[kept],
            "gram_pair_second": second[kept],
            "gram_pair_slot": (low - high)[kept] + (band + 1) * high[kept],
            "gram_band": np.array([band]),
        }

    def _build_band(self, m_upper: np.ndarray) -> None:
        """The reverse Cuthill-McKee order of the KKT pattern, its band and the scatter of the entries
        (M upper, M lower off-diagonal, G, G^T) into LAPACK's band storage."""
        nv, size = self.model.nv, self.model.nv + self.rows
        off = m_upper[:, 0] != m_upper[:, 1]
        rows = np.concatenate([m_upper[:, 0], m_upper[off, 1], nv + self._g_row, self._g_col])
        cols = np.concatenate([m_upper[:, 1], m_upper[off, 0], self._g_col, nv + self._g_row])
        order = _reverse_cuthill_mckee(rows, cols, size)
        position = np.empty(size, dtype=int)
        position[order] = np.arange(size)
        prow, pcol = position[rows], position[cols]
        band = int(np.max(np.abs(prow - pcol), initial=0))
        self.size, self.band = size, band
        self._acceleration_slots, self._row_slots = position[:nv], position[nv:]
        # LAPACK's band storage (column-major, 3 band + 1 rows): A[i, j] at ab[2 kl + i - j, j], kl = ku
        self._scatter = pcol * (3 * band + 1) + 2 * band + prow - pcol

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Joint accelerations [m/s^2, rad/s^2] at (q, v) under the applied forces ``tau`` [N, N m];
        check :attr:`singular` before using them. Computed by the compiled kernel (:attr:`kernel`)."""
        acceleration, usable = self.kernel.acceleration(q, v, tau)
        self.singular = not usable
        return acceleration

    def relative_singular_value(self, q: np.ndarray, rank: int) -> float:
        """sigma_rank / sigma_1 of the closures' Jacobian G at q [-] (NaN when not finite), the passage watch's
        sample: the compiled kernel's Rayleigh quotient iterations on the banded Gram matrix G G^T, checked by
        its inertia (``cpp/spectrum.cpp``; no dense SVD, no OpenBLAS threads). Accurate to rounding of
        sigma_1, as an SVD."""
        return self.kernel.relative_singular_value(q, rank)

    def violation(self, q: np.ndarray, v: np.ndarray) -> Violation:
        """max |phi| [m] and max |G v| [m/s] over the closures' rows at (q, v) (the model's
        :meth:`~pinstab.model.ConstrainedModel.violation` of these closures), by the compiled kernel."""
        return Violation(*self.kernel.violation(q, v))

    def multipliers(self) -> np.ndarray:
        """The closures' multipliers [N] of the last :meth:`acceleration`, in pinstab's rows (force on a)."""
        return self.kernel.multipliers()

    def residual(self, q: np.ndarray) -> np.ndarray:
        """phi (rows,) [m] of the closures at q, by the compiled kernel (the model's rows, without its Python pass)."""
        return self.kernel.values(q)[0]

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """G (rows x nv) [m/rad, 1] of the closures at q, dense, by the compiled kernel."""
        dense = np.zeros((self.rows, self.model.nv))
        dense[self._g_row, self._g_col] = self.kernel.values(q)[1]
        return dense

    def rate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """G v (rows,) [m/s] at (q, v), from the kernel's entries of G."""
        entries = self.kernel.values(q)[1]
        return np.bincount(self._g_row, weights=entries * v[self._g_col], minlength=self.rows)

    def project(self, q: np.ndarray, rows: np.ndarray) -> np.ndarray | None:
        """``M^-1 G^T (G M^-1 G^T)^-1 rows`` (nv,) at q by the banded LU (refined near a small pivot), or None
        where the KKT matrix is singular to rounding (redundant rows, a singular configuration)."""
        step, usable = self.kernel.project(q, rows)
        return step if usable else None


class BandedProjector:
    """The projections of :mod:`pinstab.projection` by the banded solve, for the closures of the banded path:
    the position step ``-M^-1 G^T (G M^-1 G^T)^-1 phi`` and the velocity projection ``v - M^-1 G^T (G M^-1 G^T)^-1
    G v`` from one KKT solve each (the general projector builds G in Python and solves a dense least-squares
    problem); where the KKT matrix is singular to rounding, the ``fallback`` projector's (its pseudo-inverse).

    Args:
        banded: the banded solve. fallback: a projector of the same model (the general one).
    """

    def __init__(self, banded: BandedDynamics, fallback: Projector) -> None:
        self.banded, self.fallback = banded, fallback

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        phi = self.banded.residual(q)
        step = self.banded.project(q, -phi) if np.isfinite(phi).all() else None
        if step is None:
            return self.fallback.position_step(q, t)
        return step, float(np.max(np.abs(phi), initial=0.0))

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        step = self.banded.project(q, self.banded.rate(q, v))
        return self.fallback.velocity_projection(q, v, t) if step is None else v - step


def banded_obstacle(closures: list[FrameClosure], size: int, band: int | None = None) -> str | None:
    """Why the banded path does not pay for these closures (fewer than :data:`MIN_CLOSURES`, or a band
    wider than :data:`MAX_BAND_FRACTION` of the ``size`` unknowns), or None."""
    if len(closures) < MIN_CLOSURES:
        return f"{len(closures)} closure(s): fewer than {MIN_CLOSURES}, Pinocchio's own solve is cheaper"
    if band is not None and band > MAX_BAND_FRACTION * size:
        return f"the KKT band ({band}) exceeds {MAX_BAND_FRACTION:g} of its {size} unknowns"
    return None

"""Singular passages: where the constraint Jacobian G loses rank along the motion, and how the
stepping keeps its evaluations away from them.

At a singular configuration two branches of the constraint manifold cross (the N-four-bar's
parallelogram and crossed branches where all links align). Near it the smallest singular value of G
falls linearly with the distance, and the equations a method evaluates there divide by it: an
off-branch deviation of size eps at a distance y from the crossing becomes an acceleration of order
eps / y^3 across the branches. A stage of an explicit scheme that lands very close to the crossing
therefore throws the motion off its branch (measured on the N-four-bar, N = 40: a 1 ms RK4 step whose
last stage fell 4e-5 rad from the crossing changed the energy by 5e-2 J).

:class:`PassageWatch` samples the smallest relative singular value ``s = sigma_r / sigma_1`` of G (r:
the rank at the start, so redundant rows are not mistaken for a singularity) at step ends, densely
when s is falling towards zero and rarely otherwise; predicts the crossing time t* where s reaches zero
(s is linear in time there; a parabola through three samples when it falls faster and faster); no
sample is further ahead than a quarter of the time s would take to reach zero at the fastest rate it has
changed so far; and plans the steps around it so that t* falls in the middle of the
widest gap between the scheme's stage times. After such a step it locates the least s on the step's
dense output and checks that the motion kept its branch: the tangent space ker G turns across the
passage no faster than before it (a branch change turns it by a finite angle at once).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from scipy.linalg import lapack
from scipy.optimize import minimize_scalar

from ..errors import BranchChangeWarning

if TYPE_CHECKING:
    from ..model import ConstrainedModel
    from .dense import Segment

GENERIC_RANK_TOLERANCE = 1e-9  # singular values below this fraction of the largest: redundant at the start
RANK_TOLERANCE = 1e-6  # at a passage, singular values below this fraction of the largest count as lost
PASSAGE_LEVEL = 1e-3  # a located minimum of s below this is a singular passage (reported)
SAMPLE_CAP = 64  # steps at most between two samples of s
APPROACH_SHARE = 0.25  # while s falls, the next sample comes after this share of the predicted time to t*
HORIZON = 2  # steps: a crossing predicted within this many steps is planned for
BRANCH_ANGLE = 1e-2  # [rad] a tangent space that turns by this much across a passage: the branch changed ...
BRANCH_FACTOR = 10.0  # ... unless it turned nearly as fast before the passage (this factor slower)
LOCATE_TOLERANCE = 1e-9  # share of the step to which the least s is located
VERTEX_ITERATIONS = 16  # parabola vertices tried before the least s is left to Brent's search
ROUNDING_SPAN = 1e-6  # share of the step: samples of s this close together resolve it to rounding


@dataclass(frozen=True)
class Passage:
    """A passage close to a singular configuration.

    Attributes:
        t: time of the least s [s].
        min_relative_singular_value: that least s = sigma_r / sigma_1 of G on the step's dense output [-].
        rank: rank of G there (singular values above :data:`RANK_TOLERANCE` of the largest).
        generic_rank: rank of G at the run's start.
        branch_kept: the motion stayed on its branch (see :attr:`tangent_turn`).
        tangent_turn: largest principal angle between ker G before and after the passage [rad].
        expected_turn: the turn expected over the same time from the rate before the passage [rad].
    """

    t: float
    min_relative_singular_value: float
    rank: int
    generic_rank: int
    branch_kept: bool
    tangent_turn: float
    expected_turn: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return asdict(self)


class Plan(NamedTuple):
    """Steps planned around a singular passage: their end times [s] (the last a grid time) and the index
    of the step that straddles the crossing."""

    ends: list[float]
    straddle: int


def node_gap(nodes: Sequence[float]) -> tuple[float, float]:
    """(centre, half-width) of the widest gap between a scheme's stage times on [0, 1] (the step's ends
    included), as shares of the step."""
    points = sorted({0.0, 1.0, *(float(c) for c in nodes)})
    width, start = max((b - a, a) for a, b in zip(points[:-1], points[1:], strict=True))
    return start + width / 2, width / 2


class Conditioning:
    """The smallest relative singular value of the constraint Jacobian.

    Args:
        model: the constrained model.
        q: the start configuration: the rank there is the generic rank r (with ``relative``, all the rows when
            sigma_rows / sigma_1 exceeds :data:`GENERIC_RANK_TOLERANCE` there, an SVD only otherwise; that value is
            the first sample's when it is taken at q).
        relative: ``(q, r) -> sigma_r / sigma_1`` computed without a dense SVD (the banded path's), or None.
        jacobian: ``q -> G`` without the model's Python pass over its rows (the banded path's), or None.
    """

    def __init__(
        self,
        model: ConstrainedModel,
        q: np.ndarray,
        relative: Callable[[np.ndarray, int], float] | None = None,
        jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.model = model
        self._relative = relative
        self._jacobian_of = jacobian
        self._zero = np.zeros(model.nv)
        self._start: tuple[np.ndarray, float] | None = None  # (q, s) at the start, for the first sample there
        rows = model.constraints.rows
        if relative is not None and 0 < rows <= model.nv:  # independent rows at the start: no SVD to say so
            start = relative(q, rows)
            if start > GENERIC_RANK_TOLERANCE:
                self.rank, self._start = rows, (q.copy(), start)
                return
        values = self._singular_values(q, 0.0)
        largest = values[0] if values.size else 0.0
        self.rank = int(np.sum(values > GENERIC_RANK_TOLERANCE * largest)) if largest > 0 else 0

    def _jacobian(self, q: np.ndarray, t: float) -> np.ndarray:
        if self._jacobian_of is not None:
            return self._jacobian_of(q)
        return self.model.constraint_values(q, self._zero, t).jacobian

    def _singular_values(self, q: np.ndarray, t: float) -> np.ndarray:
        """G's singular values at (q, t), NaN when G is not finite (a diverging run: its checks report it)."""
        jacobian = self._jacobian(q, t)
        try:
            if np.isfinite(jacobian).all():
                return np.linalg.svd(jacobian, compute_uv=False)
        except np.linalg.LinAlgError:  # entries too large for the SVD to converge
            pass
        return np.full(min(jacobian.shape), np.nan)

    def relative(self, q: np.ndarray, t: float) -> float:
        """sigma_r / sigma_1 of G at (q, t) [-] (r the generic rank)."""
        if self._relative is not None:
            start, self._start = self._start, None
            if start is not None and np.array_equal(start[0], q):  # the first sample, at the start: known
                return start[1]
            return self._relative(q, self.rank)
        values = self._singular_values(q, t)
        return float(values[self.rank - 1] / values[0]) if values[0] > 0 else math.nan

    def rank_at(self, q: np.ndarray, t: float) -> int:
        """The rank of G at (q, t) with :data:`RANK_TOLERANCE`."""
        values = self._singular_values(q, t)
        return int(np.sum(values > RANK_TOLERANCE * values[0])) if values[0] > 0 else 0

    def tangent(self, q: np.ndarray, t: float) -> np.ndarray:
        """An orthonormal basis of ker G at (q, t) of the generic dimension nv - r (nv x (nv - r)): the last columns
        of a complete QR factorization of G^T when the rows are independent at the start (r = rows: G^T's
        columns span its first r, a fifth of an SVD's cost), else the SVD's right singular vectors."""
        jacobian = self._jacobian(q, t)
        if self.rank == jacobian.shape[0] and np.isfinite(jacobian).all():
            return _trailing_q(jacobian.T)
        _, _, right = np.linalg.svd(jacobian)
        return right[self.rank :].T


def _trailing_q(matrix: np.ndarray) -> np.ndarray:
    """The last m - n columns of Q in the complete QR factorization of ``matrix`` (m x n, m >= n): LAPACK's
    Householder reflectors (``dgeqrf``) applied to those unit vectors (``dormqr``), without forming Q."""
    rows, columns = matrix.shape
    factors, reflectors, _, _ = lapack.dgeqrf(matrix)
    unit = np.zeros((rows, rows - columns), order="F")
    unit[columns:] = np.eye(rows - columns)
    basis, _, _ = lapack.dormqr("L", "N", factors, reflectors, unit, lwork=max(1, 64 * (rows - columns)))
    return basis


def _parabola_roots(samples: list[tuple[float, float, np.ndarray]], origin: float) -> list[float]:
    """The real roots, as times after ``origin`` [s], of the parabola through three samples (t, s, q): its
    coefficients from divided differences (what a degree-2 least-squares fit through three points is, without
    the fit's SVD), the roots by the cancellation-free quadratic formula."""
    (x0, y0, _), (x1, y1, _), (x2, y2, _) = ((t - origin, value, q) for t, value, q in samples)
    first, second = (y1 - y0) / (x1 - x0), (y2 - y1) / (x2 - x1)
    a = (second - first) / (x2 - x0)
    b = first - a * (x0 + x1)
    c = y0 - x0 * (first - a * x1)
    if a == 0.0:
        return [-c / b] if b != 0.0 else []
    discriminant = b * b - 4.0 * a * c
    if discriminant < 0.0:
        return []
    q = -0.5 * (b + math.copysign(math.sqrt(discriminant), b))
    return [q / a] + ([c / q] if q != 0.0 else [])


def _least(level: Callable[[float], float], t0: float, t1: float, h: float) -> tuple[float, float]:
    """(least value, its time [s]) of s = ``level`` >= 0 on [t0, t1] to :data:`LOCATE_TOLERANCE` of the step h [s].

    Near a simple crossing s^2 = a^2 (t - t*)^2 + c^2 is a parabola (s itself is a V, on which Brent's search
    falls back to golden sections): successive parabolic interpolation of s^2 through its three lowest samples (from
    the step's quarters) converges superlinearly (at most 14 evaluations, ``tests/test_passages.py``). It ends when
    the vertex moves less than the tolerance, or when the samples lie within :data:`ROUNDING_SPAN` of the step and
    the last one did not lower the least (s is resolved to rounding there). Where the samples fall towards one end of
    the step (the vertex beyond it, or no upward curve), that end is sampled, and is the least when they keep falling
    towards it. Brent's bounded search on s^2 in any other case."""
    tolerance = LOCATE_TOLERANCE * h
    samples = {t: level(t) ** 2 for t in (t0 + 0.25 * (t1 - t0), 0.5 * (t0 + t1), t0 + 0.75 * (t1 - t0))}
    vertex = math.inf
    for _ in range(VERTEX_ITERATIONS):
        by_value = sorted(samples, key=samples.__getitem__)
        least, lowest = by_value[0], sorted(by_value[:3])
        (x0, y0), (x1, y1), (x2, y2) = ((x, samples[x]) for x in lowest)
        clustered = x2 - x0 <= ROUNDING_SPAN * h
        slope_left, slope_right = (y1 - y0) / (x1 - x0), (y2 - y1) / (x2 - x1)
        curvature = (slope_right - slope_left) / (x2 - x0)
        previous, vertex = vertex, 0.5 * (x0 + x1) - slope_left / (2 * curvature) if curvature > 0 else math.nan
        if clustered and not t0 <= vertex <= t1:
            return math.sqrt(samples[least]), least
        if not t0 <= vertex <= t1:  # falling towards an end of the step
            end = t0 if least == x0 else t1 if least == x2 else None
            if end is None or end in samples:
                if end == least:
                    return math.sqrt(samples[end]), end
                break
            samples[end] = level(end) ** 2
            continue
        settled = abs(vertex - previous) <= tolerance or min(abs(vertex - x) for x in lowest) <= tolerance
        samples[vertex] = level(vertex) ** 2
        if settled or (clustered and samples[vertex] >= samples[least]):
            least = min(samples, key=samples.__getitem__)
            return math.sqrt(samples[least]), least
    found = minimize_scalar(lambda t: level(t) ** 2, bounds=(t0, t1), method="bounded", options={"xatol": tolerance})
    return math.sqrt(float(found.fun)), float(found.x)


def tangent_turn(before: np.ndarray, after: np.ndarray) -> float:
    """The largest principal angle between the spans of two orthonormal bases [rad] (from its sine, which
    stays accurate for small angles)."""
    if before.shape[1] == 0:
        return 0.0
    residue = before - after @ (after.T @ before)
    # its spectral norm from the small (d x d) Gram matrix, without an SVD of the nv x d residue
    return float(math.asin(min(1.0, math.sqrt(max(float(np.linalg.eigvalsh(residue.T @ residue)[-1]), 0.0)))))


class PassageWatch:
    """Samples s, predicts crossings, plans steps around them and reports the passages.

    Args:
        model: the constrained model.
        q: the start configuration.
        nodes: the integrator's stage times as shares of a step.
        step: the run's step [s] (fixed-step runs) or a first estimate (adaptive runs).
        relative, jacobian: see :class:`Conditioning`.
    """

    def __init__(
        self,
        model: ConstrainedModel,
        q: np.ndarray,
        nodes: Sequence[float],
        step: float,
        relative: Callable[[np.ndarray, int], float] | None = None,
        jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.conditioning = Conditioning(model, q, relative, jacobian)
        self.active = self.conditioning.rank > 0
        self.points = np.array(sorted({0.0, 1.0, *(float(c) for c in nodes)}))
        self.centre, half_width = node_gap(self.points)
        self.margin = half_width / 2
        self.step = step
        self.samples: list[tuple[float, float, np.ndarray]] = []  # the last three: (t, s, q)
        self.fastest = 0.0  # [1/s] the fastest change of s seen between two samples
        self.next_due = 0.0 if self.active else math.inf
        self.passages: list[Passage] = []

    # -- sampling ------------------------------------------------------------------------------------
    def due(self, t: float) -> bool:
        """Whether s should be sampled at time t [s]."""
        return self.active and t >= self.next_due

    def sample(self, t: float, q: np.ndarray, step: float | None = None) -> None:
        """Sample s at (q, t) and schedule the next sample (``step``: the current step [s], when it varies)."""
        if step is not None:
            self.step = step
        value = self.conditioning.relative(q, t)
        if not math.isfinite(value):
            self.next_due = t + self.step
            return
        previous = self.samples[-1] if self.samples else None
        self.samples = [*self.samples[-2:], (t, value, q.copy())]
        gap = self.step
        if previous is not None and t > previous[0]:
            elapsed = t - previous[0]
            self.fastest = max(self.fastest, abs(value - previous[1]) / elapsed)
            if value < previous[1]:
                remaining = value * elapsed / (previous[1] - value)
                gap = APPROACH_SHARE * remaining
            else:
                gap = 2.0 * elapsed
            if self.fastest > 0:  # s could fall as fast as it has ever changed: a rise is no promise
                gap = min(gap, APPROACH_SHARE * value / self.fastest)
        # (less a sliver of a step, so that a sample due at a grid time is not missed by rounding)
        self.next_due = t + min(max(gap, self.step), SAMPLE_CAP * self.step) - 1e-6 * self.step

    def crossing(self) -> float | None:
        """The time [s] where s, falling through the last samples, reaches zero: on the line through the last
        two, or earlier on the parabola through the last three when s falls faster and faster (the line
        alone would predict the crossing late and let a step straddle it unplanned); None when s is not
        falling."""
        if len(self.samples) < 2:
            return None
        (t0, s0, _), (t1, s1, _) = self.samples[-2:]
        if not s1 < s0 or t1 <= t0:
            return None
        linear = t1 + s1 * (t1 - t0) / (s0 - s1)
        if len(self.samples) < 3 or not self.samples[0][1] > s0:
            return linear
        ahead = [root for root in _parabola_roots(self.samples, t1) if root > 0]
        return min([linear, *(t1 + root for root in ahead)])

    def snapshot(self) -> tuple:
        """The watch's state, for :meth:`restore` (a replayed chunk plans as the first pass did)."""
        return list(self.samples), self.next_due, len(self.passages), self.fastest

    def restore(self, state: tuple) -> None:
        """Return to a :meth:`snapshot`."""
        samples, self.next_due, count, self.fastest = state
        self.samples = list(samples)
        del self.passages[count:]

    # -- planning ------------------------------------------------------------------------------------
    def plan(self, start: float, step: float, next_grid: Callable[[float], float]) -> Plan | None:
        """Steps that keep every stage away from a crossing predicted within :data:`HORIZON` steps of
        ``start`` [s], or None for the regular step of ``step`` [s].

        The crossing t* is placed at the centre of the widest gap between stage times of a step of
        ``step`` (shorter when t* is closer than that); a step up to its start and one from its end to the
        next grid time (``next_grid(t)``: the first grid time at or after t) complete the plan.
        """
        crossing = self.crossing()
        if crossing is None or not start < crossing < start + HORIZON * step:
            return None
        slack = 1e-6 * step  # grid times are k dt: start + step may exceed the next one by rounding
        if self._clear(start, step, crossing) or crossing - start < self.margin * step:
            # the regular step; when it straddles the crossing, it is located like a planned one
            end = next_grid(start + step - slack)
            return Plan([end], 0) if crossing < end and end >= start + step - slack else None
        begin = max(start, crossing - self.centre * step)
        length = step if begin > start else (crossing - start) / self.centre
        ends = [begin] if begin > start + slack else []
        end = begin + length
        ends.append(end)
        straddle = len(ends) - 1
        grid = next_grid(end - slack)
        if grid < end - slack:  # the run ends inside the straddling step
            return None
        if grid > end + slack:
            ends.append(grid)
        return Plan(ends, straddle)

    def limit(self, start: float, step: float) -> tuple[float, bool]:
        """The step [s] to take from ``start`` [s] instead of ``step`` (a step of error-controlled length) so
        that no stage falls next to a predicted crossing, and whether that step straddles the crossing: the
        crossing at the centre of the widest gap between stage times of a step no longer than ``step``, or a
        shorter step first that ends where the next one of ``step`` will place it there."""
        crossing = self.crossing()
        if crossing is None or not start < crossing < start + HORIZON * step:
            return step, False
        if self._clear(start, step, crossing) or crossing - start < self.margin * step:
            return step, crossing < start + step
        straddle = (crossing - start) / self.centre
        if straddle <= step:
            return straddle, True
        return crossing - self.centre * step - start, False

    def _clear(self, start: float, length: float, crossing: float) -> bool:
        """Whether every stage time of a step of ``length`` [s] from ``start`` [s] is at least the margin
        (a share of the step) away from the crossing time [s]."""
        share = (crossing - start) / length
        return bool(np.min(np.abs(self.points - share)) >= self.margin)

    # -- after a planned step ------------------------------------------------------------------------
    def locate(self, segment: Segment, q_start: np.ndarray, q_end: np.ndarray) -> Passage | None:
        """Locate the least s on the dense output of a step that straddled a predicted crossing, check the
        branch, and record the passage when s fell below :data:`PASSAGE_LEVEL`; returns it (or None)."""
        conditioning = self.conditioning

        def level(t: float) -> float:
            return conditioning.relative(segment.state(t)[0], t)

        least, t_min = _least(level, segment.t0, segment.t1, segment.h)
        if not least < PASSAGE_LEVEL:
            return None
        if self.passages and t_min - self.passages[-1].t < HORIZON * segment.h:  # the same dip, seen twice
            if least >= self.passages[-1].min_relative_singular_value:
                return None
            self.passages.pop()
        before = conditioning.tangent(q_start, segment.t0)
        after = conditioning.tangent(q_end, segment.t1)
        turn = tangent_turn(before, after)
        expected = self._turn_rate(segment.t0, before) * segment.h
        passage = Passage(
            t=t_min,
            min_relative_singular_value=least,
            rank=conditioning.rank_at(segment.state(t_min)[0], t_min),
            generic_rank=conditioning.rank,
            branch_kept=turn <= max(BRANCH_ANGLE, BRANCH_FACTOR * expected),
            tangent_turn=turn,
            expected_turn=expected,
        )
        self.passages.append(passage)
        if not passage.branch_kept:
            warnings.warn(
                BranchChangeWarning(
                    f"at t = {t_min:.6g} s the motion left its branch at a singular configuration (smallest "
                    f"relative singular value of G {least:.2g}, rank {passage.rank} of {conditioning.rank}): its "
                    f"tangent space turned by {turn:.3g} rad across the passage, {expected:.2g} rad expected; "
                    "reduce dt or use --method projection"
                ),
                stacklevel=2,
            )
        return passage

    def _turn_rate(self, t: float, tangent: np.ndarray) -> float:
        """How fast ker G turned before time t [rad/s]: from the latest sample before t."""
        earlier = [(ts, qs) for ts, _, qs in self.samples if ts < t]
        if not earlier:
            return 0.0
        ts, qs = earlier[-1]
        return tangent_turn(self.conditioning.tangent(qs, ts), tangent) / (t - ts)

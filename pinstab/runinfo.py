"""What a run reports besides its samples: ``RunInfo`` (scene, method, integrator, solver, step, end
time, constraint layout, assembly report, solver statistics). It round-trips through the JSON of
``pinstab run --json`` and the NPZ trajectory files."""

from __future__ import annotations

import json
import math
import types
import typing
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from typing import Any

from .errors import PinstabError


@dataclass
class SolverStatistics:
    """Counts and worst residuals over a run's KKT solves.

    Attributes:
        solves: KKT solves. status_counts: solves per backend status (e.g. ``PROXQP_SOLVED``).
        iterations_total, iterations_max: the backend's iterations (0 for direct factorizations).
        worst_primal_residual: largest ``|G a - rhs|`` relative to the size of its terms [-].
        worst_dual_residual: largest ``|M a - f - G^T lambda|`` relative to its terms [-] (backends
            that satisfy it by construction, dense elimination, do not measure it).
        fallbacks: solves handed to a rank-robust backend after this one missed the constraints.
    """

    solves: int = 0
    status_counts: dict[str, int] = field(default_factory=dict)
    iterations_total: int = 0
    iterations_max: int = 0
    worst_primal_residual: float = 0.0
    worst_dual_residual: float = 0.0
    fallbacks: int = 0

    def record(self, status: str, iterations: int, primal: float, dual: float) -> None:
        """Add one solve."""
        self.solves += 1
        self.status_counts[status] = self.status_counts.get(status, 0) + 1
        self.iterations_total += iterations
        self.iterations_max = max(self.iterations_max, iterations)
        if math.isfinite(primal):
            self.worst_primal_residual = max(self.worst_primal_residual, primal)
        if math.isfinite(dual):
            self.worst_dual_residual = max(self.worst_dual_residual, dual)


@dataclass(frozen=True)
class AssemblySummary:
    """The assembly of the initial state: LM iterations, residual [m or rad], velocity residual
    [m/s or rad/s], displacement from the declared configuration (tangent norm), the residual accepted
    (tolerance) [m or rad] and the mechanism's size [m] it is relative to (None in older saved runs)."""

    iterations: int
    residual: float
    velocity_residual: float
    displacement: float
    tolerance: float | None = None
    size: float | None = None


@dataclass
class RunInfo:
    """Everything a run reports besides its samples.

    Attributes:
        scene, method, integrator, solver: names. dt: step [s]. t_end: simulated end time [s].
        steps: steps taken. parameters: the method's options. solver_options: the solver's.
        scene_parameters: generator parameters of the scene.
        constraint_rows: constraint name -> [first row, last row + 1].
        row_kinds: constraint name -> ``equality`` | ``unilateral`` | ``cone``.
        force_frames: constraint name -> the frame its multipliers are expressed in.
        assembly: the assembly of the initial state, or None when it was skipped.
        solver_statistics: the KKT solves of the run.
        path: ``native`` (Pinocchio's own algorithm evaluated the dynamics), ``banded`` (a chain of point
            closures solved by a banded LU, :mod:`pinstab.paths.banded`), ``servo`` (prescribed joint relations
            solved compiled, :mod:`pinstab.paths.servo`) or ``general`` (pinstab's kinematics and KKT backend; see
            :mod:`pinstab.system`). path_reason: why ``general``, or why ``banded`` or ``servo``.
        record_every: a sample was kept every this many steps (and at the last).
        compiled_steps: steps taken by the compiled step loop with a compiled evaluation (``pinstab._compiled``, on
            the native, banded, servo and core paths; :mod:`pinstab.integration.compiled`); the loop takes the other
            steps too, calling the evaluation back in Python, but for a correcting method's (``projection``,
            ``post``), a shortened last step, a passage's and a registered integrator's own steps.
        controls: the names of the controls that realize prescribed constraints (``[actuation]``).
        correction_iterations_total, correction_iterations_max: post-step correction iterations over
            every step (projection, post).
        passages: the singular passages of the run, each a
            :class:`~pinstab.integration.passages.Passage` as a dict.
        contact_events: with event-driven contacts, every switch of a contact's mode
            (:class:`~pinstab.contact.modes.ContactEvent` as a dict: time, contact, from, to, cause, force,
            slip velocity, impulse).
        error_control: with rtol/atol, the tolerances and the accepted and rejected steps
            (:meth:`~pinstab.integration.adaptive.ErrorControl.summary`); None for fixed steps.
        newton: with an implicit integrator, what its Newton iteration did (``newton_iterations``: iterations, one
            evaluation each; ``jacobian_evaluations``; ``lu_factorizations``; ``newton_failures``: stages not
            solved even globalized, under error control each retried with a shorter step;
            ``globalized_iterations``: Newton iterations with a Jacobian at the iterate, taken when the simplified
            iteration does not converge; ``continuation_shares``: the shares s < 1 of a stage their continuation
            solved on the way to s = 1); None otherwise.
        stopped: why the run ended before its duration, with the samples up to then: ``reason`` (``slip``
            or ``separation``: an event it was asked to stop on, with ``contact`` and ``event``; ``contact
            failure``: contacts with no solution, with ``error``, the error's class, and ``message``) and
            ``t`` [s]; None when it ran to the end.
        limits_active_s: with joint limits on, how long each limit was held [s] by name (``panda_joint4
            upper``), empty when none was reached; None with limits off or a model without limits.
        timings: the wall time of the :func:`~pinstab.simulate` call split [s]: ``setup_s`` (checks, system,
            assembly, kernels), ``stepping_s`` (the stepping loops), ``post_s`` (the trajectory, its drift and
            energy series, a streamed run's derived series); they add up to the trajectory's ``wall_time``. Empty in
            files saved before it was kept.
        cut_short: a run read back from a file whose run was cut short before its end (a streamed run interrupted
            by Ctrl-C or SIGTERM, or killed): ``t`` [s] and ``step`` of its last sample written, ``cause``
            (``interrupted``: its final info was written; ``killed``: the info is its start's, with ``t_end`` and
            ``steps`` from its samples); None otherwise.
        contact_treatment: how contacts were treated (:class:`~pinstab.simulate.choice.ContactChoice` as a dict:
            ``treatment``, ``chosen``, ``why``); None for a scene without contacts.
        integrator_choice: with ``integrator="auto"``, the integrator ``picked``, the ``reason`` and the ``stiff_mode``
            it was picked by (element, frequency [rad/s], eigenvalue (re, im) [1/s], step_limit [s]; None without
            one) (:mod:`pinstab.simulate.integrator_choice`); None otherwise.
    """

    scene: str
    method: str
    integrator: str
    solver: str
    dt: float
    t_end: float = 0.0
    steps: int = 0
    parameters: dict[str, Any] = field(default_factory=dict)
    solver_options: dict[str, Any] = field(default_factory=dict)
    scene_parameters: dict[str, Any] = field(default_factory=dict)
    constraint_rows: dict[str, list[int]] = field(default_factory=dict)
    row_kinds: dict[str, str] = field(default_factory=dict)
    force_frames: dict[str, str] = field(default_factory=dict)
    assembly: AssemblySummary | None = None
    solver_statistics: SolverStatistics = field(default_factory=SolverStatistics)
    path: str = "general"
    path_reason: str = ""
    record_every: int = 1
    compiled_steps: int = 0
    correction_iterations_total: int = 0
    correction_iterations_max: int = 0
    controls: list[str] = field(default_factory=list)
    passages: list[dict[str, Any]] = field(default_factory=list)
    error_control: dict[str, Any] | None = None
    newton: dict[str, int] | None = None
    contact_events: list[dict[str, Any]] = field(default_factory=list)
    stopped: dict[str, Any] | None = None
    limits_active_s: dict[str, float] | None = None
    timings: dict[str, float] = field(default_factory=dict)
    cut_short: dict[str, Any] | None = None
    contact_treatment: dict[str, Any] | None = None
    integrator_choice: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (nested dataclasses as dicts)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunInfo:
        """The inverse of :meth:`to_dict`.

        Raises:
            PinstabError: not a dict, a key missing or unknown, or a value of the wrong type (naming the field).
        """
        if not isinstance(data, dict):
            raise PinstabError(f"run info: a JSON object of fields, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise PinstabError(f"run info: unknown field {unknown[0]!r}")
        values = dict(data)
        for name, value in values.items():
            _check_type(name, value, RUN_INFO_TYPES[name])
        try:
            if values.get("assembly") is not None:
                values["assembly"] = AssemblySummary(**values["assembly"])
            values["solver_statistics"] = SolverStatistics(**values.get("solver_statistics", {}))
            return cls(**values)
        except TypeError as exc:
            raise PinstabError(f"run info: {exc}") from None

    @classmethod
    def from_json(cls, text: str | bytes, source: str) -> RunInfo:
        """The run info saved as JSON in the file ``source`` (:meth:`to_dict`).

        Raises:
            PinstabError: not JSON, or not a run info (:meth:`from_dict`); the message names ``source``.
        """
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise PinstabError(f"{source}: the run info is not JSON ({exc})") from None
        try:
            return cls.from_dict(data)
        except PinstabError as exc:
            raise PinstabError(f"{source}: {exc}") from None


RUN_INFO_TYPES = typing.get_type_hints(RunInfo)


def _check_type(name: str, value: Any, hint: Any) -> None:
    """Refuse a value read back from JSON that does not have the type ``hint`` of field ``name`` (a dataclass: its
    fields; a dict or list: its entries), naming the field and the entry."""
    origin, arguments = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        options = [option for option in arguments if option is not type(None)]
        if value is not None:
            _check_type(name, value, options[0])
        return
    if hint is Any:
        return
    if is_dataclass(hint):
        _check_type(name, value, dict[str, Any])
        nested = typing.get_type_hints(hint)
        for key, entry in value.items():
            if key in nested:  # an unknown one is refused by the dataclass
                _check_type(f"{name}.{key}", entry, nested[key])
        return
    kinds = {float: (int, float), int: (int,), str: (str,), dict: (dict,), list: (list,)}[origin or hint]
    if isinstance(value, bool) or not isinstance(value, kinds):
        words = {float: "a number", int: "an integer", str: "a string", dict: "a JSON object", list: "a list"}
        raise PinstabError(f"run info: {name} must be {words[origin or hint]}, got {json.dumps(value)[:60]}")
    if origin is dict:
        for key, entry in value.items():
            _check_type(f"{name}[{key!r}]", entry, arguments[1])
    elif origin is list:
        for index, entry in enumerate(value):
            _check_type(f"{name}[{index}]", entry, arguments[0])

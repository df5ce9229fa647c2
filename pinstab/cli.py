"""The ``pinstab`` command line: ``check`` a scene, ``run`` a simulation, analyse a ``grasp``, map
``stability``.

Exit codes (:data:`EXIT_CODES`): 0 success, 2 bad input (message, no traceback), 3 divergence (any blow-up,
whatever the solver; with ``--json`` the figures up to the last finite state; ``--save`` writes the partial
trajectory), 4 stopped at a contact event asked for with ``--stop-on``, 5 contacts with no solution during the run
(held contacts that cannot hold, a lost grasp, Painleve's paradox), 130 Ctrl-C and 143 SIGTERM (one line;
``--save`` writes the partial trajectory). With 4 and 5 the run's JSON, ``--save`` file, ``--plot`` chart and
recording are written up to the stop. A closed stdout (``| head``) ends quietly.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, nullcontext
from typing import Any

import numpy as np

from . import __version__
from .analysis import check_coordinates, check_reference, trajectory_error
from .bench.workprecision import MUJOCO_DTS, PEER_DTS, RTOLS
from .contact.modes import STOP_KINDS
from .errors import (
    ContactInfeasibleError,
    DivergenceError,
    PinstabError,
    ProjectionError,
    SceneError,
    UnstableGainsWarning,
)
from .files import check_output
from .integration import INTEGRATORS
from .memory import memory_limit
from .registry import Registry, option_fields
from .simulate import EVENT_RTOL, MAX_EVENT_CONTACTS, MIN_RTOL
from .solvers import SOLVERS
from .stability_map import map_methods
from .stabilizers import STABILIZERS

EXIT_OK, EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_SIGNAL_BASE = 0, 2, 3, 128  # a signal: 128 + its number
EXIT_STOPPED = 4  # the run ended at a contact event asked for with --stop-on
EXIT_CONTACT_FAILED = 5  # contacts with no solution during the run (ContactInfeasibleError: a lost grasp, Painleve)
EXIT_CODES = (
    f"exit codes: {EXIT_OK} success; {EXIT_BAD_INPUT} bad input (a message, no traceback); {EXIT_DIVERGED} divergence "
    f"(--json: the figures up to the last finite state, --save: the trajectory up to there); {EXIT_STOPPED} stopped at "
    f"the contact event asked for with --stop-on; {EXIT_CONTACT_FAILED} contacts with no solution during the run "
    f"(held contacts that cannot hold, a lost grasp, Painleve's paradox); with {EXIT_STOPPED} and "
    f"{EXIT_CONTACT_FAILED} the JSON, --save, --plot and the recording hold the run up to the stop; 130 Ctrl-C, 143 "
    "SIGTERM (--save: the trajectory so far)"
)
DEFAULT_METHOD = "baumgarte"
CONTACTS = ("event", "stepping", "held")  # --contacts; held: the constraint rows of simulate(contacts=None)
HELD_ONLY = ("method", "integrator", "solver")  # run options that --contacts event has no use for
SIMULATING = ("run", "record", "servo")  # the commands that run a simulation (and may stop at an event)
EVENT_ROWS = 20  # contact events listed in text output (all of them in the JSON)
METHOD_OPTION, SOLVER_OPTION = "method_option_", "solver_option_"  # argparse dest prefixes


class Kept(Exception):
    """A run that failed once started (``error``) whose outputs up to the failure were written (``result``)."""

    def __init__(self, error: PinstabError, result: dict[str, Any]) -> None:
        super().__init__(str(error))
        self.error, self.result = error, result


def _parameters(pairs: list[str]) -> dict[str, Any]:
    """``--param N=20`` -> {"N": 20} (values read as TOML scalars: ints, floats, strings)."""
    import tomllib

    parsed: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise SceneError(f"--param expects NAME=VALUE, got {pair!r}")
        if key in parsed:
            raise SceneError(f"--param {key} given twice ({key}={parsed[key]!r} and {pair!r}); give it once")
        try:
            parsed[key] = tomllib.loads(f"x = {value}")["x"]
        except tomllib.TOMLDecodeError:
            parsed[key] = value
    return parsed


def _scene_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "scene", help="bundled scene name (fourbar, nfourbar, allegro-sphere, ...: see README) or a .toml file"
    )
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="scene generator parameter, e.g. N=20"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument(
        "--memory-limit",
        metavar="SIZE",
        help="refuse work whose estimated memory exceeds SIZE, e.g. 4GB, 512MiB (default: 80%% of the memory "
        "available at the start)",
    )


def _add_registry_options(parser: argparse.ArgumentParser, registry: Registry, prefix: str) -> None:
    """One flag per option of the registry's entries (shared by entries with the same option), its
    help naming the entries that take it; only flags given on the command line reach the namespace."""
    flags: dict[str, list] = {}
    for entry in registry.entries():
        for option in option_fields(entry.options):
            flags.setdefault(option.flag, []).append((entry.name, option))
    group = parser.add_argument_group(f"{registry.kind} options")
    for flag, users in flags.items():
        option = users[0][1]
        described = "; ".join(f"{name}: {item.help}" for name, item in users)
        common = dict(dest=prefix + option.name, default=argparse.SUPPRESS, help=described)
        if option.kind is bool:
            group.add_argument(flag, action="store_false" if option.default else "store_true", **common)
        else:
            metavar = None if option.choices else option.name.upper()
            group.add_argument(flag, type=option.kind, choices=option.choices, metavar=metavar, **common)


def _given_options(args: argparse.Namespace, prefix: str) -> dict[str, Any]:
    """The registry options given on the command line (their flags' dests carry ``prefix``)."""
    return {key[len(prefix) :]: value for key, value in vars(args).items() if key.startswith(prefix)}


def _listed(registry: Registry) -> str:
    """Each registered entry with its one-line summary, for a flag's help."""
    return "; ".join(f"{entry.name}: {entry.summary}" if entry.summary else entry.name for entry in registry.entries())


def _run_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--contacts",
        choices=CONTACTS,
        help=f"how contacts are treated: event (modes sticking, sliding, separated switched at located events, "
        f"with impacts; error-controlled dop853, --rtol default {EVENT_RTOL:g}), stepping (time-stepping with "
        "impulses), held (constraint rows that hold, with --method, --integrator, --solver). Default: event for "
        f"scenes whose constraints are plane contacts, at most {MAX_EVENT_CONTACTS}; held otherwise",
    )
    parser.add_argument(
        "--stop-on",
        action="append",
        choices=STOP_KINDS,
        help="end the run at the first such contact event (exit 4; repeat for both): slip, a contact at rest "
        "starts sliding; separation, a touching contact opens (after an impact too). The outputs hold the run "
        "up to it",
    )
    parser.add_argument(
        "--method",
        default=None,
        choices=STABILIZERS,
        metavar="METHOD",
        help=f"stabilization method (default: {DEFAULT_METHOD}). {_listed(STABILIZERS)}",
    )
    parser.add_argument(
        "--integrator",
        default=None,
        choices=INTEGRATORS,
        metavar="INTEGRATOR",
        help=f"integrator (default: rk4; dop853 with --rtol). {_listed(INTEGRATORS)}",
    )
    parser.add_argument(
        "--solver",
        default=None,
        choices=SOLVERS,
        metavar="SOLVER",
        help=(
            "KKT backend (default: Pinocchio's own algorithm where the scene and method allow it, else "
            f"proxsuite; naming one keeps every evaluation on it). {_listed(SOLVERS)}"
        ),
    )
    parser.add_argument(
        "--dt", type=float, default=1e-3, help="time step [s]; with --rtol the step of the samples (default: 1e-3)"
    )
    parser.add_argument(
        "--rtol",
        type=float,
        help="error control: steps chosen by the embedded pair's error estimate (dopri5, dop853) to this "
        "relative tolerance, samples every --dt from its dense output",
    )
    parser.add_argument("--atol", type=float, help="absolute tolerance of the error control (default: --rtol)")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated time [s] (default: 1)")
    _add_registry_options(parser, STABILIZERS, METHOD_OPTION)
    _add_registry_options(parser, SOLVERS, SOLVER_OPTION)
    parser.add_argument("--strict", action="store_true", help="refuse gains predicted unstable instead of warning")
    parser.add_argument(
        "--drift-limit",
        type=float,
        default=1.0,
        help="position drift [m or rad] that counts as divergence (default: 1)",
    )
    parser.add_argument(
        "--record-every",
        type=int,
        default=1,
        metavar="K",
        help="keep a sample every K steps and the last (default: 1, every step)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pinstab",
        description="Constrained multibody simulation with measurable constraint stabilization.",
        epilog=EXIT_CODES,
    )
    parser.add_argument("--version", action="version", version=f"pinstab {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    check = sub.add_parser("check", help="assemble a scene and report its constraint structure")
    _scene_arguments(check)

    grasp = sub.add_parser("grasp", help="analyse a scene's grasps: grasp map, hand Jacobian, force closure, quality")
    _scene_arguments(grasp)
    grasp.add_argument(
        "--facets", type=int, default=8, help="sides of the pyramids that linearize the friction cones (default: 8)"
    )
    grasp.add_argument(
        "--squeeze",
        type=float,
        help="largest normal force per contact [N] for the largest load and tilt (default: the scene's grasp-hold)",
    )
    grasp.add_argument(
        "--tilt-axis",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="world axis of the hand's tilt (default: the two horizontal world axes)",
    )

    servo = sub.add_parser(
        "servo",
        help="realize a scene's prescribed constraints: controls, constraint error, reactions",
        epilog=EXIT_CODES,
    )
    _scene_arguments(servo)
    _run_options(servo)
    servo.add_argument(
        "--check", action="store_true", help="only check at the start that the controls can realize them"
    )
    servo.add_argument("--save", metavar="FILE.npz", help="save the trajectory")
    servo.add_argument("--plot", metavar="FILE.png", help="chart drift, energy error, constraint forces and controls")

    run = sub.add_parser("run", help="simulate a scene and report drift and energy", epilog=EXIT_CODES)
    _scene_arguments(run)
    _run_options(run)
    run.add_argument("--save", metavar="FILE.npz", help="save the trajectory")
    run.add_argument("--plot", metavar="FILE.png", help="chart drift, energy error and constraint forces")
    run.add_argument(
        "--reference",
        metavar="exact|RUN.npz",
        help="report the trajectory error against the scene's exact motion (exact: fourbar, nfourbar) or a "
        "saved run of the same scene (--save of a finer or another method)",
    )
    run.add_argument(
        "--error-of",
        action="append",
        metavar="NAME",
        help="coordinate whose error --reference reports: a joint [rad or m], a frame's origin [m] or 'joints' "
        "(the largest joint error); repeat for several (default: the exact reference's crank, else joints)",
    )

    record = sub.add_parser(
        "record", help="simulate and write a standalone HTML recording (or stream it live)", epilog=EXIT_CODES
    )
    _scene_arguments(record)
    _run_options(record)
    record.add_argument("-o", "--output", metavar="OUT.html", help="the recording to write")
    record.add_argument("--fps", type=float, default=30.0, help="frames per second of the recording (default: 30)")
    record.add_argument("--live", action="store_true", help="stream to a meshcat server on 127.0.0.1 instead")

    plot = sub.add_parser("plot", help="chart a saved run (drift, energy error, constraint forces)")
    plot.add_argument("run_file", metavar="RUN.npz")
    plot.add_argument("-o", "--output", metavar="OUT.png", required=True)
    plot.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    bench = sub.add_parser("bench", help="work-precision sweep with peers, overhead and scaling; charts and tables")
    bench.add_argument("scene", help="bundled scene name or a .toml file")
    bench.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="scene generator parameter")
    bench.add_argument(
        "--methods", nargs="+", default=["baumgarte", "mukharlyamov", "projection", "pinocchio"], choices=STABILIZERS
    )
    bench.add_argument(
        "--integrators", nargs="+", default=["semi-implicit-euler", "rk4", "dop853"], choices=INTEGRATORS
    )
    bench.add_argument("--dts", nargs="+", type=float, default=[4e-3, 2e-3, 1e-3], help="pinstab's steps [s]")
    for flag, steps, whose in (
        ("--peer-dts", PEER_DTS, "the hand-written Pinocchio loop's steps [s]"),
        ("--mujoco-dts", MUJOCO_DTS, "MuJoCo's steps [s], each with solref 2 dt"),
        ("--rtols", RTOLS, "tolerances of the error-controlled runs, pinstab's dop853 --rtol and SciPy's DOP853"),
    ):
        listed = ", ".join(f"{dt:g}" for dt in steps)
        bench.add_argument(flag, nargs="+", type=float, default=list(steps), help=f"{whose} (default: {listed})")
    bench.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (default: 2)")
    bench.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for results.json/.csv and charts")
    bench.add_argument(
        "--scheduler", metavar="ADDRESS", help="join a Dask scheduler (tcp://host:port); default: local cluster"
    )
    bench.add_argument("--serial", action="store_true", help="run in this process instead of on Dask")
    bench.add_argument(
        "--tolerance", type=float, default=1e-6, help="trajectory error for the cost comparison [rad, m]"
    )
    bench.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    bench.add_argument("--quiet", action="store_true", help="no progress bar")

    stability = sub.add_parser("stability", help="map observed vs predicted stability over a (dt, gain) grid")
    _scene_arguments(stability)
    stability.add_argument(
        "--method", default="baumgarte", choices=map_methods(), help="a method with gains kp, kd (default: baumgarte)"
    )
    stability.add_argument(
        "--integrator", default="semi-implicit-euler", choices=INTEGRATORS, help="(default: semi-implicit-euler)"
    )
    stability.add_argument(
        "--dt-range",
        nargs=2,
        type=float,
        default=[1e-4, 3e-2],
        metavar=("A", "B"),
        help="steps [s] (default: 1e-4 3e-2)",
    )
    stability.add_argument(
        "--gain-range",
        nargs=2,
        type=float,
        default=[1e2, 1e9],
        metavar=("C", "D"),
        help="Kp [1/s^2], Kd = 2 sqrt(Kp) (default: 1e2 1e9)",
    )
    stability.add_argument("--grid", type=int, default=40, help="cells per axis (default: 40)")
    stability.add_argument("--steps", type=int, default=200, help="steps per run (default: 200)")
    stability.add_argument("--perturbation", type=float, default=0.01, help="initial violation [rad] (default: 0.01)")
    stability.add_argument(
        "--solver", default="dense", choices=SOLVERS, help="KKT backend of the runs (default: dense)"
    )
    stability.add_argument("-o", "--output", metavar="MAP.png", help="write the map as a PNG")
    stability.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    args = build_parser().parse_args(argv)
    received: list[int] = []
    with _terminate_as_interrupt(received):
        try:
            return _dispatch(args)
        except KeyboardInterrupt as exc:
            return _interrupted(exc, args, received[0] if received else signal.SIGINT)


@contextmanager
def _terminate_as_interrupt(received: list[int]) -> Iterator[None]:
    """SIGTERM (``kill``, a batch system's time limit) ends a command the way Ctrl-C does: temporary files
    removed, the partial trajectory saved; the signal's number is appended to ``received``."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum: int, frame) -> None:
        received.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _dispatch(args: argparse.Namespace) -> int:
    """Run the command and print its result or its error; returns the exit code."""
    try:
        limit = getattr(args, "memory_limit", None)
        with warnings.catch_warnings(), nullcontext() if limit is None else memory_limit(limit):
            warnings.simplefilter("always", UnstableGainsWarning)
            warnings.showwarning = _show_warning(args.command)
            result = COMMANDS[args.command](args)
    except Kept as kept:
        _fail(kept.error, args, kept.result.get("saved"))
        if getattr(args, "json", False):
            _write(json.dumps(_clean(kept.result)))
        return EXIT_CONTACT_FAILED
    except (DivergenceError, ProjectionError) as exc:
        _fail(exc, args, _save_partial(args, getattr(exc, "finite_trajectory", None)))
        return EXIT_DIVERGED
    except PinstabError as exc:
        _fail(exc, args)
        return EXIT_BAD_INPUT
    _emit(result, args)
    stopped = result.get("stopped")
    if stopped is None or args.command not in SIMULATING:
        return EXIT_OK
    print(f"pinstab {args.command}: stopped (--stop-on): {stopped_text(stopped)}", file=sys.stderr)
    return EXIT_STOPPED


def stopped_text(stopped: dict[str, Any]) -> str:
    """``info.stopped`` in words: what, when [s], which contact and how its mode changed."""
    event = stopped.get("event")
    if event is None:
        return f"{stopped['reason']} at t = {stopped['t']:.9g} s ({stopped['error']})"
    change = f"{event['from']} -> {event['to']} ({event['cause']})"
    return f"{stopped['reason']} at t = {stopped['t']:.9g} s: contact {event['contact']} {change}"


def _show_warning(command: str):
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"pinstab {command}: warning: {message}", file=sys.stderr, flush=True)

    return show


def _interrupted(exc: KeyboardInterrupt, args: argparse.Namespace, signum: int) -> int:
    """Ctrl-C (SIGINT) or SIGTERM: one line on stderr, the partial trajectory saved when ``--save`` was given;
    exit 128 + the signal's number (130, 143)."""
    trajectory = getattr(exc, "trajectory", None)
    where = "" if trajectory is None else f" at t = {trajectory.t[-1]:.6g} s (step {trajectory.steps})"
    saved = _save_partial(args, trajectory)
    kept = f"; the partial trajectory is saved to {saved}" if saved else ""
    cause = "interrupted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"
    print(f"pinstab {args.command}: {cause}{where}{kept}", file=sys.stderr)
    return EXIT_SIGNAL_BASE + signum


def _save_partial(args: argparse.Namespace, trajectory) -> str | None:
    """Save a stopped run's partial trajectory to ``--save``, if given; returns the path written or None."""
    path = getattr(args, "save", None)
    if path is None or trajectory is None:
        return None
    try:
        trajectory.save(path)
    except (PinstabError, OSError) as exc:
        print(f"pinstab {args.command}: error: the partial trajectory was not saved: {exc}", file=sys.stderr)
        return None
    return path


def _fail(exc: PinstabError, args: argparse.Namespace, saved: str | None = None) -> None:
    """The error on stderr; with ``--json``, a divergence's figures on stdout (:func:`_divergence_payload`)."""
    print(f"pinstab {args.command}: error: {exc}", file=sys.stderr)
    if saved is not None:
        print(f"pinstab {args.command}: the partial trajectory is saved to {saved}", file=sys.stderr)
    if getattr(args, "json", False) and isinstance(exc, (DivergenceError, ProjectionError)):
        _write(json.dumps(_clean(_divergence_payload(exc, args, saved))))


def _divergence_payload(
    exc: DivergenceError | ProjectionError, args: argparse.Namespace, saved: str | None
) -> dict[str, Any]:
    """A stopped run's JSON: the run's figures up to the last finite state, ``diverged_at`` [s] (the failed
    step's time) and ``last_finite_state`` (t [s], q, v)."""
    trajectory = getattr(exc, "finite_trajectory", None)
    payload = {"scene": args.scene} if trajectory is None else _run_summary(args, trajectory)
    payload.update(diverged=True, error=str(exc))
    if isinstance(exc, DivergenceError):
        payload["diverged_at"] = exc.diverged_at
        payload["last_finite_state"] = {"t": exc.time, "q": np.asarray(exc.q).tolist(), "v": np.asarray(exc.v).tolist()}
    if saved is not None:
        payload["saved"] = saved
    return payload


def _write(text: str) -> None:
    """Print ``text`` on stdout; a reader that closed it (``| head``) ends the output quietly: stdout is
    pointed at /dev/null so that the interpreter's last flush does not fail again."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def _emit(result: dict[str, Any], args: argparse.Namespace) -> None:
    if args.json:
        _write(json.dumps(_clean(result)))
        return
    if args.command in TEXT_FORMATS:
        _write(TEXT_FORMATS[args.command](result))
        return
    shown = {key: value for key, value in result.items() if key != "contact_events"}
    if shown.get("stopped"):
        shown["stopped"] = stopped_text(shown["stopped"])
    width = max(len(k) for k in shown)
    lines = [f"{key:<{width}}  {f'{value:.6g}' if isinstance(value, float) else value}" for key, value in shown.items()]
    _write("\n".join(lines + events_table(result.get("contact_events") or [])))


def events_table(events: list[dict[str, Any]], rows: int = EVENT_ROWS) -> list[str]:
    """The first ``rows`` contact events as text lines (time [s], contact, from -> to, cause, normal force [N],
    slip speed [m/s]), and how many more there are; no lines without events."""
    if not events:
        return []
    lines = [
        f"contact events ({len(events)}):",
        f"  {'t [s]':>14}  {'contact':<12} {'from -> to':<24} {'f_n [N]':>10}  {'slip [m/s]':>10}  cause",
    ]
    for event in events[:rows]:
        change = f"{event['from']} -> {event['to']}"
        lines.append(
            f"  {event['t']:>14.9g}  {event['contact']:<12} {change:<24} {event['force'][0]:>10.4g}  "
            f"{float(np.hypot(*event['slip_velocity'])):>10.3g}  {event['cause']}"
        )
    if len(events) > rows:
        lines.append(f"  ... and {len(events) - rows} more (all of them in --json)")
    return lines


def _clean(value: Any) -> Any:
    """JSON-safe: numpy scalars to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _check(args: argparse.Namespace) -> dict[str, Any]:
    from .assembly import assemble
    from .model import ConstrainedModel
    from .scene import load_scene

    scene = load_scene(args.scene, **_parameters(args.param))
    model = ConstrainedModel(scene)
    report = assemble(model, scene.q0, scene.v0)
    values = model.constraint_values(report.q, report.v, 0.0)
    rows = model.constraints.rows
    if rows:
        singular_values = np.linalg.svd(values.jacobian, compute_uv=False)
        rank = int(np.sum(singular_values > 1e-9 * max(singular_values[0], 1.0)))
    else:
        rank = 0
    return {
        "scene": scene.name,
        "nq": scene.model.nq,
        "nv": scene.model.nv,
        "rows": rows,
        "rank": rank,
        "redundant": rows - rank,
        "mobility": scene.model.nv - rank,
        "assembly_residual": report.residual,
        "assembly_iterations": report.iterations,
        "assembly_velocity_residual": report.velocity_residual,
        "constraints": {
            c.name: {"rows": c.rows, "holonomic": c.holonomic, "kind": c.row_kind.value, "frame": c.force_frame}
            for c in scene.constraints
        },
        "locked_joints": scene.locked_joints,
    }


def _grasp(args: argparse.Namespace) -> dict[str, Any]:
    from .grasp.report import analyse_scene_grasps
    from .scene import load_scene

    scene = load_scene(args.scene, **_parameters(args.param))
    grasps = analyse_scene_grasps(scene, facets=args.facets, squeeze=args.squeeze, tilt_axis=args.tilt_axis)
    return {"scene": scene.name, "objects": {name: grasp.to_json() for name, grasp in grasps.items()}}


def _grasp_text(result: dict[str, Any]) -> str:
    """``pinstab grasp`` without ``--json``: each object's figures as lines a person reads."""
    return "\n".join(_object_grasp_text(name, figures) for name, figures in result["objects"].items())


def _object_grasp_text(name: str, figures: dict[str, Any]) -> str:
    rows, columns = figures["grasp_map_shape"]
    unresisted = figures["unresisted_wrench"]
    closure = "yes" if figures["force_closure"] else f"no (unresisted wrench {np.round(unresisted, 3).tolist()})"
    lines = [
        f"object {name}: {len(figures['contacts'])} contacts "
        + ", ".join(f"{c} ({v['model']})" for c, v in figures["contacts"].items()),
        f"  grasp map G: {rows} x {columns}, rank {figures['grasp_map_rank']}, "
        f"smallest singular value {figures['smallest_singular_value']:.4g}",
        f"  hand Jacobian J_h: {' x '.join(map(str, figures['hand_jacobian_shape']))}, rank "
        f"{figures['hand_jacobian_rank']}, manipulable: {'yes' if figures['manipulable'] else 'no'}",
        f"  force closure: {closure}",
        f"  internal forces: dimension {figures['internal_force_dimension']}",
        f"  quality (Ferrari-Canny, length {figures['quality_length_m']:.4g} m): {figures['quality']:.4g} N",
        *_capacity_text(figures),
    ]
    return "\n".join(lines)


def _capacity_text(figures: dict[str, Any]) -> list[str]:
    """The squeeze the weight needs, the largest load and the tilts, as lines (JSON nulls: none holds)."""
    need = figures["squeeze_needed_n"]
    lines = [
        f"  weight {figures['load_n']:.4g} N: "
        + ("no contact forces inside the cones hold it" if need is None else f"squeeze needed {need:.4g} N per contact")
    ]
    if figures["squeeze_n"] is not None:
        largest = figures["largest_load_n"]
        tilts = ", ".join(
            f"{axis} {'any' if tilt is None else f'{tilt:.4g}'}"
            for axis, tilt in figures["first_slip_tilt_deg"].items()
        )
        lines.append(
            f"  at squeeze {figures['squeeze_n']:.4g} N: largest load "
            + ("unbounded" if largest is None else f"{largest:.4g} N")
            + f"; first slip at tilt [deg] {tilts}"
        )
    return lines


def _servo(args: argparse.Namespace) -> dict[str, Any]:
    from .assembly import assemble
    from .scene import load_scene
    from .system import build_system

    scene = load_scene(args.scene, **_parameters(args.param))
    if not any(c.prescribed for c in scene.constraints):
        raise SceneError(f"scene {scene.name} has no prescribed constraints ([[servos]]) to realize")
    if args.check:
        system = build_system(scene, args.method or DEFAULT_METHOD)
        start = assemble(system.model, scene.q0, scene.v0)
        evaluation = system.dynamics(start.q, start.v, 0.0)  # raises ServoInfeasibleError when it cannot
        decoupling = system.servo.decoupling(system.model.kin.mass_matrix, evaluation.values.jacobian)[0]
        return {
            "scene": scene.name,
            "realizable": True,
            "decoupling_singular_values": np.linalg.svd(decoupling, compute_uv=False).tolist(),
            "controls_at_start": dict(zip(scene.actuation.names, evaluation.controls.tolist(), strict=True)),
        }
    return _run(args, _add_reactions)


def _add_reactions(scene, trajectory, result: dict[str, Any]) -> None:
    """The largest reaction of the real constraints over the run [N, N m] (prescribed rows have none)."""
    reactions = trajectory.multipliers[:, ~scene.constraint_set.prescribed_mask]
    result["max_reaction"] = float(np.nanmax(np.abs(reactions))) if reactions.size else 0.0


TEXT_FORMATS = {"grasp": _grasp_text}


def _simulate(args: argparse.Namespace, before: Callable[[Any], None] | None = None):
    """Load the scene, check it with ``before(scene)`` when given, and simulate it with the run options;
    returns (scene, trajectory, failure): a run that failed once started (ContactInfeasibleError) returns its
    partial trajectory and the error."""
    from .scene import load_scene
    from .simulate import simulate

    scene = load_scene(args.scene, **_parameters(args.param))
    if before is not None:
        before(scene)
    contacts = _contacts(args, scene)
    adaptive = args.rtol is not None or args.atol is not None
    try:
        trajectory = simulate(
            scene,
            method=args.method or DEFAULT_METHOD,
            integrator=args.integrator or ("dop853" if adaptive else "rk4"),
            rtol=args.rtol,
            atol=args.atol,
            dt=args.dt,
            duration=args.duration,
            solver=args.solver,
            solver_options=_given_options(args, SOLVER_OPTION),
            strict=args.strict,
            drift_limit=args.drift_limit,
            progress=not args.quiet,
            record_every=args.record_every,
            contacts=contacts,
            stop_on=tuple(args.stop_on or ()),
            **_given_options(args, METHOD_OPTION),
        )
    except ContactInfeasibleError as exc:
        if getattr(exc, "trajectory", None) is None:  # before the run started: the scene, not the run
            raise
        return scene, exc.trajectory, exc
    return scene, trajectory, None


def _contacts(args: argparse.Namespace, scene) -> str | None:
    """The contact treatment of ``simulate`` (None: held rows): ``--contacts``, else the scene's default
    (:func:`~pinstab.simulate.default_contacts`). Refuses the held contacts' options with ``event`` and
    ``--stop-on`` without it."""
    from .simulate import default_contacts

    contacts = default_contacts(scene) if args.contacts is None else args.contacts
    contacts = None if contacts == "held" else contacts
    if contacts == "event":
        given = [f"--{name}" for name in HELD_ONLY if getattr(args, name) is not None]
        given += [f"--{name.replace('_', '-')}" for name in _given_options(args, METHOD_OPTION)]
        given += [f"--{name.replace('_', '-')}" for name in _given_options(args, SOLVER_OPTION)]
        if given:
            chosen = "--contacts event" if args.contacts else f"scene {scene.name}'s default, event"
            raise PinstabError(
                f"{', '.join(given)}: the contacts are event-driven ({chosen}): their modes are integrated by "
                "error-controlled dop853 (--rtol), without a stabilization method or KKT backend; give --contacts "
                "held to hold the contacts as constraint rows with these options"
            )
    if args.stop_on and contacts != "event":
        treatment = "held as constraint rows" if contacts is None else f"{contacts}"
        raise PinstabError(
            f"--stop-on {' '.join(args.stop_on)} ends a run at a contact event, which event-driven contacts locate "
            f"(--contacts event); scene {scene.name}'s contacts are {treatment} here"
        )
    return contacts


def _run_summary(args: argparse.Namespace, trajectory) -> dict[str, Any]:
    """The figures of a run (or of a stopped run's samples) that ``run --json`` prints."""
    info = trajectory.info
    return {
        "scene": info.scene,
        "method": info.method,
        "integrator": info.integrator,
        "solver": info.solver,
        "dt": info.dt,
        "duration": args.duration,
        **trajectory.summary(),
        "diverged": False,
        "parameters": info.parameters,
        "path": info.path,
        "path_reason": info.path_reason,
        "record_every": info.record_every,
    }


def _run(args: argparse.Namespace, add=None) -> dict[str, Any]:
    """Simulate, summarize (``add(scene, trajectory, result)`` adds figures), save and chart when asked."""
    from .viz.plots import plot_trajectory

    if args.save:
        check_output(args.save, ".npz", "trajectory")
    if args.plot:
        check_output(args.plot, ".png", "chart")
    reference = getattr(args, "reference", None)
    if reference is None and getattr(args, "error_of", None):
        raise PinstabError("--error-of names what --reference compares: give --reference exact or RUN.npz")
    scene, trajectory, failure = _simulate(
        args, None if reference is None else lambda scene: _check_reference(args, scene)
    )
    result = _run_summary(args, trajectory)
    if add is not None:
        add(scene, trajectory, result)
    if reference is not None:
        trajectory.comparison = trajectory_error(trajectory, reference, args.error_of, scene)
        result["trajectory_error"] = trajectory.comparison.summary(trajectory.t)
    if args.save:
        trajectory.save(args.save)
        result["saved"] = args.save
    if args.plot:
        plot_trajectory(trajectory, args.plot, scene)
        result["plot"] = args.plot
    return _ended(result, failure)


def _ended(result: dict[str, Any], failure: PinstabError | None) -> dict[str, Any]:
    """``result``, or :class:`Kept` raised with it (and the error's message) when the run failed once started."""
    if failure is None:
        return result
    result["error"] = str(failure)
    raise Kept(failure, result)


def _check_reference(args: argparse.Namespace, scene) -> None:
    """Refuse --reference and --error-of before the run (a scene without an exact motion, a bad file, an
    unknown coordinate)."""
    check_reference(args.reference, scene)
    check_coordinates(scene.model, args.error_of or ())


def _record(args: argparse.Namespace) -> dict[str, Any]:
    import time

    from .model import ConstrainedModel
    from .viz.recording import check_frames, play_live, write_recording

    if not args.live and not args.output:
        raise PinstabError("record: give -o OUT.html for a recording, or --live to stream to a meshcat viewer")
    if args.output:
        check_output(args.output, ".html", "recording")
    check_frames(args.duration, args.fps)
    start = time.perf_counter()
    scene, trajectory, failure = _simulate(args)
    model = ConstrainedModel(scene)
    result = _run_summary(args, trajectory)
    if args.live:
        result["live_url"] = play_live(model, trajectory, fps=args.fps)
    if args.output:
        recording = write_recording(model, trajectory, args.output, fps=args.fps)
        result.update(
            recording=str(recording.path),
            size_bytes=recording.size_bytes,
            frames=recording.frames,
            fps=recording.fps,
            force_scale=recording.force_scale,
        )
    result["record_wall_s"] = time.perf_counter() - start
    return _ended(result, failure)


def _plot(args: argparse.Namespace) -> dict[str, Any]:
    from .trajectory import Trajectory
    from .viz.plots import plot_trajectory

    check_output(args.output, ".png", "chart")
    trajectory = Trajectory.load(args.run_file)
    plot_trajectory(trajectory, args.output)
    info = trajectory.info
    return {
        "run": args.run_file,
        "plot": args.output,
        "steps": trajectory.steps,
        "t_end": float(trajectory.t[-1]),
        "stopped": info.stopped,
        "contact_events": info.contact_events,
    }


def _bench(args: argparse.Namespace) -> dict[str, Any]:
    from pathlib import Path

    from .bench.overhead import measure_overhead
    from .bench.scaling import scaling
    from .bench.workprecision import (
        cheapest_table,
        check_tolerance,
        default_configs,
        make_output_folder,
        sweep,
        write_outputs,
    )
    from .scene import load_scene

    parameters = _parameters(args.param)
    scene = load_scene(args.scene, **parameters)  # validates the scene before any work
    for flag, steps in (("--dts", args.dts), ("--peer-dts", args.peer_dts), ("--mujoco-dts", args.mujoco_dts)):
        for dt in steps:
            if not dt > 0:
                raise PinstabError(f"{flag}: steps must be positive, got {dt}")
    for rtol in args.rtols:
        if not MIN_RTOL <= rtol < 1:
            raise PinstabError(f"--rtols: tolerances must be in [{MIN_RTOL:g}, 1), got {rtol}")
    check_tolerance(args.tolerance)
    out_dir = Path(args.output)
    make_output_folder(out_dir)
    configs = default_configs(
        args.methods,
        args.integrators,
        sorted(args.dts),
        peer_dts=tuple(sorted(args.peer_dts)),
        mujoco_dts=tuple(sorted(args.mujoco_dts)),
        rtols=tuple(sorted(args.rtols)),
    )
    reference, results = sweep(
        str(scene.source or args.scene), parameters, configs, args.duration, args.scheduler, args.serial, not args.quiet
    )
    extra: dict[str, Any] = {"duration": args.duration, "tolerance": args.tolerance}
    extra["cheapest"] = cheapest_table(results, args.tolerance)
    extra["overhead"] = measure_overhead(scene)
    extra["overhead_ratio"] = extra["overhead"]["overhead_ratio"]
    if scene.parameters and "N" in scene.parameters and scene.name == "nfourbar":
        extra["scaling"] = scaling()
        extra["scaling_exponent"] = extra["scaling"]["scaling_exponent"]
    summary = write_outputs(out_dir, scene.name, reference, results, extra)
    if not args.json:
        return {k: v for k, v in summary.items() if k not in ("results", "overhead", "scaling")} | {
            "output": str(out_dir)
        }
    return summary


def _stability(args: argparse.Namespace) -> dict[str, Any]:
    from .scene import load_scene
    from .stability_map import plot_stability_map, stability_map

    if args.output:
        check_output(args.output, ".png", "chart")
    scene = load_scene(args.scene, **_parameters(args.param))
    result = stability_map(
        scene,
        method=args.method,
        integrator=args.integrator,
        dt_range=tuple(args.dt_range),
        gain_range=tuple(args.gain_range),
        grid=args.grid,
        steps=args.steps,
        perturbation=args.perturbation,
        solver=args.solver,
        progress=not args.quiet,
    )
    if args.output:
        plot_stability_map(result, args.output)
    payload = result.to_json()
    if not args.json:
        counts = {name: sum(c.observed == name for c in result.cells) for name in ("converged", "bounded", "diverged")}
        payload = {k: v for k, v in payload.items() if k != "cells"} | counts
    if args.output:
        payload["map"] = args.output
    return payload


COMMANDS = {
    "check": _check,
    "grasp": _grasp,
    "servo": _servo,
    "run": _run,
    "record": _record,
    "plot": _plot,
    "stability": _stability,
    "bench": _bench,
}


if __name__ == "__main__":
    sys.exit(main())

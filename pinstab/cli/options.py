"""Arguments that several commands share: the scene and its parameters, the run options, registry flags."""

from __future__ import annotations

import argparse
import re
from typing import Any

from ..contact.modes import STOP_KINDS
from ..errors import SceneError
from ..integration import INTEGRATORS
from ..registry import Registry, option_fields
from ..simulate import AUTO, ERROR_CONTROLLED_INTEGRATOR, EVENT_RTOL, FIXED_STEP_INTEGRATOR, MAX_EVENT_CONTACTS
from ..solvers import SOLVERS
from ..stabilizers import STABILIZERS
from ..tables import toml_scalar

DEFAULT_METHOD = "baumgarte"
CONTACTS = ("event", "stepping", "held")  # --contacts; held: the constraint rows of simulate(contacts="held")
METHOD_OPTION, SOLVER_OPTION = "method_option_", "solver_option_"  # argparse dest prefixes
# a word that starts with a minus and a digit, ``-1,0,0``, ``-1e-3``: a value, not an option
NEGATIVE_VALUE = re.compile(r"^-\.?\d[\w.,+-]*$")


class Parser(argparse.ArgumentParser):
    """argparse's parser that reads a word starting with a minus and a digit as a value (:data:`NEGATIVE_VALUE`):
    ``--tilt-axis -1,0,0``, which argparse alone takes for an unknown option. Its sub-parsers are of this class."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE  # argparse's test for "-1", "-.5", without commas


def _numbers(text: str) -> list[float]:
    """``-1,0,0`` (or one number) -> [-1.0, 0.0, 0.0]."""
    try:
        return [float(item) for item in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or comma-separated numbers") from None


class _Vector(argparse.Action):
    """The three numbers of ``X,Y,Z`` (one word: ``--flag=-1,0,0`` too) or ``X Y Z``, as a list."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        flat = [number for value in values for number in value]
        if len(flat) != 3:
            raise argparse.ArgumentError(self, f"expects three numbers, X,Y,Z or X Y Z; got {len(flat)}")
        setattr(namespace, self.dest, flat)


def vector_argument(parser: argparse.ArgumentParser, flag: str, help: str) -> None:
    """``flag X,Y,Z`` (also ``flag=X,Y,Z``, ``flag X Y Z``; negative numbers too): a 3-vector, as a list of floats."""
    parser.add_argument(flag, nargs="+", type=_numbers, action=_Vector, metavar="X,Y,Z", help=help)


def output_argument(parser: argparse.ArgumentParser, metavar: str, help: str, required: bool = False) -> None:
    """``-o``/``--out``/``--output`` (``args.output``): the file or folder a command writes, the same spelling in
    every command."""
    parser.add_argument("-o", "--out", "--output", dest="output", metavar=metavar, required=required, help=help)


def common_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every command takes: ``--quiet``."""
    parser.add_argument(
        "--quiet", action="store_true", help="no progress bar on stderr (a command without one prints the same)"
    )


def parameters(pairs: list[str]) -> dict[str, Any]:
    """``--param N=20`` -> {"N": 20} (values read as TOML scalars: ints, floats, strings)."""
    parsed: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise SceneError(f"--param expects NAME=VALUE, got {pair!r}")
        if key in parsed:
            raise SceneError(f"--param {key} given twice ({key}={parsed[key]!r} and {pair!r}); give it once")
        parsed[key] = toml_scalar(value)
    return parsed


def scene_arguments(parser: argparse.ArgumentParser) -> None:
    """The scene (bundled name or file), ``--param``, ``--keyframe``, ``--json`` and ``--memory-limit``."""
    parser.add_argument(
        "scene",
        help="bundled scene name (fourbar, nfourbar, allegro-sphere, ...: see docs/guide/scenes.md) or a .toml file",
    )
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="scene generator parameter, e.g. N=20"
    )
    parser.add_argument(
        "--keyframe",
        metavar="NAME",
        help="start from this keyframe of the robot's MJCF file (default: the scene's robot.keyframe, else the first)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    memory_limit_argument(parser)


def scene_options(args: argparse.Namespace) -> dict[str, Any]:
    """:func:`~pinstab.scene.load_scene`'s keywords from :func:`scene_arguments`: ``--param``'s and ``--keyframe``."""
    return {**parameters(args.param), "keyframe": args.keyframe}


def memory_limit_argument(parser: argparse.ArgumentParser) -> None:
    """``--memory-limit SIZE``: the memory budget of the command's work (``args.memory_limit``)."""
    parser.add_argument(
        "--memory-limit",
        metavar="SIZE",
        help="refuse work whose estimated memory exceeds SIZE, e.g. 4GB, 512MiB (default: 80%% of the memory "
        "available at the start)",
    )


def limits_argument(parser: argparse.ArgumentParser) -> None:
    """``--ignore-limits``: run (or check) without the robot's joint limits, whose start is then not checked."""
    parser.add_argument(
        "--ignore-limits",
        action="store_true",
        help="ignore the robot's joint limits (default: held as one-sided constraints with impacts, the start inside "
        "them; a run that reaches one is run by the event path, reported in limits_active_s and the events)",
    )


def assembly_argument(parser: argparse.ArgumentParser) -> None:
    """``--assembly-tol``: the closure residual the assembly accepts, relative to the mechanism's size."""
    parser.add_argument(
        "--assembly-tol",
        type=float,
        metavar="TOL",
        help="closure residual the assembly accepts, relative to the mechanism's size (the diagonal of the box "
        "holding its joints and frames), in (0, 1) (default: the scene's [assembly] tolerance, else 1e-10)",
    )


def assembly_tolerance(args: argparse.Namespace) -> float | None:
    """``--assembly-tol`` checked (a SceneError naming the flag when it is not in (0, 1)), or None."""
    from ..validation import relative_tolerance

    return None if args.assembly_tol is None else relative_tolerance(args.assembly_tol, "--assembly-tol")


def add_registry_options(parser: argparse.ArgumentParser, registry: Registry, prefix: str) -> None:
    """One flag per option of the registry's entries (shared by entries with the same option), its
    help naming the entries that take it; only flags given on the command line reach the namespace. A boolean flag
    stores the opposite of its default, False when named ``--no-...`` (a default of None: decided at run time)."""
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
            stores_false = option.default or flag.startswith("--no-")
            group.add_argument(flag, action="store_false" if stores_false else "store_true", **common)
        else:
            metavar = None if option.choices else option.name.upper()
            group.add_argument(flag, type=option.kind, choices=option.choices, metavar=metavar, **common)


def given_options(args: argparse.Namespace, prefix: str) -> dict[str, Any]:
    """The registry options given on the command line (their flags' dests carry ``prefix``)."""
    return {key[len(prefix) :]: value for key, value in vars(args).items() if key.startswith(prefix)}


def _listed(registry: Registry) -> str:
    """Each registered entry with its one-line summary, for a flag's help."""
    return "; ".join(f"{entry.name}: {entry.summary}" if entry.summary else entry.name for entry in registry.entries())


def stream_argument(parser: argparse.ArgumentParser) -> None:
    """``--stream FILE.h5``: the samples written to an HDF5 file as the run proceeds, not kept in memory."""
    parser.add_argument(
        "--stream",
        metavar="FILE.h5",
        help="write the samples to this HDF5 file as the run proceeds (memory bounded whatever the duration; "
        "readable while it runs and after a kill; needs h5py: pip install 'pinstab[stream]'); read it with "
        "pinstab plot, pinstab record --from or Trajectory.load",
    )


def run_options(parser: argparse.ArgumentParser) -> None:
    """The options of the commands that simulate: contacts, method, integrator, solver, steps, tolerances."""
    parser.add_argument(
        "--contacts",
        choices=CONTACTS,
        help=f"how contacts are treated: event (modes sticking, sliding, separated switched at located events, "
        f"with impacts; error-controlled dop853, --rtol default {EVENT_RTOL:g}), stepping (time-stepping with "
        "impulses), held (constraint rows that hold, with --method, --integrator, --solver). Default: the scene's "
        "[run] contacts, else event where every contact has modes and they are the only constraints "
        f"(time-stepping beyond {MAX_EVENT_CONTACTS} declared ones), held otherwise; the run's JSON says which and "
        "why (contact_treatment)",
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
        choices=[*INTEGRATORS, AUTO],
        metavar="INTEGRATOR",
        help=f"integrator (default: {FIXED_STEP_INTEGRATOR}; {ERROR_CONTROLLED_INTEGRATOR} with --rtol or --atol; "
        f"{AUTO}: that default, or an implicit one when the step is above its stability limit of a force element's "
        f"stiff mode at the start, said in the JSON's integrator_choice). {_listed(INTEGRATORS)}",
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
        "--dt",
        type=float,
        help="time step [s]; with --rtol the step of the samples (default: the scene's [run] dt, else 1e-3)",
    )
    parser.add_argument(
        "--rtol",
        type=float,
        help="error control: steps chosen by the embedded pair's error estimate (dopri5, dop853, esdirk4) to this "
        "relative tolerance, samples every --dt from its dense output",
    )
    parser.add_argument("--atol", type=float, help="absolute tolerance of the error control (default: --rtol)")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated time [s] (default: 1)")
    add_registry_options(parser, STABILIZERS, METHOD_OPTION)
    add_registry_options(parser, SOLVERS, SOLVER_OPTION)
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
    limits_argument(parser)
    assembly_argument(parser)

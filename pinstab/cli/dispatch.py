"""Parse the command line, run the command, print its result or its error, and return the exit code."""

from __future__ import annotations

import _thread
import argparse
import json
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from typing import Any

import numpy as np

from .. import __version__
from ..errors import (
    DivergenceError,
    MemoryBudgetError,
    PinstabError,
    ProjectionError,
    StiffStepError,
    UnstableGainsWarning,
)
from ..memory import exhausted, memory_limit
from .commands import COMMANDS, SIMULATING
from .exits import (
    EXIT_BAD_INPUT,
    EXIT_CODES,
    EXIT_CONTACT_FAILED,
    EXIT_DIVERGED,
    EXIT_OK,
    EXIT_POINTS_FAILED,
    EXIT_SIGNAL_BASE,
    EXIT_STOPPED,
    Kept,
)
from .options import Parser, common_arguments
from .output import clean, emit, json_only_stdout, stopped_text, write
from .running import run_summary


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``pinstab`` with a sub-parser per registered command."""
    parser = Parser(
        prog="pinstab",
        description="Constrained multibody simulation with measurable constraint stabilization.",
        epilog=EXIT_CODES,
    )
    parser.add_argument("--version", action="version", version=f"pinstab {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in sorted(COMMANDS.values(), key=lambda c: c.order):
        command_parser = sub.add_parser(command.name, help=command.help)
        command.arguments(command_parser)
        common_arguments(command_parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    args = build_parser().parse_args(argv)
    received: list[int] = []
    with _terminate_as_interrupt(received), json_only_stdout() if getattr(args, "json", False) else nullcontext():
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
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _redeliver(received, previous_hook)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        sys.unraisablehook = previous_hook


def _redeliver(received: list[int], previous):
    """An unraisable-exception hook: a signal's KeyboardInterrupt raised while Python ran a destructor or a weakref
    callback is swallowed there ("Exception ignored in ..."), and the run would go on; the signal is delivered again
    to the main thread instead (SIGINT when none was recorded), 10 ms later from a helper thread: delivered at once
    it would be handled inside this hook, where it is swallowed as well."""

    def hook(unraisable) -> None:
        if not issubclass(unraisable.exc_type, KeyboardInterrupt):
            previous(unraisable)
            return
        signum = received[-1] if received else signal.SIGINT
        threading.Timer(0.01, _thread.interrupt_main, (signum,)).start()

    return hook


def _dispatch(args: argparse.Namespace) -> int:
    """Run the command and print its result or its error; returns the exit code."""
    try:
        limit = getattr(args, "memory_limit", None)
        with warnings.catch_warnings(), nullcontext() if limit is None else memory_limit(limit):
            warnings.simplefilter("always", UnstableGainsWarning)
            warnings.showwarning = _show_warning(args.command)
            try:
                result = COMMANDS[args.command].execute(args)
            except MemoryError as error:
                raise exhausted(f"pinstab {args.command} {getattr(args, 'scene', '')}".rstrip(), error) from None
    except Kept as kept:
        _fail(kept.error, args, kept.result.get("saved"))
        if getattr(args, "json", False):
            write(json.dumps(clean(kept.result)))
        return EXIT_CONTACT_FAILED
    except (DivergenceError, ProjectionError) as exc:
        _fail(exc, args, _save_partial(args, getattr(exc, "finite_trajectory", None)))
        return EXIT_DIVERGED
    except MemoryBudgetError as exc:  # a run that ran out of memory keeps its samples up to then
        _fail(exc, args, _save_partial(args, exc.trajectory))
        return EXIT_BAD_INPUT
    except PinstabError as exc:
        _fail(exc, args)
        return EXIT_BAD_INPUT
    command = COMMANDS[args.command]
    emit(result, args.json, command.text)
    stopped = result.get("stopped")
    if stopped is not None and args.command in SIMULATING and not getattr(args, "run_file", None):  # --from: read
        print(f"pinstab {args.command}: stopped (--stop-on): {stopped_text(stopped)}", file=sys.stderr)
        return EXIT_STOPPED
    failed = None if command.failures is None else command.failures(result)
    if failed is None:
        return EXIT_OK
    print(f"pinstab {args.command}: {failed}", file=sys.stderr)
    return EXIT_POINTS_FAILED


def _show_warning(command: str):
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"pinstab {command}: warning: {message}", file=sys.stderr, flush=True)

    return show


def _interrupted(exc: KeyboardInterrupt, args: argparse.Namespace, signum: int) -> int:
    """Ctrl-C (SIGINT) or SIGTERM: one line on stderr, the partial trajectory saved when ``--save`` was given;
    exit 128 + the signal's number (130, 143)."""
    trajectory = getattr(exc, "trajectory", None)
    where = "" if trajectory is None else f" at t = {trajectory.info.t_end:.6g} s (step {trajectory.steps})"
    saved = _save_partial(args, trajectory)
    kept = f"; the partial trajectory is saved to {saved}" if saved else ""
    streamed = getattr(trajectory, "path", None)
    kept += f"; the samples so far are in {streamed}" if streamed else ""
    kept += f"; {exc.kept}" if getattr(exc, "kept", None) else ""  # work that stops after its pieces in flight
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
        write(json.dumps(clean(_divergence_payload(exc, args, saved))))


def _divergence_payload(
    exc: DivergenceError | ProjectionError, args: argparse.Namespace, saved: str | None
) -> dict[str, Any]:
    """A stopped run's JSON: the run's figures up to the last finite state (NaN, null in the JSON, where they cannot
    be had: a servo's controls at a state whose dynamics are not finite, :data:`pinstab.series.NO_DYNAMICS`),
    ``diverged_at`` [s] (the failed step's time) and ``last_finite_state`` (t [s], q, v); for a stiff mode's
    divergence ``stiff_mode``: its force element, frequency [rad/s], eigenvalue (re, im) [1/s], step limit [s]."""
    trajectory = getattr(exc, "finite_trajectory", None)
    payload: dict[str, Any] = {"scene": args.scene} if trajectory is None else run_summary(args, trajectory)
    payload.update(diverged=True, error=str(exc))
    if isinstance(exc, DivergenceError):
        payload["diverged_at"] = exc.diverged_at
        payload["last_finite_state"] = {"t": exc.time, "q": np.asarray(exc.q).tolist(), "v": np.asarray(exc.v).tolist()}
    if isinstance(exc, StiffStepError):
        payload["stiff_mode"] = {
            "element": exc.element,
            "frequency": exc.frequency,
            "eigenvalue": [exc.eigenvalue.real, exc.eigenvalue.imag],
            "step_limit": exc.limit,
        }
    if saved is not None:
        payload["saved"] = saved
    return payload

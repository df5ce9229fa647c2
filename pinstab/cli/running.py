"""Simulating a scene with the run options, and the figures of a run: shared by ``run``, ``servo`` and
``record``."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from ..errors import ContactInfeasibleError, PinstabError, ServoInfeasibleError
from ..simulate import HELD_ONLY
from .exits import Kept
from .options import DEFAULT_METHOD, METHOD_OPTION, SOLVER_OPTION, assembly_tolerance, given_options, scene_options


def simulate_scene(args: argparse.Namespace, before: Callable[[Any], None] | None = None, scene: Any = None):
    """Load the scene (unless ``scene`` is the one already loaded), check it with ``before(scene)`` when given, and
    simulate it with the run options; returns (scene, trajectory, failure): a run that failed once started
    (ContactInfeasibleError, ServoInfeasibleError after t = 0 s) returns its partial trajectory and the error."""
    from ..scene import load_scene
    from ..simulate import simulate

    if scene is None:
        scene = load_scene(args.scene, **scene_options(args))
    if before is not None:
        before(scene)
    contacts = _contacts(args, scene)
    try:
        trajectory = simulate(
            scene,
            method=args.method or DEFAULT_METHOD,
            integrator=args.integrator,  # None: simulate()'s default_integrator, dop853 with --rtol/--atol
            rtol=args.rtol,
            atol=args.atol,
            dt=args.dt,
            duration=args.duration,
            solver=args.solver,
            solver_options=given_options(args, SOLVER_OPTION),
            strict=args.strict,
            drift_limit=args.drift_limit,
            progress=not args.quiet,
            record_every=args.record_every,
            contacts=contacts,
            stop_on=tuple(args.stop_on or ()),
            assembly_tol=assembly_tolerance(args),
            limits=not args.ignore_limits,
            stream=getattr(args, "stream", None),
            **given_options(args, METHOD_OPTION),
        )
    except (ContactInfeasibleError, ServoInfeasibleError) as exc:
        if getattr(exc, "trajectory", None) is None:  # before the run started: the scene, not the run
            raise
        return scene, exc.trajectory, exc
    return scene, trajectory, None


def _contacts(args: argparse.Namespace, scene) -> str | None:
    """The contact treatment of ``simulate``: ``--contacts``, else ``auto`` (the scene's choice,
    :func:`~pinstab.simulate.choice.contact_choice`). Refuses the held contacts' options with ``event`` and
    ``--stop-on`` without it."""
    from ..simulate.choice import resolve_contacts

    asked = "auto" if args.contacts is None else args.contacts
    contacts, _ = resolve_contacts(scene, asked)
    if contacts == "event":
        given = [f"--{name}" for name in HELD_ONLY if getattr(args, name) is not None]
        given += [f"--{name.replace('_', '-')}" for name in given_options(args, METHOD_OPTION)]
        given += [f"--{name.replace('_', '-')}" for name in given_options(args, SOLVER_OPTION)]
        if given:
            chosen = "--contacts event" if args.contacts else f"scene {scene.name}'s choice, event"
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
    return asked


def run_summary(args: argparse.Namespace, trajectory) -> dict[str, Any]:
    """The figures of a run (or of a stopped run's samples) that ``run --json`` prints."""
    info = trajectory.info
    return {
        "scene": info.scene,
        "method": info.method,
        "integrator": info.integrator,
        "integrator_choice": info.integrator_choice,
        "solver": info.solver,
        "dt": info.dt,
        "duration": args.duration,
        **trajectory.summary(),
        "diverged": False,
        "parameters": info.parameters,
        "path": info.path,
        "path_reason": info.path_reason,
        "contact_treatment": info.contact_treatment,
        "compiled_steps": info.compiled_steps,
        "record_every": info.record_every,
    }


def ended(result: dict[str, Any], failure: PinstabError | None) -> dict[str, Any]:
    """``result``, or :class:`Kept` raised with it (and the error's message) when the run failed once started."""
    if failure is None:
        return result
    result["error"] = str(failure)
    raise Kept(failure, result)

"""``pinstab stability``: map observed against predicted stability over a grid of runs: a stabilizer's (dt, gain), or
with ``--element`` (and by default on a scene with force elements and no constraints) a stiff force element's
(dt, scale), one panel per integrator."""

from __future__ import annotations

import argparse
from typing import Any

from ...analysis.stability_map import map_methods
from ...errors import PinstabError
from ...files import check_output
from ...integration import INTEGRATORS
from ...solvers import SOLVERS
from ..options import output_argument, scene_arguments, scene_options
from .base import Command, register

GAIN_DEFAULTS = {
    "method": "baumgarte",
    "dt_range": [1e-4, 3e-2],
    "gain_range": [1e2, 1e9],
    "perturbation": 0.01,
    "solver": "dense",
}
ELEMENT_DEFAULTS = {"dt_range": [1e-5, 1e-2], "factor_range": [1e-2, 1e2], "scale": "element"}


def arguments(stability: argparse.ArgumentParser) -> None:
    """The scene, the kind of map (gains, or ``--element``), its integrators and grid, ``-o``."""
    scene_arguments(stability)
    stability.add_argument(
        "--element",
        metavar="NAME",
        help="map this force element's scale (its stiffness and damping x a factor) instead of a stabilizer's gains "
        "(default on a scene with force elements and no constraints: the element that owns the stiffest mode)",
    )
    stability.add_argument(
        "--integrator",
        action="append",
        choices=INTEGRATORS,
        help="repeatable for an element map, one panel each (default: every integrator with a known stability "
        "function); one for a gains map (default: semi-implicit-euler)",
    )
    stability.add_argument(
        "--dt-range", nargs=2, type=float, metavar=("A", "B"), help="steps [s] (default: 1e-4 3e-2; element: 1e-5 1e-2)"
    )
    stability.add_argument("--grid", type=int, default=40, help="cells per axis (default: 40)")
    stability.add_argument("--steps", type=int, default=200, help="steps per run (default: 200)")
    gains = stability.add_argument_group("gains map (a stabilizer's Kp, Kd)")
    gains.add_argument("--method", choices=map_methods(), help="a method with gains kp, kd (default: baumgarte)")
    gains.add_argument(
        "--gain-range", nargs=2, type=float, metavar=("C", "D"), help="Kp [1/s^2], Kd = 2 sqrt(Kp) (default: 1e2 1e9)"
    )
    gains.add_argument("--perturbation", type=float, help="initial violation [rad] (default: 0.01)")
    gains.add_argument("--solver", choices=SOLVERS, help="KKT backend of the runs (default: dense)")
    element = stability.add_argument_group("element map (--element)")
    element.add_argument(
        "--factor-range", nargs=2, type=float, metavar=("C", "D"), help="the element's scale [-] (default: 1e-2 1e2)"
    )
    element.add_argument(
        "--scale",
        choices=["element", "stiffness"],
        help="what the factor multiplies: stiffness and damping together (element, the default) or the stiffness",
    )
    output_argument(stability, "MAP.png", "write the map as a PNG")


def _options(args: argparse.Namespace, defaults: dict[str, Any], other: dict[str, Any], kind: str) -> dict[str, Any]:
    """``defaults``' options from ``args`` (their defaults where not given); an option of the ``other`` kind of map
    given is refused, naming it."""
    given = [name for name in other if name not in defaults and getattr(args, name) is not None]
    if given:
        flags = ", ".join("--" + name.replace("_", "-") for name in given)
        raise PinstabError(f"{flags}: not an option of {kind} map (see pinstab stability --help)")
    return {
        name: value if (value := getattr(args, name)) is not None else default for name, default in defaults.items()
    }


def stability(args: argparse.Namespace) -> dict[str, Any]:
    from ...analysis.element_map import CLASSES, default_element, element_map, plot_element_map
    from ...scene import load_scene

    if args.output:
        check_output(args.output, ".png", "chart")
    scene = load_scene(args.scene, **scene_options(args))
    element = args.element or default_element(scene)
    if element is None:
        return _gains_map(args, scene)
    options = _options(args, ELEMENT_DEFAULTS, GAIN_DEFAULTS, "an element")
    result = element_map(
        scene,
        element,
        integrators=args.integrator,
        dt_range=tuple(options["dt_range"]),
        factor_range=tuple(options["factor_range"]),
        grid=args.grid,
        steps=args.steps,
        scale=options["scale"],
        progress=not args.quiet,
    )
    if args.output:
        plot_element_map(result, args.output)
    payload = result.to_json(cells=args.json)
    if not args.json:  # a line per scheme
        payload = {k: v for k, v in payload.items() if k not in ("schemes", "stiffest_mode")}
        for name, figures in result.to_json(cells=False)["schemes"].items():
            limit = figures["limit_dt"]
            payload[name] = (
                f"agree on {100 * figures['agreement']:.1f} % (|R| <= 1: {100 * figures['region_agreement']:.1f} %), "
                f"step limit {'none' if limit is None else f'{1e3 * limit:.3g} ms'}; "
                + ", ".join(f"{figures[label]} {label}" for label in CLASSES if figures[label] or label != "unsolved")
            )
    if args.output:
        payload["map"] = args.output
    return payload


def _gains_map(args: argparse.Namespace, scene: Any) -> dict[str, Any]:
    """The map of a stabilizer's gains (one integrator)."""
    from ...analysis.stability_map import plot_stability_map, stability_map

    options = _options(args, GAIN_DEFAULTS, ELEMENT_DEFAULTS, "a gains")
    integrators = args.integrator or ["semi-implicit-euler"]
    if len(integrators) > 1:
        raise PinstabError(
            f"--integrator given {len(integrators)} times: a gains map takes one (an element map, --element, takes "
            "several)"
        )
    result = stability_map(
        scene,
        method=options["method"],
        integrator=integrators[0],
        dt_range=tuple(options["dt_range"]),
        gain_range=tuple(options["gain_range"]),
        grid=args.grid,
        steps=args.steps,
        perturbation=options["perturbation"],
        solver=options["solver"],
        progress=not args.quiet,
    )
    if args.output:
        plot_stability_map(result, args.output)
    payload = result.to_json() | {"kind": "gains"}
    if not args.json:
        counts = {name: sum(c.observed == name for c in result.cells) for name in ("converged", "bounded", "diverged")}
        payload = {k: v for k, v in payload.items() if k != "cells"} | counts
    if args.output:
        payload["map"] = args.output
    return payload


register(
    Command(
        "stability",
        "map observed vs predicted stability over a (dt, gain) or (dt, element scale) grid",
        arguments,
        stability,
        order=7,
    )
)

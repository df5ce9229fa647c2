"""The spring-damper and the joint torque compiled in the core kernel (``cpp/spring_damper.cpp``,
``cpp/core_kernel.cpp`` add_joint_torques) against their evaluation in Python at every stage, as before (the core's
Python part, ``pinstab.paths.core.PythonPart``: ``CORE_FORCE_KINDS`` as it was, joint springs, holds and wrenches), side
by side in one run: CPU s per simulated second of the whole ``pinstab.simulate()`` call of

- ``finger-rolling`` at its defaults (its ``press`` spring and three joint torques, one a table; its rolling rows stay
  in Python), and
- the four-bar with a damped spring from its coupler to a world point under Mukharlyamov's term (the core path; the
  spring is the scene's only element, so before it the Python part held the spring alone),

the runs interleaved and repeated (the least of REPEATS counts), with the ratio before / after and the largest
difference of the two runs' q and v.

    python benchmarks/spring_damper.py    # prints the table, writes benchmarks/results/spring_damper.json (~1 min)
"""

from __future__ import annotations

import time
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
import pinstab.paths.core
from pinstab.bench import save_results
from pinstab.scene import scene_from_dict
from pinstab.simulate import default_contacts

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
REPEATS = 5
DURATION = 1.0  # [s] simulated
OUT = Path(__file__).parent / "results" / "spring_damper.json"
COMPILED_KINDS = pinstab.paths.core.CORE_FORCE_KINDS
PYTHON_KINDS = ("joint-spring", "hold", "wrench")  # before: spring-dampers and joint torques in Python


def fourbar_spring() -> pinstab.Scene:
    """The bundled four-bar with a 40 N/m, 1.5 N s/m spring-damper (rest 0.3 m) from its coupler's midpoint to the
    world point (0.2, 0.6, 0)."""
    data = tomllib.loads((ROBOTS / "fourbar.toml").read_text())
    data["forces"] = [
        {
            "name": "spring",
            "kind": "spring-damper",
            "frame_a": "coupler",
            "offset_a": [0.3, 0.0, 0.0],
            "offset_b": [0.2, 0.6, 0.0],
            "stiffness": 40.0,
            "damping": 1.5,
            "rest_length": 0.3,
        }
    ]
    return scene_from_dict(data, base_dir=ROBOTS, name="fourbar-spring")


SCENES: dict[str, tuple[Callable[[], pinstab.Scene], dict[str, Any]]] = {
    "finger-rolling": (lambda: pinstab.load_scene("finger-rolling"), {}),
    "fourbar-spring": (fourbar_spring, {"method": "mukharlyamov"}),
}


def timed(scene: pinstab.Scene, kinds: tuple[str, ...], options: dict[str, Any]) -> tuple[pinstab.Trajectory, float]:
    """One ``simulate()`` of ``scene`` over DURATION with the core taking the force kinds ``kinds``, and its CPU time
    [s]."""
    pinstab.paths.core.CORE_FORCE_KINDS = kinds
    try:
        began = time.process_time()
        run = pinstab.simulate(scene, duration=DURATION, progress=False, contacts=default_contacts(scene), **options)
        return run, time.process_time() - began
    finally:
        pinstab.paths.core.CORE_FORCE_KINDS = COMPILED_KINDS


def measure(name: str) -> dict[str, Any]:
    build, options = SCENES[name]
    cpu: dict[str, list[float]] = {"python": [], "compiled": []}
    runs: dict[str, pinstab.Trajectory] = {}
    for _ in range(REPEATS):
        for label, kinds in (("python", PYTHON_KINDS), ("compiled", COMPILED_KINDS)):
            runs[label], seconds = timed(build(), kinds, options)
            cpu[label].append(seconds)
    before, after = runs["python"], runs["compiled"]
    row = {
        "duration_s": DURATION,
        "paths": [before.info.path, after.info.path],
        "reasons": [before.info.path_reason, after.info.path_reason],
        "python_cpu_s_per_s": min(cpu["python"]) / DURATION,
        "compiled_cpu_s_per_s": min(cpu["compiled"]) / DURATION,
        "max_dq": float(np.max(np.abs(before.q - after.q))),
        "max_dv": float(np.max(np.abs(before.v - after.v))),
    }
    row["speedup"] = row["python_cpu_s_per_s"] / row["compiled_cpu_s_per_s"]
    print(
        f"{name:<15} {DURATION:3.1f} s  in Python {row['python_cpu_s_per_s']:7.3f}  compiled "
        f"{row['compiled_cpu_s_per_s']:7.3f} CPU s/s  ({row['speedup']:4.2f}x)  |dq| {row['max_dq']:.1e}  "
        f"|dv| {row['max_dv']:.1e}",
        flush=True,
    )
    return row


def main() -> None:
    rows = {name: measure(name) for name in SCENES}
    save_results(OUT, {"repeats": REPEATS, "scenes": rows})


if __name__ == "__main__":
    main()

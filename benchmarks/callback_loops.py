"""One step loop in C++ for every path (issue 35): the compiled loops stepping with the system's Python evaluation
called back (``cpp/callback_kernel.cpp``) against the Python loops taking the same steps one by one, interleaved in
one process, median CPU time of ROUNDS; both runs' trajectories compared to the last bit.

- the general path (``--solver proxsuite`` forced on the four-bar, Baumgarte, fixed RK4 at 1 ms over 1 s): the
  compiled fixed-step loop on the callback against the Python fixed-step loop;
- the same scene with error control (dop853, ``--rtol 1e-8`` over 2 s): the compiled error-controlled loop on the
  callback against the Python error-controlled loop (whose attempts are the same compiled function, one call each).

The free flyer's case (``cassie``, ``--rtol 1e-6`` over 0.1 s, the compiled loop on the configuration group) is in
``benchmarks/compiled_adaptive.py``.

    python benchmarks/callback_loops.py    # prints the table, writes benchmarks/results/callback_loops.json
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from pinstab import load_scene, simulate
from pinstab.bench import save_results
from pinstab.integration.compiled import CompiledAdaptive, CompiledSteps

ROUNDS = 7
GENERAL = {"solver": "proxsuite"}  # the four-bar's general path
CASES = {
    "fourbar general path, rk4 1 ms, 1 s": ("fourbar", "rk4", 1e-3, 1.0, GENERAL, CompiledSteps),
    "fourbar general path, dop853 rtol 1e-8, 2 s": (
        "fourbar",
        "dop853",
        1e-2,
        2.0,
        {**GENERAL, "rtol": 1e-8},
        CompiledAdaptive,
    ),
}
OUT = Path(__file__).parent / "results" / "callback_loops.json"


@contextlib.contextmanager
def python_loop(loop: type, on: bool) -> Iterator[None]:
    """The compiled loop ``loop`` switched off while ``on``."""
    if not on:
        yield
        return
    original = loop.__dict__["of"]
    loop.of = classmethod(lambda cls, *arguments: None)
    try:
        yield
    finally:
        loop.of = original


def main() -> None:
    results = {}
    for name, (scene_name, integrator, dt, duration, options, loop) in CASES.items():
        scene = load_scene(scene_name)
        cpu: dict[str, list[float]] = {"compiled": [], "python": []}
        runs = {}
        for _ in range(ROUNDS):
            for label in cpu:
                with python_loop(loop, label == "python"):
                    began = time.process_time()
                    runs[label] = simulate(scene, "baumgarte", integrator, dt, duration, **options)
                    cpu[label].append(time.process_time() - began)
        fast, slow = runs["compiled"], runs["python"]
        median = {label: float(np.median(times)) for label, times in cpu.items()}
        entry = {
            "path": fast.info.path,
            "cpu_s": median,
            "all_rounds": cpu,
            "speedup": median["python"] / median["compiled"],
            "bitwise_equal": bool(np.array_equal(fast.q, slow.q) and np.array_equal(fast.v, slow.v)),
            "compiled_steps": fast.info.compiled_steps,
        }
        results[name] = entry
        print(
            f"{name:45s} ({entry['path']} path) compiled loop {median['compiled']:8.3f} s, python loop "
            f"{median['python']:8.3f} s CPU: {entry['speedup']:.2f}x; bitwise equal: {entry['bitwise_equal']}"
        )
    save_results(OUT, {"rounds": ROUNDS, "cases": results})


if __name__ == "__main__":
    main()

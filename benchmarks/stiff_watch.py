"""What the stiff-mode watch (issue 37, ``pinstab/integration/stiffness.py``) adds to a run: the same run with the watch
and without it (``StiffWatch.of`` returning None), interleaved in one process, median CPU time of ROUNDS; both runs'
trajectories compared to the last bit. On a scene without force elements the loop has no watch (checked): nothing is
added.

    python benchmarks/stiff_watch.py    # prints the table
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import numpy as np

from pinstab import load_scene, simulate
from pinstab.integration import stepping
from pinstab.integration.stiffness import StiffWatch

ROUNDS = 5
CASES = {
    "stiff-fourbar rk4 0.1 ms, 1 s (nv = 2, 1 element)": ("stiff-fourbar", 1e-4, 1.0),
    "stiff-fourbar rk4 0.3 ms, 1 s (near the limit: every check)": ("stiff-fourbar", 3e-4, 1.0),
    "cassie-legs rk4 0.1 ms, 0.1 s (nv = 22, 28 elements)": ("cassie-legs", 1e-4, 0.1),
    "fourbar rk4 1 ms, 2 s (no force element: no watch)": ("fourbar", 1e-3, 2.0),
}


@contextlib.contextmanager
def unwatched(on: bool) -> Iterator[None]:
    """The watch switched off while ``on``."""
    if not on:
        yield
        return
    original = StiffWatch.__dict__["of"]
    stepping.StiffWatch.of = classmethod(lambda cls, *arguments: None)
    try:
        yield
    finally:
        stepping.StiffWatch.of = original


def main() -> None:
    print(f"{'case':62s} {'watched [s]':>12s} {'unwatched [s]':>14s} {'ratio':>7s}  same")
    for label, (name, dt, duration) in CASES.items():
        scene = load_scene(name)
        times: dict[bool, list[float]] = {False: [], True: []}
        runs = {}
        for _ in range(ROUNDS):
            for off in (False, True):
                with unwatched(off):
                    start = time.process_time()
                    runs[off] = simulate(scene, integrator="rk4", dt=dt, duration=duration)
                    times[off].append(time.process_time() - start)
        watched, bare = float(np.median(times[False])), float(np.median(times[True]))
        same = np.array_equal(runs[False].q, runs[True].q) and np.array_equal(runs[False].v, runs[True].v)
        print(f"{label:62s} {watched:12.4f} {bare:14.4f} {watched / bare:7.3f}  {same}")


if __name__ == "__main__":
    main()

"""The corrections of ``projection`` and ``post`` compiled on the core path (``cpp/projection.cpp``: the rows, M, the
Gauss-Newton iteration and the velocity projection in C++, in the compiled step loop) against the correction in Python
as it ran before (the core's dynamics, the Python step loop, the general projector: pinstab's rows and M evaluated in
Python at each iteration), as a user runs it (``pinstab.simulate()``, the whole call, RK4 at 1 ms): CPU s per simulated
second of ``delta`` and the full ``cassie`` over 0.2 s, the runs interleaved and repeated (the least of REPEATS counts),
with the ratio, the largest difference of the two runs' q and v, the largest position drift and the correction
iterations.

    python benchmarks/core_projection.py    # prints the table, writes benchmarks/results/core_projection.json (~5 s)
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.integration.compiled import CompiledSteps
from pinstab.projection import GeneralProjector
from pinstab.system import ConstrainedSystem

SCENES = ("delta", "cassie")
METHODS = ("projection", "post")
DT, DURATION = 1e-3, 0.2  # [s]
REPEATS = 3
OUT = Path(__file__).parent / "results" / "core_projection.json"


@contextmanager
def python_correction():
    """The correction in Python: the general projector and the Python step loop (the core's dynamics kept)."""
    bind = ConstrainedSystem.bind

    def python_bind(self, *arguments, **keywords):
        bind(self, *arguments, **keywords)
        self.projector = GeneralProjector(self.model)

    with (
        mock.patch.object(ConstrainedSystem, "bind", python_bind),
        mock.patch.object(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None)),
    ):
        yield


def timed(scene: pinstab.Scene, method: str, python: bool) -> tuple[pinstab.Trajectory, float]:
    """``simulate(scene, method)`` (RK4, DT, DURATION) and its CPU time [s], the correction in Python or compiled."""
    began = time.process_time()
    if python:
        with python_correction():
            run = pinstab.simulate(scene, method, "rk4", DT, DURATION, progress=False)
    else:
        run = pinstab.simulate(scene, method, "rk4", DT, DURATION, progress=False)
    return run, time.process_time() - began


def measure(name: str, method: str) -> dict[str, Any]:
    scene = pinstab.load_scene(name)
    cpu: dict[bool, list[float]] = {False: [], True: []}
    runs: dict[bool, pinstab.Trajectory] = {}
    for _ in range(REPEATS):
        for python in (False, True):
            runs[python], seconds = timed(scene, method, python)
            cpu[python].append(seconds)
    core, python = runs[False], runs[True]
    row = {
        "paths": [core.info.path, python.info.path],
        "compiled_steps": [core.info.compiled_steps, python.info.compiled_steps],
        "core_cpu_s_per_s": min(cpu[False]) / DURATION,
        "python_cpu_s_per_s": min(cpu[True]) / DURATION,
        "max_dq": float(np.max(np.abs(core.q - python.q))),
        "max_dv": float(np.max(np.abs(core.v - python.v))),
        "max_position_drift_m": [float(np.max(core.position_drift)), float(np.max(python.position_drift))],
        "correction_iterations": [core.info.correction_iterations_total, python.info.correction_iterations_total],
    }
    row["speedup"] = row["python_cpu_s_per_s"] / row["core_cpu_s_per_s"]
    print(
        f"{name:<7} {method:<10} core {row['core_cpu_s_per_s']:8.3f}  python {row['python_cpu_s_per_s']:8.3f} CPU s/s "
        f"({row['speedup']:5.1f}x)  |dq| {row['max_dq']:.1e}  |dv| {row['max_dv']:.1e}  drift "
        f"{row['max_position_drift_m'][0]:.1e} / {row['max_position_drift_m'][1]:.1e} m",
        flush=True,
    )
    return row


def main() -> None:
    rows = {f"{name} {method}": measure(name, method) for name in SCENES for method in METHODS}
    save_results(OUT, {"integrator": "rk4", "dt_s": DT, "duration_s": DURATION, "repeats": REPEATS, "runs": rows})


if __name__ == "__main__":
    main()

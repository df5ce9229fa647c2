"""Compiled error control (issue 35, item 3): ``--rtol`` runs with the compiled error-controlled loop
(``cpp/adaptive.cpp``) against the same runs with it switched off (the Python adaptive loop) and against SciPy's
DOP853 over Pinocchio, interleaved, median CPU of ROUNDS, measured as ``pinstab bench`` measures them
(:func:`pinstab.bench.workprecision.run_config`: pinstab's whole ``simulate()`` call, SciPy's ``solve_ivp``; the
trajectory error max |q - q_ref| against the scene's exact motion, samples every 10 ms).

    python benchmarks/compiled_adaptive.py    # prints the tables, writes benchmarks/results/compiled_adaptive.json

The acceptance line: on the four-bar over 10 s, pinstab's cheapest ``--rtol`` run within 1e-6 rad costs at most 1/3
of SciPy's cheapest within 1e-6 rad (any of its gains and tolerances). The N-four-bar (N = 10, 5 s, banded; rtol
1e-7: at smaller tolerances its error-controlled passage through the aligned configuration ends on either branch
with rounding, benchmarks/README.md), the slider-crank (10 s; force elements: in the native kernel since issue 37,
the compiled loop on the system's Python evaluation in the results before) and the full cassie (0.1 s at rtol 1e-6;
a free flyer: the compiled loop on the configuration group, the core path) give the compiled loop's speed-up over
the Python adaptive loop. The "python" runs are this checkout's Python loop, whose attempts are compiled too (one
call each): the Python adaptive loop before the compiled one is slower still.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from pinstab.bench import save_results
from pinstab.bench.scipy_peer import SCIPY_PEER
from pinstab.bench.workprecision import (
    ADAPTIVE_OUTPUT_STEP,
    SCIPY_KP,
    Config,
    Result,
    reference_motion,
    run_config,
)
from pinstab.integration.compiled import CompiledAdaptive

ROUNDS = 5
TOLERANCE = 1e-6  # [rad] the trajectory error the cheapest runs must reach
GOAL = 1 / 3  # pinstab's cheapest over SciPy's cheapest
FOURBAR_DURATION = 10.0  # [s]
PINSTAB_RTOLS = (1e-7, 3e-8, 1e-8, 3e-9, 1e-9)
SCIPY_RTOLS = (1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 1e-10)
OTHER_SCENES = (  # (scene, parameters, s, rtol)
    ("nfourbar", {"N": 10}, 5.0, 1e-7),
    ("slider-crank", {}, 10.0, 3e-8),
    ("cassie", {}, 0.1, 1e-6),
)
LOOPS = ("compiled", "python")
OUT = Path(__file__).parent / "results" / "compiled_adaptive.json"


@contextlib.contextmanager
def python_loop(loop: str) -> Iterator[None]:
    """The compiled error-controlled loop switched off while ``loop`` is ``"python"``."""
    if loop == "compiled":
        yield
        return
    original = CompiledAdaptive.__dict__["of"]
    CompiledAdaptive.of = classmethod(lambda cls, system, stepper, pair: None)
    try:
        yield
    finally:
        CompiledAdaptive.of = original


def measure(scene: str, parameters: dict, duration: float, configs: dict[str, tuple[str, Config]]) -> dict[str, dict]:
    """ROUNDS interleaved runs of each configuration (label -> (loop, config)): the median CPU s per simulated s,
    the trajectory error [rad or m] and the evaluations."""
    reference = reference_motion(scene, parameters, duration)
    cpu: dict[str, list[float]] = {label: [] for label in configs}
    last: dict[str, Result] = {}
    for _ in range(ROUNDS):
        for label, (loop, config) in configs.items():
            with python_loop(loop):
                last[label] = run_config(scene, parameters, config, duration, reference)
            cpu[label].append(last[label].cpu_per_sim_s)
    return {
        label: {
            "cpu_s_per_simulated_s": float(np.median(cpu[label])),
            "all_rounds": cpu[label],
            "trajectory_error": last[label].trajectory_error,
            "evaluations": last[label].evaluations,
            "diverged": last[label].diverged,
        }
        for label in configs
    }


def cheapest(rows: dict[str, dict], prefix: str) -> tuple[str, dict] | None:
    """The cheapest configuration whose label starts with ``prefix`` within :data:`TOLERANCE`."""
    eligible = [
        (label, row)
        for label, row in rows.items()
        if label.startswith(prefix) and not row["diverged"] and row["trajectory_error"] <= TOLERANCE
    ]
    return min(eligible, key=lambda item: item[1]["cpu_s_per_simulated_s"]) if eligible else None


def main() -> None:
    configs: dict[str, tuple[str, Config]] = {}
    for rtol in PINSTAB_RTOLS:
        for loop in LOOPS:
            configs[f"pinstab {loop} rtol={rtol:g}"] = (
                loop,
                Config("baumgarte", "dop853", ADAPTIVE_OUTPUT_STEP, rtol=rtol),
            )
    for kp in SCIPY_KP:
        for rtol in SCIPY_RTOLS:
            config = Config(SCIPY_PEER, "dop853", ADAPTIVE_OUTPUT_STEP, SCIPY_PEER, kp, 2.0 * math.sqrt(kp), rtol=rtol)
            configs[f"scipy Kp={kp:g} rtol={rtol:g}"] = ("compiled", config)
    fourbar = measure("fourbar", {}, FOURBAR_DURATION, configs)
    print(f"fourbar, {FOURBAR_DURATION:g} s ({ROUNDS} rounds, median):")
    print(f"{'configuration':36s} {'CPU s/s':>9s} {'error [rad]':>12s} {'evaluations':>12s}")
    for label, row in fourbar.items():
        print(
            f"{label:36s} {row['cpu_s_per_simulated_s']:9.5f} {row['trajectory_error']:12.3g} {row['evaluations']:12d}"
        )
    best = {
        name: cheapest(fourbar, prefix)
        for name, prefix in (("compiled", "pinstab compiled"), ("python", "pinstab python"), ("scipy", "scipy"))
    }
    acceptance = {}
    if best["scipy"] is not None:
        scipy_cost = best["scipy"][1]["cpu_s_per_simulated_s"]
        for loop in LOOPS:
            if best[loop] is None:
                continue
            ratio = best[loop][1]["cpu_s_per_simulated_s"] / scipy_cost
            acceptance[f"{loop} loop / scipy"] = {"value": ratio, "met": ratio <= GOAL}
            print(
                f"cheapest within {TOLERANCE:g} rad: {best[loop][0]} / {best['scipy'][0]} = {ratio:.3f} "
                f"(goal <= {GOAL:.3f}: {'MET' if ratio <= GOAL else 'NOT MET'})"
            )
    others = {}
    for scene, parameters, duration, rtol in OTHER_SCENES:
        rows = measure(
            scene,
            parameters,
            duration,
            {loop: (loop, Config("baumgarte", "dop853", ADAPTIVE_OUTPUT_STEP, rtol=rtol)) for loop in LOOPS},
        )
        speedup = rows["python"]["cpu_s_per_simulated_s"] / rows["compiled"]["cpu_s_per_simulated_s"]
        others[scene] = {
            "parameters": parameters,
            "duration_s": duration,
            "rtol": rtol,
            "runs": rows,
            "speedup": speedup,
        }
        fast, slow = rows["compiled"], rows["python"]
        print(
            f"{scene} {parameters or ''} {duration:g} s, rtol {rtol:g}: compiled {fast['cpu_s_per_simulated_s']:.5f}, "
            f"python loop {slow['cpu_s_per_simulated_s']:.5f} CPU s/s ({speedup:.2f}x), errors "
            f"{fast['trajectory_error']:.3g} / {slow['trajectory_error']:.3g}"
        )
    save_results(
        OUT,
        {
            "rounds": ROUNDS,
            "tolerance": TOLERANCE,
            "fourbar": {
                "duration_s": FOURBAR_DURATION,
                "runs": fourbar,
                "cheapest": {k: None if v is None else v[0] for k, v in best.items()},
            },
            "acceptance": acceptance,
            "other_scenes": others,
        },
    )


if __name__ == "__main__":
    main()

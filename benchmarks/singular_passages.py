"""The N-four-bar through its singular configurations: trajectory error against the exact motion, for
every stabilization method, N = 1 ... 40 (issue 20's acceptance table).

Each run is what a user runs (``pinstab.simulate``; RK4 at dt = 1 ms unless --dt), compared with the
parallelogram pendulum (``pinstab.trajectory_error(run, "exact")``, SciPy DOP853 at 1e-13). Columns:
largest crank-angle error [rad], largest position drift [m], singular passages listed and branch
changes, CPU seconds of the ``simulate()`` call and its ratio to projection's at the same N (measured in
the same round, methods interleaved).

    python benchmarks/singular_passages.py                 # N = 1 2 5 10 20 40, 20 s: about 15 min
    python benchmarks/singular_passages.py --ns 5 --duration 5   # a quick look

It prints a markdown table and writes benchmarks/results/singular_passages.json.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import pinstab
from pinstab.bench import save_results

METHODS = ("baumgarte", "projection", "post", "mukharlyamov")
OUT = Path(__file__).parent / "results" / "singular_passages.json"


def measure(n: int, method: str, duration: float, dt: float) -> dict:
    """One run of N = n: its crank error, drift, passages and CPU time."""
    scene = pinstab.load_scene("nfourbar", N=n)
    start = time.process_time()
    run = pinstab.simulate(scene, method=method, integrator="rk4", dt=dt, duration=duration)
    cpu = time.process_time() - start
    comparison = pinstab.trajectory_error(run, "exact", scene=scene)
    summary = run.summary()
    return {
        "N": n,
        "method": method,
        "crank_error_rad": float(comparison.error.max()),
        "max_position_drift_m": summary["max_position_drift"],
        "singular_passages": len(summary["singular_passages"]),
        "branch_changes": summary["branch_changes"],
        "cpu_s": cpu,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ns", type=int, nargs="+", default=[1, 2, 5, 10, 20, 40])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--dt", type=float, default=1e-3)
    args = parser.parse_args()
    rows = []
    print("| N | method | crank error [rad] | drift [m] | passages | branch changes | CPU [s] | CPU / projection |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.ns:
        block = [measure(n, method, args.duration, args.dt) for method in args.methods]
        base = next((row["cpu_s"] for row in block if row["method"] == "projection"), None)
        for row in block:
            row["cpu_over_projection"] = None if base is None else row["cpu_s"] / base
            ratio = "" if base is None else f"{row['cpu_over_projection']:.2f}"
            print(
                f"| {n} | {row['method']} | {row['crank_error_rad']:.2e} | {row['max_position_drift_m']:.1e} | "
                f"{row['singular_passages']} | {row['branch_changes']} | {row['cpu_s']:.2f} | {ratio} |",
                flush=True,
            )
        rows += block
    OUT.parent.mkdir(exist_ok=True)
    command = "python benchmarks/singular_passages.py " + " ".join(
        [
            "--ns",
            *map(str, args.ns),
            "--methods",
            *args.methods,
            "--duration",
            f"{args.duration:g}",
            "--dt",
            f"{args.dt:g}",
        ]
    )
    save_results(OUT, {"command": command, "integrator": "rk4", "dt": args.dt, "rows": rows})


if __name__ == "__main__":
    main()

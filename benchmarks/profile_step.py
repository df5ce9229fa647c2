"""Where a simulate() step's time goes (issue 9): cProfile of simulate() on the four-bar and the
N-four-bar (N = 10), Baumgarte + RK4 at dt = 1 ms for 2 s, the time grouped by where it is spent.

python benchmarks/profile_step.py [--label after] # writes benchmarks/results/profile-<label>.json

Run it from another checkout (PYTHONPATH=<checkout> python benchmarks/profile_step.py --label before)
to profile older code the same way. Profiling slows Python-heavy code more than calls into C++, so the
shares are indicative; the absolute per-step figures come from benchmarks/overhead.py.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
from pathlib import Path

import pinstab
from pinstab.bench import save_results

SCENES = {"fourbar": {}, "nfourbar": {"N": 10}}
OUT = Path(__file__).parent / "results"


def _group(filename: str, function: str) -> str:
    if "pinocchio" in function or "pinocchio" in filename:
        return "Pinocchio (C++ calls)"
    if "proxsuite" in function or "proxsuite" in filename:
        return "ProxSuite (C++ calls)"
    if "numpy" in filename or "numpy" in function or function.startswith("<method") or function.startswith("<built-in"):
        return "numpy and builtins"
    if "/pinstab/" in filename:
        return "pinstab " + filename.split("/pinstab/")[-1].removesuffix(".py")
    return "other Python"


def profile(name: str, parameters: dict) -> dict:
    scene = pinstab.load_scene(name, **parameters)
    pinstab.simulate(scene, "baumgarte", "rk4", 1e-3, 0.05)  # warm caches and imports
    profiler = cProfile.Profile()
    profiler.enable()
    trajectory = pinstab.simulate(scene, "baumgarte", "rk4", 1e-3, 2.0)
    profiler.disable()
    stats = pstats.Stats(profiler)
    groups: dict[str, float] = {}
    for (filename, _, function), (_, _, total, _, _) in stats.stats.items():
        key = _group(filename, function)
        groups[key] = groups.get(key, 0.0) + total
    steps = len(trajectory.t) - 1
    whole = sum(groups.values())
    ranked = sorted(groups.items(), key=lambda item: -item[1])
    return {
        "steps": steps,
        "profiled_us_per_step": whole / steps * 1e6,
        "share": {key: value / whole for key, value in ranked},
        "us_per_step": {key: value / steps * 1e6 for key, value in ranked},
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--label", default="after")
    args = parser.parse_args()
    results = {name: profile(name, parameters) for name, parameters in SCENES.items()}
    for name, result in results.items():
        print(f"{name}: {result['profiled_us_per_step']:.1f} us/step under the profiler")
        for key, share in list(result["share"].items())[:8]:
            print(f"  {key:40s} {100 * share:5.1f} %  {result['us_per_step'][key]:8.1f} us/step")
    save_results(OUT / f"profile-{args.label}.json", results)


if __name__ == "__main__":
    main()

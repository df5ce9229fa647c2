"""Set-up in proportion to the model (issue 35, item 5): a short run of the N-four-bar, N = 10, 20, 40, 80, RK4 at
1 ms over 0.2 s, against MuJoCo's RK4 ``mj_step``. Per step, CPU microseconds of the whole ``simulate()`` call (set-up
included, the scene loaded before) and of MuJoCo's loop, best of five interleaved rounds in one process; the
set-up's wall milliseconds (``info.timings``) of the same best round. Then, each in a fresh process, the memory a
0.2 s run adds at its peak (``VmHWM`` after the run less ``VmRSS`` before it, the scene loaded) and its set-up's
wall milliseconds, at N = 40 and 80.

python benchmarks/short_runs.py      # prints the tables, writes benchmarks/results/short_runs.json
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from pinstab import load_scene, simulate
from pinstab.bench import save_results
from pinstab.bench.mujoco_peer import DEFAULT_SOLREF, run_mujoco

OUT = Path(__file__).parent / "results" / "short_runs.json"
SIZES = (10, 20, 40, 80)
FRESH_SIZES = (40, 80)
DT, DURATION, ROUNDS = 1e-3, 0.2, 5
CHILD = """
import json, sys
from pinstab import load_scene, simulate
def status(key):
    with open("/proc/self/status") as lines:
        return next(int(line.split()[1]) for line in lines if line.startswith(key)) * 1024
scene = load_scene("nfourbar", N=int(sys.argv[1]))
before = status("VmRSS:")
trajectory = simulate(scene, "baumgarte", "rk4", float(sys.argv[2]), float(sys.argv[3]))
print(json.dumps({"added_bytes": status("VmHWM:") - before, "setup_ms": trajectory.info.timings["setup_s"] * 1e3}))
"""


def side_by_side() -> dict[str, Any]:
    """Per N: microseconds per step of the short run (whole call) and of MuJoCo, best of :data:`ROUNDS`, and the
    set-up milliseconds of the best short run."""
    steps = round(DURATION / DT)
    run_us = {n: math.inf for n in SIZES}
    mujoco_us = {n: math.inf for n in SIZES}
    setup_ms = {n: math.inf for n in SIZES}
    for _ in range(ROUNDS):
        for n in SIZES:
            scene = load_scene("nfourbar", N=n)
            began = time.process_time()
            trajectory = simulate(scene, "baumgarte", "rk4", DT, DURATION)
            cost = (time.process_time() - began) / steps * 1e6
            if cost < run_us[n]:
                run_us[n], setup_ms[n] = cost, trajectory.info.timings["setup_s"] * 1e3
            _, _, seconds = run_mujoco(scene, trajectory.q[0], trajectory.v[0], DT, steps, "rk4", DEFAULT_SOLREF, steps)
            mujoco_us[n] = min(mujoco_us[n], seconds / steps * 1e6)
    result: dict[str, Any] = {"N": list(SIZES), "dt": DT, "duration": DURATION, "rounds": ROUNDS}
    result["run_us"] = [run_us[n] for n in SIZES]
    result["mujoco_us"] = [mujoco_us[n] for n in SIZES]
    result["setup_ms"] = [setup_ms[n] for n in SIZES]
    result["run_over_mujoco"] = [run_us[n] / mujoco_us[n] for n in SIZES]
    result["run_exponent"] = float(np.polyfit(np.log(SIZES), np.log(result["run_us"]), 1)[0])
    return result


def fresh(n: int) -> dict[str, float]:
    """The memory a 0.2 s run of N-four-bar N = n adds at its peak [bytes] and its set-up [ms], in a fresh process."""
    argv = [sys.executable, "-c", CHILD, str(n), str(DT), str(DURATION)]
    done = subprocess.run(argv, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    result = side_by_side()
    print("  N  run [us/step]  MuJoCo [us/step]  run/MuJoCo  set-up [ms]")
    for index, n in enumerate(SIZES):
        print(
            f"{n:3d}  {result['run_us'][index]:13.1f}  {result['mujoco_us'][index]:16.1f}"
            f"  {result['run_over_mujoco'][index]:10.2f}  {result['setup_ms'][index]:11.2f}"
        )
    print(f"exponent p of the short run's cost per step ~ N^p: {result['run_exponent']:.2f}")
    result["fresh"] = {n: fresh(n) for n in FRESH_SIZES}
    print("fresh process:  N  memory added [MiB]  set-up [ms]")
    for n, row in result["fresh"].items():
        print(f"{n:17d}  {row['added_bytes'] / 2**20:17.1f}  {row['setup_ms']:11.2f}")
    save_results(OUT, result)


if __name__ == "__main__":
    main()

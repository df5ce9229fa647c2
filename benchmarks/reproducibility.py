"""How reproducible the N-four-bar's trajectory is through its singular passages: the banded path (pinstab's
default at N = 40) against the reference path (Pinocchio's solve, ``solver="pinocchio"``), and the reference path
against itself started at velocities scaled by 1 + eps (eps from 1e-15, a few units in the last place, to 1e-12).

Every run is ``pinstab.simulate`` (RK4, 1 ms, 20 s, 20 passages); each figure is the largest difference of any joint
angle over the run [rad], then the same after each passage (100 steps after it), and each run's crank error against the
exact motion (``trajectory_error(run, "exact")``).

    python benchmarks/reproducibility.py    # 3 min; prints the table, writes benchmarks/results/reproducibility.json
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.simulate.loop import start_state

N = 40
DURATION = 20.0  # [s]
SCALES = (1e-15, 1e-14, 1e-13, 1e-12)  # eps: the reference started at v0 (1 + eps)
AFTER = 100  # steps after a passage where the parting is read
OUT = Path(__file__).parent / "results" / "reproducibility.json"


def parting(run: pinstab.Trajectory, reference: pinstab.Trajectory) -> np.ndarray:
    """The largest joint-angle difference at each sample [rad]."""
    return np.max(np.abs(run.q - reference.q), axis=1)


def main() -> None:
    scene = pinstab.load_scene("nfourbar", N=N)
    _, v0 = start_state(scene, None, None)
    reference = pinstab.simulate(scene, duration=DURATION, solver="pinocchio")
    runs = {"banded (the default path)": pinstab.simulate(scene, duration=DURATION)}
    for eps in SCALES:
        runs[f"reference, v0 (1 + {eps:g})"] = pinstab.simulate(
            scene, duration=DURATION, solver="pinocchio", v0=v0 * (1.0 + eps)
        )
    after = [int(round(p["t"] / reference.info.dt)) + AFTER for p in reference.info.passages]
    after = [k for k in after if k < len(reference.t)]
    results = {"N": N, "duration_s": DURATION, "passages": len(reference.info.passages), "runs": {}}
    reference_error = float(pinstab.trajectory_error(reference, "exact", scene=scene).error.max())
    print(
        f"reference (Pinocchio's solve): path {reference.info.path}, crank error to the exact motion "
        f"{reference_error:.3g} rad, {len(reference.info.passages)} passages"
    )
    print(f"{'run':34s} {'path':8s} {'parting max':>12s} {'after passage 1, 5, 10, 20':>40s} {'crank error':>12s}")
    for label, run in runs.items():
        difference = parting(run, reference)
        marks = [float(difference[after[i]]) for i in (0, 4, 9, len(after) - 1)]
        error = float(pinstab.trajectory_error(run, "exact", scene=scene).error.max())
        print(
            f"{label:34s} {run.info.path:8s} {difference.max():12.3g} "
            f"{' '.join(f'{m:9.2e}' for m in marks):>40s} {error:12.3g}"
        )
        results["runs"][label] = {
            "path": run.info.path,
            "parting_max_rad": float(difference.max()),
            "parting_after_passages_1_5_10_20_rad": marks,
            "crank_error_to_exact_rad": error,
        }
    results["reference_crank_error_to_exact_rad"] = reference_error
    save_results(OUT, results)


if __name__ == "__main__":
    main()

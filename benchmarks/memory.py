"""Peak memory of a long run (issues 9, 13): 1e6 steps of the four-bar (dt = 1 ms, 1000 s) saved to NPZ,
against the same command for 10 steps, each in a fresh process (peak resident set size); and the same run
kept whole under a 100 MB budget, refused before it starts (exit 2).

python benchmarks/memory.py            # prints the table, writes benchmarks/results/memory.json
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pinstab import load_scene
from pinstab.bench import save_results
from pinstab.simulate import kept_samples

OUT = Path(__file__).parent / "results" / "memory.json"
CHILD = (
    "import resource, sys\n"
    "from pinstab.cli import main\n"
    "code = main(sys.argv[1:])\n"
    "print('PEAK_KIB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, 'EXIT', code)\n"
)


def peak_mib(duration: float, every: int, folder: Path) -> tuple[float, float]:
    """(peak RSS [MiB], wall seconds) of ``pinstab run fourbar --duration D --record-every K --save``."""
    argv = ["run", "fourbar", "--duration", str(duration), "--record-every", str(every), "--quiet", "--json"]
    argv += ["--save", str(folder / f"run-{duration:g}-{every}.npz")]
    began = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, text=True, check=True)
    wall = time.perf_counter() - began
    fields = done.stdout.split("PEAK_KIB")[-1].split()
    if fields[2] != "0":
        raise SystemExit(f"pinstab run failed: {done.stderr}")
    return int(fields[0]) / 1024, wall


def main() -> None:
    results = {}
    scene = load_scene("fourbar")
    with tempfile.TemporaryDirectory() as folder:
        for every in (100, 1):
            baseline, _ = peak_mib(0.01, every, Path(folder))
            peak, wall = peak_mib(1000.0, every, Path(folder))
            size = (Path(folder) / f"run-1000-{every}.npz").stat().st_size / 2**20
            estimate = kept_samples(scene, 1_000_000, every)[1] / 2**20  # the budget's, for the samples
            results[f"record_every_{every}"] = {
                "steps": 1_000_000,
                "baseline_peak_mib": baseline,
                "peak_mib": peak,
                "growth_mib": peak - baseline,
                "wall_s": wall,
                "npz_mib": size,
                "estimate_mib": estimate,
            }
            print(
                f"1e6 steps, --record-every {every:3d}: peak {peak:7.1f} MiB, baseline (10 steps) {baseline:6.1f} MiB, "
                f"growth {peak - baseline:6.1f} MiB (estimate {estimate:.1f}), file {size:6.1f} MiB, {wall:5.1f} s"
            )
    refused = subprocess.run(
        [sys.executable, "-m", "pinstab.cli", "run", "fourbar", "--duration", "1000", "--memory-limit", "100MB"],
        capture_output=True,
        text=True,
    )
    results["refused_under_100MB"] = {"exit": refused.returncode, "message": refused.stderr.strip()}
    print(f"1e6 steps kept whole, --memory-limit 100MB: exit {refused.returncode}: {refused.stderr.strip()}")
    save_results(OUT, results)


if __name__ == "__main__":
    main()

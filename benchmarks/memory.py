"""Peak memory of a long run (issues 9, 13, 23): 1e6 steps of the four-bar (dt = 1 ms, 1000 s) saved to NPZ,
against the same command for 10 steps, each in a fresh process (peak resident set size); and the same run
kept whole under a 100 MB budget, refused before it starts (exit 2). ``stream``: the run streamed to HDF5
(``--stream``, every step kept) for 10, 100 and 1000 s, each in a fresh process.

python benchmarks/memory.py            # prints the table, writes benchmarks/results/memory.json
python benchmarks/memory.py stream     # writes benchmarks/results/stream_memory.json
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
STREAM_OUT = OUT.with_name("stream_memory.json")
STREAM_DURATIONS = (10.0, 100.0, 1000.0)  # [s]
CHILD = (
    "import resource, sys\n"
    "from pinstab.cli import main\n"
    "code = main(sys.argv[1:])\n"
    "print('PEAK_KIB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, 'EXIT', code)\n"
)


def peak_mib(duration: float, every: int, folder: Path) -> tuple[float, float]:
    """(peak RSS [MiB], wall seconds) of ``pinstab run fourbar --duration D --record-every K --save``."""
    return run_peak(
        [
            "--duration",
            str(duration),
            "--record-every",
            str(every),
            "--save",
            str(folder / f"run-{duration:g}-{every}.npz"),
        ]
    )


def run_peak(options: list[str]) -> tuple[float, float]:
    """(peak RSS [MiB], wall seconds) of ``pinstab run fourbar --quiet --json`` with ``options``, in a fresh process."""
    argv = ["run", "fourbar", "--quiet", "--json", *options]
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


def stream() -> None:
    """Peak RSS of the four-bar streamed to HDF5 over :data:`STREAM_DURATIONS`."""
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        for duration in STREAM_DURATIONS:
            path = Path(folder) / f"run-{duration:g}.h5"
            peak, wall = run_peak(["--duration", str(duration), "--stream", str(path)])
            size = path.stat().st_size / 2**20
            results[f"stream_{duration:g}s"] = {
                "steps": round(duration * 1000),
                "peak_mib": peak,
                "wall_s": wall,
                "h5_mib": size,
            }
            print(
                f"{duration:6g} s streamed ({round(duration * 1000):,} steps): peak {peak:6.1f} MiB, "
                f"file {size:6.1f} MiB, {wall:5.1f} s"
            )
    save_results(STREAM_OUT, results)


if __name__ == "__main__":
    stream() if sys.argv[1:] == ["stream"] else main()

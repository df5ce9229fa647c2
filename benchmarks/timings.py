"""What a run's reported wall time covers (issue 33): ``pinstab run --json``'s ``wall_s`` beside the process's own
wall time (measured around the child process, as ``/usr/bin/time`` does), and its split: start-up (interpreter and
imports), set-up, stepping, post-processing (derived series, summary) and output. Each case in a fresh process,
``ROUNDS`` rounds interleaved (the machine is shared: figures are medians, ratios side by side).

python benchmarks/timings.py           # the four-bar (10 s) and the N-four-bar (N = 40, 20 s)
python benchmarks/timings.py stream    # and the four-bar streamed to HDF5 over 1000 s (10^6 samples; one round)

Writes benchmarks/results/timings.json.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pinstab.bench import save_results

OUT = Path(__file__).parent / "results" / "timings.json"
ROUNDS = 3
CASES = {
    "fourbar 10 s": ["fourbar", "--duration", "10"],
    "nfourbar N=40 20 s": ["nfourbar", "--param", "N=40", "--duration", "20"],
}
STREAM_CASE = "fourbar 1000 s streamed"
PARTS = ("startup_s", "setup_s", "stepping_s", "post_s", "output_s")


def one_run(arguments: list[str]) -> dict[str, Any]:
    """``pinstab run ARGUMENTS --json --quiet`` in a fresh process: its JSON's ``wall_s`` and ``timings`` [s] and the
    process's wall time [s] measured around it."""
    began = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "pinstab.cli", "run", *arguments, "--json", "--quiet"],
        capture_output=True,
        text=True,
        check=True,
    )
    process = time.perf_counter() - began
    result = json.loads(done.stdout)
    return {"process_s": process, "wall_s": result["wall_s"], **result["timings"]}


def summary(rounds: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians over the rounds [s], the reported over the process's wall time and post-processing over stepping."""
    median = {key: statistics.median(r[key] for r in rounds) for key in ("process_s", "wall_s", *PARTS)}
    ratios = [r["wall_s"] / r["process_s"] for r in rounds]
    post = [r["post_s"] / r["stepping_s"] for r in rounds]
    return {
        **median,
        "wall_over_process": statistics.median(ratios),
        "wall_over_process_range": [min(ratios), max(ratios)],
        "post_over_stepping": statistics.median(post),
        "rounds": len(rounds),
    }


def main() -> None:
    stream = sys.argv[1:] == ["stream"]
    rounds: dict[str, list[dict[str, Any]]] = {name: [] for name in CASES}
    for _ in range(ROUNDS):
        for name, arguments in CASES.items():
            rounds[name].append(one_run(arguments))
    if stream:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "run.h5"
            rounds[STREAM_CASE] = [one_run(["fourbar", "--duration", "1000", "--stream", str(path)])]
    results = {name: summary(runs) for name, runs in rounds.items()}
    print(f"{'case':<26} {'process':>8} {'wall_s':>8} {'ratio':>6}  {'stepping':>8} {'post':>7} {'post/step':>9}")
    for name, row in results.items():
        print(
            f"{name:<26} {row['process_s']:>8.3f} {row['wall_s']:>8.3f} {row['wall_over_process']:>6.3f}  "
            f"{row['stepping_s']:>8.3f} {row['post_s']:>7.3f} {row['post_over_stepping']:>9.3f}"
        )
    if not stream and OUT.exists():  # keep the stream case of an earlier `stream` run
        earlier = json.loads(OUT.read_text()).get("cases", {})
        if STREAM_CASE in earlier:
            results[STREAM_CASE] = earlier[STREAM_CASE]
    save_results(OUT, {"cases": results, "parts": list(PARTS), "rounds": ROUNDS})


if __name__ == "__main__":
    main()

"""What simulate() costs over a hand-written Pinocchio loop (issue 9): same scheme, dt and gains, both
storing q and v every step, interleaved; the four-bar, the N-four-bar N = 10 and N = 40 (2 s through
its aligned configurations).

python benchmarks/overhead.py          # prints the table, writes benchmarks/results/overhead.json
"""

from __future__ import annotations

from pathlib import Path

import pinstab
from pinstab.bench import save_results
from pinstab.bench.overhead import measure_overhead

SCENES = {"fourbar": ("fourbar", {}), "nfourbar": ("nfourbar", {"N": 10}), "nfourbar N=40": ("nfourbar", {"N": 40})}
OUT = Path(__file__).parent / "results" / "overhead.json"


def main() -> None:
    results = {}
    for name, (scene, parameters) in SCENES.items():
        result = measure_overhead(pinstab.load_scene(scene, **parameters), rounds=3 if parameters.get("N") == 40 else 5)
        results[name] = result
        for scheme, entry in result["schemes"].items():
            print(
                f"{name:13s} {scheme:20s} hand-written {entry['hand_written_us']:7.1f} us/step  "
                f"simulate() {entry['simulate_us']:7.1f} us/step  ratio {entry['ratio']:5.2f}  ({entry['path']} path)"
            )
    save_results(OUT, results)


if __name__ == "__main__":
    main()

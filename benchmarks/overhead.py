"""What simulate() costs over a hand-written Pinocchio loop (issue 9): same scheme, dt and gains, both
storing q and v every step, interleaved.

python benchmarks/overhead.py          # prints the table, writes benchmarks/results/overhead.json
"""

from __future__ import annotations

import json
from pathlib import Path

import pinstab
from pinstab.bench.overhead import measure_overhead

SCENES = {"fourbar": {}, "nfourbar": {"N": 10}}
OUT = Path(__file__).parent / "results" / "overhead.json"


def main() -> None:
    results = {}
    for name, parameters in SCENES.items():
        result = measure_overhead(pinstab.load_scene(name, **parameters))
        results[name] = result
        for scheme, entry in result["schemes"].items():
            print(
                f"{name:9s} {scheme:20s} hand-written {entry['hand_written_us']:7.1f} us/step  "
                f"simulate() {entry['simulate_us']:7.1f} us/step  ratio {entry['ratio']:5.2f}  ({entry['path']} path)"
            )
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps(results, indent=1))
    print(f"-> {OUT}")


if __name__ == "__main__":
    main()

"""Per-step overhead (issue 5, item 3): pinstab's stabilized step against Pinocchio's native step.

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
        print(f"{name}: native {result['native_us']:.1f} us/step")
        for label, step in result["step_us"].items():
            print(f"  {label:45s} {step:8.1f} us/step  ratio {result['ratios'][label]:6.1f}")
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps(results, indent=1))
    print(f"-> {OUT}")


if __name__ == "__main__":
    main()

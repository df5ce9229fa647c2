"""What a Pinocchio ``Data`` costs to create (pin 4.1) on the N-four-bar, N = 10, 40, 80 (21, 81, 161 velocities):
the smallest and largest wall milliseconds of 6 ``model.createData()`` calls, the resident memory each adds, and
the milliseconds of ``model.saveToString()`` (how a model crosses into pinstab's compiled kernels). A run creates
three: the model's two and its compiled kernel's.

python benchmarks/data_creation.py
"""

from __future__ import annotations

import os
import time

from pinstab import load_scene

SIZES = (10, 40, 80)
REPEATS = 6


def _milliseconds(call) -> list[float]:
    times = []
    for _ in range(REPEATS):
        began = time.perf_counter()
        call()
        times.append((time.perf_counter() - began) * 1e3)
    return times


def _resident_mib() -> float:
    with open(f"/proc/{os.getpid()}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS")) / 1024


def main() -> None:
    print("  N  velocities  createData [ms] min-max  MiB each  saveToString [ms]")
    for n in SIZES:
        model = load_scene("nfourbar", N=n).model
        data, text = _milliseconds(model.createData), _milliseconds(model.saveToString)
        before = _resident_mib()
        kept = [model.createData() for _ in range(3)]
        size = (_resident_mib() - before) / len(kept)
        print(f"{n:3d}  {model.nv:10d}  {min(data):8.2f} - {max(data):7.2f}  {size:8.1f}  {min(text):17.2f}")


if __name__ == "__main__":
    main()

"""What a Pinocchio ``Data`` costs to create (pin 4.1) on the N-four-bar, N = 10, 40, 80 (21, 81, 161 velocities),
by ``model.createData()`` (its binding returns the Data by value: a copy that writes every page), by the constructor
``pin.Data(model)`` (it allocates and zeroes pin 4.1's nv^3 second-order derivative tensors) and by pinstab's
``new_data`` (``cpp/light_data.cpp``: the same Data without those tensors, what pinstab calls): the smallest and
largest wall milliseconds of 6 calls each, interleaved, the resident memory each adds, and the milliseconds of
``model.saveToString()`` (how a model crosses into pinstab's compiled kernels).

python benchmarks/data_creation.py
"""

from __future__ import annotations

import os
import time

import pinocchio as pin

from pinstab import load_scene
from pinstab.memory import new_data

SIZES = (10, 40, 80)
REPEATS = 6


def _milliseconds(call) -> float:
    began = time.perf_counter()
    call()
    return (time.perf_counter() - began) * 1e3


def _resident_mib() -> float:
    with open(f"/proc/{os.getpid()}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS")) / 1024


def _added_mib(create) -> float:
    before = _resident_mib()
    kept = [create() for _ in range(3)]
    return (_resident_mib() - before) / len(kept)


def main() -> None:
    builders = {"createData": lambda m: m.createData(), "pin.Data": pin.Data, "new_data": new_data}
    print("  N  velocities" + "".join(f"  {name + ' [ms]':>15s} min-max" for name in builders), end="")
    print("  MiB each:" + "".join(f"  {name:>10s}" for name in builders) + "  saveToString [ms]")
    for n in SIZES:
        model = load_scene("nfourbar", N=n).model
        times: dict[str, list[float]] = {name: [] for name in builders}
        for _ in range(REPEATS):
            for name, build in builders.items():
                times[name].append(_milliseconds(lambda m=model, b=build: b(m)))
        text = min(_milliseconds(model.saveToString) for _ in range(REPEATS))
        sizes = [_added_mib(lambda m=model, b=build: b(m)) for build in builders.values()]
        print(f"{n:3d}  {model.nv:10d}" + "".join(f"  {min(t):10.2f} - {max(t):7.2f}" for t in times.values()), end="")
        print("          " + "".join(f"  {size:10.1f}" for size in sizes) + f"  {text:17.2f}")


if __name__ == "__main__":
    main()

"""What a Pinocchio ``Data`` costs to create (pin 4.1) on the N-four-bar, N = 10, 40, 80 (21, 81, 161 velocities),
by ``model.createData()`` (its binding returns the Data by value: a copy that writes every page) and by the
constructor ``pin.Data(model)`` (what pinstab calls: pin 4.1's nv^3 derivative tensors stay unwritten until used):
the smallest and largest wall milliseconds of 6 calls each, interleaved, the resident memory each adds, and the
milliseconds of ``model.saveToString()`` (how a model crosses into pinstab's compiled kernels). A run on the
banded path creates two, the model's (its compiled kernel computes in the model's scratch ``Data``).

python benchmarks/data_creation.py
"""

from __future__ import annotations

import os
import time

import pinocchio as pin

from pinstab import load_scene

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
    print(
        "  N  velocities  createData [ms] min-max  pin.Data [ms] min-max"
        "  MiB each: createData  pin.Data  saveToString [ms]"
    )
    for n in SIZES:
        model = load_scene("nfourbar", N=n).model
        copied, built = [], []
        for _ in range(REPEATS):
            copied.append(_milliseconds(model.createData))
            built.append(_milliseconds(lambda m=model: pin.Data(m)))
        text = min(_milliseconds(model.saveToString) for _ in range(REPEATS))
        sizes = _added_mib(model.createData), _added_mib(lambda m=model: pin.Data(m))
        print(
            f"{n:3d}  {model.nv:10d}  {min(copied):8.2f} - {max(copied):7.2f}  {min(built):8.2f} - {max(built):7.2f}"
            f"  {sizes[0]:20.1f}  {sizes[1]:8.1f}  {text:17.2f}"
        )


if __name__ == "__main__":
    main()

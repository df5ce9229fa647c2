"""Long chains at linear cost (issue 23): the N-four-bar, N = 10, 20, 40, 80, RK4 at 1 ms, CPU microseconds
per step of pinstab's default run (the whole simulate() call over 1 s, and over 5 s: the set-up
spread over more steps), of the same run on Pinocchio's solve (the native path) and of MuJoCo's RK4 mj_step
(its loop), best of three interleaved rounds in one process; per evaluation, the banded
solve, pin.constraintDynamics and the Pinocchio passes the banded solve starts from.

python benchmarks/chains.py          # prints the table, writes benchmarks/results/chains.json
"""

from __future__ import annotations

from pathlib import Path

from pinstab.bench import save_results
from pinstab.bench.scaling import chain_costs

OUT = Path(__file__).parent / "results" / "chains.json"


def main() -> None:
    result = chain_costs()
    print(
        "  N  path    default  5 s run   native   MuJoCo  default/MuJoCo  5 s/MuJoCo"
        "  | per evaluation: banded  constraintDynamics  passes  conditioning"
    )
    for index, n in enumerate(result["N"]):
        print(
            f"{n:3d}  {result['default_path'][n]:7s} {result['default_us'][index]:7.0f}"
            f"  {result['long_us'][index]:8.0f}  {result['native_us'][index]:7.0f}"
            f"  {result['mujoco_us'][index]:7.0f}  {result['default_over_mujoco'][index]:14.2f}"
            f"  {result['long_over_mujoco'][index]:15.2f}  |"
            f" {result['banded_us'][index]:22.0f}  {result['constraintDynamics_us'][index]:18.0f}"
            f"  {result['pinocchio_passes_us'][index]:6.0f}  {result['conditioning_us'][index]:12.0f}"
        )
    print(
        "exponent p of cost ~ N^p: "
        + ", ".join(
            f"{name} {result[name + '_exponent']:.2f}" for name in ("default", "long", "native", "mujoco", "banded")
        )
    )
    save_results(OUT, result)


if __name__ == "__main__":
    main()

"""
Compare the stabilization methods
=================================

Compare the stabilization methods on a bundled scene: drift, energy error and cost, side by side.

.. code-block:: bash

    python demos/compare_methods.py                 # fourbar, 10 s, dt = 1e-3, rk4
    python demos/compare_methods.py delta --duration 2 --integrator semi-implicit-euler
"""

from __future__ import annotations

import argparse

import pinstab


def main() -> None:
    parser = argparse.ArgumentParser(
        description="Compare the stabilization methods on a bundled scene: drift, energy error and cost, side by side."
    )
    parser.add_argument("scene", nargs="?", default="fourbar")
    parser.add_argument("--duration", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument("--dt", type=float, default=1e-3, help="time step [s]")
    parser.add_argument("--integrator", default="rk4", choices=pinstab.INTEGRATORS)
    args = parser.parse_args()

    scene = pinstab.load_scene(args.scene)
    print(f"{scene.name}: {scene.description}; dt = {args.dt} s, {args.duration} s, {args.integrator}")
    print(f"{'method':<12}{'max |phi|':>12}{'max |g|':>12}{'|dE| [J]':>12}{'wall [s]':>10}")
    for method in pinstab.METHODS:
        try:
            traj = pinstab.simulate(  # contacts held as rows: the methods stabilize rows
                scene, method=method, integrator=args.integrator, dt=args.dt, duration=args.duration, contacts="held"
            )
        except pinstab.PinstabError as exc:
            print(f"{method:<12}failed: {exc}")
            continue
        s = traj.summary()
        print(
            f"{method:<12}{s['max_position_drift']:>12.2e}{s['max_velocity_drift']:>12.2e}"
            f"{abs(s['energy_end'] - s['energy_start']):>12.2e}{s['wall_s']:>10.2f}"
        )


if __name__ == "__main__":
    main()

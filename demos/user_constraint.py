"""
A constraint written in Python
==============================

The planar pendulum as a free point mass with x^2 + y^2 = l^2.

The multiplier is checked against the closed form lambda = -m (l w^2 + g cos(theta)) / (2 l)
[Murray, Li & Sastry, ex. 6.1]. Runs headless in a second:

.. code-block:: bash

    python demos/user_constraint.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pinstab
from pinstab.scene import scene_from_dict

MASS, LENGTH, GRAVITY = 2.0, 0.8, 9.81
try:
    HERE = Path(__file__).resolve().parent
except NameError:  # sphinx-gallery runs the script without __file__, from the script's folder
    HERE = Path.cwd()
URDF = HERE.parent / "tests" / "data" / "point_mass.urdf"


def main() -> None:
    scene = scene_from_dict(
        {
            "robot": {"urdf": str(URDF)},
            "gravity": [0.0, -GRAVITY, 0.0],
            "initial": {"q": {"x": LENGTH * np.sin(0.9), "y": -LENGTH * np.cos(0.9)}},
        },
        name="pendulum",
    )
    scene.add_constraint(
        pinstab.HolonomicConstraint(
            "rod",
            1,
            residual=lambda q, t: np.array([q[0] ** 2 + q[1] ** 2 - LENGTH**2]),
            jacobian=lambda q, t: np.array([[2 * q[0], 2 * q[1]]]),
            drift=lambda q, v, t: np.array([2 * (v[0] ** 2 + v[1] ** 2)]),
            nv=2,
        )
    )
    traj = pinstab.simulate(scene, method="projection", dt=1e-3, duration=2.0)
    theta = np.arctan2(traj.q[:, 0], -traj.q[:, 1])
    rate = (traj.q[:, 0] * traj.v[:, 1] - traj.q[:, 1] * traj.v[:, 0]) / LENGTH**2
    closed_form = -MASS * (LENGTH * rate**2 + GRAVITY * np.cos(theta)) / (2 * LENGTH)
    error = np.abs(traj.multipliers_of("rod")[:, 0] - closed_form).max()
    print(f"rod tension from lambda: {-2 * LENGTH * traj.multipliers_of('rod')[0, 0]:.4f} N at t = 0")
    print(f"max |lambda - closed form| over 2 s: {error:.2e} N; max |phi|: {traj.position_drift.max():.1e} m^2")


if __name__ == "__main__":
    main()

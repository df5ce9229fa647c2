"""Contacts found from collision geometry (issue 36, kind ``geometry``) against the same contacts declared: the
CPU seconds of each event-driven run (``time.process_time`` of the whole ``simulate()`` call, the scene loaded
before), measured interleaved (ROUNDS rounds, the least of each kept), their ratio, and the largest difference of
the final configurations.

* ``incline``: the cube sliding down the slope (theta 0.5 rad, mu 0.3, 2 s): its four bottom corners;
* ``sphere-spin``: the ball thrown with backspin (1 s): one sphere contact;
* ``bouncing-ball``: dropped from 1 m with e = 0.5 (2 s): one sphere contact;
* ``box-drop``: a frictionless cube dropped on a corner (1.5 s): the corners found as they come near, against all
  eight declared;
* ``box-stack``: three cubes at rest (2 s): twelve redundant corners sticking, 20 declared (the far ones too);
* ``stack-drop``: a fourth cube dropped 0.1 m onto them (1 s): its corners found on the way, 28 declared.

The geometry runs ask coal for the contacts at every step's end (:class:`~pinstab.integration.events.EventLoop`).

    python benchmarks/geometry_contacts.py    # prints the table (~20 s); with --save, writes
                                              # benchmarks/results/geometry_contacts.json
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pinstab import simulate
from pinstab.bench import save_results
from pinstab.bench.box_stack import declared_stack
from pinstab.scene import scene_from_dict

ROUNDS = 5
OUT = Path(__file__).parent / "results" / "geometry_contacts.json"
HALF = 0.05  # [m] the cube's half side
CORNERS = [[sx * HALF, sy * HALF, sz * HALF] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
TILTED = pin.Quaternion(pin.rpy.rpyToMatrix(0.3, 0.2, 0.0)).coeffs().tolist()


def corner_entries(corners: list[list[float]], mu: float) -> list[dict[str, Any]]:
    """Declared plane contacts at the cube's ``corners`` [m] with friction ``mu``."""
    return [
        {"name": f"c{k}", "kind": "plane-contact", "frame_a": "box", "offset_a": p, "mu": mu}
        for k, p in enumerate(corners)
    ]


# name: (scene data without contacts, the declared contacts, the geometry entry, duration [s])
CASES: dict[str, tuple[dict[str, Any], list[dict[str, Any]] | None, dict[str, Any], float]] = {
    "incline": ({"generator": {"name": "incline", "theta": 0.5, "mu": 0.3}}, None, {"mu": 0.3}, 2.0),
    "sphere-spin": ({"generator": {"name": "sphere-spin"}}, None, {"mu": 0.3}, 1.0),
    "bouncing-ball": ({"generator": {"name": "bouncing-ball"}}, None, {"restitution": 0.5}, 2.0),
    "box-drop": (
        {
            "generator": {"name": "incline", "theta": 0.0},
            "initial": {"q": {"root_joint": [0.0, 0.0, 0.3, *TILTED]}},
        },
        corner_entries(CORNERS, 0.0),
        {"mu": 0.0},
        1.5,
    ),
    "box-stack": (
        {"generator": {"name": "box-stack"}},
        declared_stack(["box0", "box1", "box2"], 0.5)[0],
        {"mu": 0.5},
        2.0,
    ),
    "stack-drop": (
        {"generator": {"name": "box-stack", "drop": 0.1}},
        declared_stack(["box0", "box1", "box2", "dropped"], 0.5)[0],
        {"mu": 0.5},
        1.0,
    ),
}


def scenes(name: str) -> tuple[Any, Any]:
    """The (declared, geometry) scenes of a case."""
    data, declared, entry, _ = CASES[name]
    declared_data = data if declared is None else {**data, "contacts": declared}
    return (
        scene_from_dict(declared_data, name=name),
        scene_from_dict({**data, "contacts": [{"kind": "geometry", **entry}]}, name=name),
    )


def timed(scene: Any, duration: float) -> tuple[float, np.ndarray]:
    """CPU seconds of one event-driven run and its final configuration."""
    start = time.process_time()
    run = simulate(scene, dt=0.01, duration=duration, contacts="event")
    return time.process_time() - start, run.q[-1]


def main() -> None:
    rows = []
    print(f"{'case':<15}{'declared [s]':>14}{'geometry [s]':>14}{'ratio':>8}{'|dq| end':>11}")
    for name, (_, _, _, duration) in CASES.items():
        best = {"declared": np.inf, "geometry": np.inf}
        ends = {}
        for _ in range(ROUNDS):
            for label, scene in zip(("declared", "geometry"), scenes(name), strict=True):
                seconds, ends[label] = timed(scene, duration)
                best[label] = min(best[label], seconds)
        ratio = best["geometry"] / best["declared"]
        difference = float(np.max(np.abs(ends["geometry"] - ends["declared"])))
        rows.append({"case": name, **best, "ratio": ratio, "final_q_difference": difference})
        print(f"{name:<15}{best['declared']:>14.3f}{best['geometry']:>14.3f}{ratio:>8.2f}{difference:>11.1e}")
    if "--save" in sys.argv:
        save_results(OUT, {"rounds": ROUNDS, "rows": rows})


if __name__ == "__main__":
    main()

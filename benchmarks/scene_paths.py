"""Every bundled scene at its defaults (issue 35's table): the path ``pinstab.simulate()`` takes (``"path"`` in the
JSON: native, banded, servo, grasp, core, or the general path in Python), its reason, and the CPU
seconds per simulated second of the whole call (set-up included) at the scene's own step and the contact treatment
``pinstab run`` gives it by default (``default_contacts``: event-driven for scenes of plane contacts only).

Each scene first runs PROBE s of simulated time; its measured duration is then the one that costs about BUDGET CPU
s (between PROBE and MAX_DURATION), run ROUNDS times interleaved with the others; the median is reported. A scene
that stops before its duration (a lost grasp, a refusal: ``ring-on-rod``, ``pinch``) is reported with its error
and the time it reached.

    python benchmarks/scene_paths.py    # prints the table, writes benchmarks/results/scene_paths.json (minutes)

The table beside it is the one before the core path (``results/scene_paths_before.json``, commit d561c68: the
general path in Python for every scene with a weld, a joint relation, a rolling or soft-finger contact or grasp
control); the printout gives both and the ratio, after over before. The scenes whose path was the general one are
also run on it now (``solver="proxsuite"`` keeps a run there) in the same rounds, interleaved: the column "general
now" and the ratio of the two measured side by side.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.errors import PinstabError
from pinstab.readers.sources import bundled_scenes
from pinstab.simulate import default_contacts

PROBE = 0.01  # [s] simulated in the first run of each scene
BUDGET = 2.0  # [CPU s] aimed at per measured run
MAX_DURATION = 1.0  # [s] simulated at most per run
ROUNDS = 3
OUT = Path(__file__).parent / "results" / "scene_paths.json"
BEFORE = Path(__file__).parent / "results" / "scene_paths_before.json"


def timed(scene: pinstab.Scene, duration: float, **options: Any) -> dict[str, Any]:
    """One default ``simulate()`` of ``scene`` over ``duration`` [s] (with ``options``): CPU s, the simulated time
    reached [s], the path and its reason, or the error that stopped it."""
    began = time.process_time()
    try:
        trajectory = pinstab.simulate(
            scene, duration=duration, progress=False, contacts=default_contacts(scene), **options
        )
    except PinstabError as exc:
        reached = getattr(getattr(exc, "trajectory", None), "info", None)
        return {
            "cpu_s": time.process_time() - began,
            "reached_s": reached.t_end if reached is not None else 0.0,
            "path": reached.path if reached is not None else None,
            "path_reason": reached.path_reason if reached is not None else None,
            "error": f"{type(exc).__name__}: {str(exc)[:160]}",
        }
    info = trajectory.info
    return {
        "cpu_s": time.process_time() - began,
        "reached_s": info.t_end,
        "path": info.path,
        "path_reason": info.path_reason,
        "error": None,
    }


def cost(measured: list[dict[str, Any]]) -> float:
    """The median CPU s per simulated second of the runs (the last one's reach) [-]."""
    reached = measured[-1]["reached_s"]
    return float(np.median([run["cpu_s"] for run in measured])) / reached if reached > 0 else math.nan


def main() -> None:
    scenes = {name: pinstab.load_scene(name) for name in bundled_scenes()}
    before = json.loads(BEFORE.read_text())["scenes"]
    was_general = [name for name in scenes if before.get(name, {}).get("path") == "general"]
    durations: dict[str, float] = {}
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name in scenes}
    general_runs: dict[str, list[dict[str, Any]]] = {name: [] for name in was_general}
    for name, scene in scenes.items():
        probe = timed(scene, PROBE)
        per_second = probe["cpu_s"] / max(probe["reached_s"], PROBE)
        durations[name] = float(np.clip(BUDGET / per_second, PROBE, MAX_DURATION)) if probe["error"] is None else 0
        if probe["error"] is not None:
            runs[name].append(probe)
    for _ in range(ROUNDS):
        for name, scene in scenes.items():
            if durations[name]:
                runs[name].append(timed(scene, durations[name]))
                if name in general_runs:
                    general_runs[name].append(timed(scene, durations[name], solver="proxsuite"))
    rows = {}
    for name, measured in runs.items():
        rows[name] = {**measured[-1], "duration_s": durations[name] or PROBE, "cpu_s_per_s": cost(measured)}
        if general_runs.get(name):
            rows[name]["general_now"] = {**general_runs[name][-1], "cpu_s_per_s": cost(general_runs[name])}
    width = max(map(len, rows))
    print(
        f"| {'scene':<{width}} | path before | CPU s/s before | path | CPU s/s | after/before | general now | "
        "after/general now | reason or error |"
    )
    for name, row in rows.items():
        note = row["error"] or row["path_reason"] or ""
        old = before.get(name, {"path": None, "cpu_s_per_s": math.nan})
        ratio = row["cpu_s_per_s"] / old["cpu_s_per_s"]
        now = row.get("general_now", {}).get("cpu_s_per_s", math.nan)
        print(
            f"| {name:<{width}} | {old['path'] or '-'} | {old['cpu_s_per_s']:.3g} | {row['path'] or '-'} | "
            f"{row['cpu_s_per_s']:.3g} | {ratio:.2g} | {now:.3g} | {row['cpu_s_per_s'] / now:.2g} | {note[:90]} |"
        )
    general = sorted(name for name, row in rows.items() if row["path"] == "general")
    print(f"general path: {len(general)} of {len(rows)}: {', '.join(general)}")
    save_results(OUT, {"probe_s": PROBE, "budget_cpu_s": BUDGET, "rounds": ROUNDS, "scenes": rows})


if __name__ == "__main__":
    main()

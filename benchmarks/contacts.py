"""Contacts that switch, on the scenes with closed forms: the error against the closed form and the CPU
time of pinstab (event-driven, ``contacts="event"``; time-stepping, ``contacts="stepping"``), MuJoCo at its
best (elliptic cones, impratio, the noslip solver, the step and the contact stiffness swept, the most
accurate setting kept per row) and a Moreau--Jean loop over Pinocchio 4.1's ADMM in NCP mode
(``pinstab.bench.admm_contacts``, the step swept).

Per row every configuration runs once (the sweep); the most accurate of each simulator (ties within
TIE to the cheaper), and the ADMM loop at its largest step, are then timed again, ROUNDS interleaved
rounds, best of them (``time.process_time``: pinstab's whole ``simulate()`` call, the peers' loops).
Errors: ``pinstab.bench.contact_scenes``. A row whose pinstab scene or contact treatment is not there
(``pinch``, ``contacts="stepping"``, still being built) is skipped with the reason printed.

    python benchmarks/contacts.py    # prints the table, writes benchmarks/contacts/results.{json,md}, error_cost.png
    python benchmarks/contacts.py sphere-spin    # those rows only, nothing written
"""

from __future__ import annotations

import math
import re
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pinstab import load_scene, simulate
from pinstab.bench import contact_scenes as cs
from pinstab.bench import mujoco_contacts as mj
from pinstab.bench import save_results
from pinstab.bench.admm_contacts import ContactProblem, SteppingSettings, pinch_problem, run_contacts, scene_problem
from pinstab.errors import PinstabError

OUT = Path(__file__).parent / "contacts"
ROUNDS = 3
TIE = 1.1  # errors within this factor of the best are ties: the cheaper wins
FLOOR = 1e-16  # errors below are drawn at this value
STEPS = (1e-3, 1e-4)  # [s] pinstab's stepping mode and the ADMM loop
MUJOCO_STEPS = (1e-3, 1e-4)
IMPRATIOS = (1.0, 10.0, 100.0)
NOSLIP = (0, 20)
SOLIMPS = ((0.9, 0.95, 0.001), (0.9999, 0.9999, 0.001))  # MuJoCo's default; as stiff as it allows
TIMECONSTS = (None, 0.02)  # solref: 2 dt (the stiffest); MuJoCo's default
ADMM_LABEL = "Moreau-Jean, dt {dt:g} s"
COARSE = "ADMM at the largest step"
STICK, SLIDE = (math.radians(20), 0.37), (math.radians(30), 0.3)
SPIN = {"v0": 2.0, "omega0": 5.0, "mu": 0.3, "radius": 0.1}
BALL = {"height": 1.0, "restitution": 0.5}
HOLD, SLIP = {"mu": 0.5, "squeeze": 10.0, "mass": 0.5}, {"mu": 0.2, "squeeze": 5.0, "mass": 0.5}


@dataclass(frozen=True)
class Row:
    """One benchmark row: a pinstab scene, its MuJoCo and ADMM models and its score.

    Attributes:
        name: the row. scene, params: ``load_scene(scene, **params)``. duration: [s].
        sample: the sampling interval [s] (None: every step, for times a time-stepper resolves by its step).
        score: ``(samples, events or None) -> errors``; ``errors["error"]`` is the headline (relative, or
            metres for a creep). mujoco, admm: the peers' models. exact: the closed form (for the table).
    """

    name: str
    scene: str
    params: dict[str, float]
    duration: float
    sample: float | None
    score: Callable[[cs.ObjectSamples, list[dict] | None], dict[str, float]]
    mujoco: Callable[[], mj.MujocoScene]
    admm: Callable[[], ContactProblem]
    exact: str


def creep_score(axes: tuple[int, ...]):
    def score(samples: cs.ObjectSamples, events: list[dict] | None) -> dict[str, float]:
        value = cs.creep(samples, axes)
        return {"creep_m": value, "error": value}

    return score


def drop_score(exact: float, axis: int):
    def score(samples: cs.ObjectSamples, events: list[dict] | None) -> dict[str, float]:
        value = cs.relative_error(abs(samples.position[-1, axis] - samples.position[0, axis]), exact)
        return {"position_relative_error": value, "error": value}

    return score


def spin_score(samples: cs.ObjectSamples, events: list[dict] | None) -> dict[str, float]:
    t_star, v_star = cs.rolling_onset(**SPIN)
    if events is None:
        found = cs.slip_end(samples, SPIN["radius"])
    else:
        found = next(event["t"] for event in events if event["to"] == "sticking")
    t_error, v_error = abs(found - t_star), cs.relative_error(samples.velocity[-1, 0], v_star)
    return {"t_star_error_s": t_error, "v_star_relative_error": v_error, "error": max(t_error / t_star, v_error)}


def ball_score(samples: cs.ObjectSamples, events: list[dict] | None) -> dict[str, float]:
    apexes, rest = cs.bounce(**BALL)
    found = cs.apex_gaps(samples, cs.BALL_RADIUS)[: cs.APEXES]
    found = np.pad(found, (0, cs.APEXES - len(found)))  # a missing apex counts as 0 (error 1)
    apex_error = float(np.max(np.abs(found / apexes - 1)))
    if events is not None:
        at_rest = [e["t"] for e in events if e["to"] == "sticking"][-1]
    else:
        try:
            at_rest = cs.rest_time(samples)
        except ValueError:  # still bouncing at the end: the error is at least the run's overshoot
            at_rest = float(samples.t[-1])
    rest_error = cs.relative_error(at_rest, rest)
    return {
        "apex_relative_error": apex_error,
        "rest_time_relative_error": rest_error,
        "error": max(apex_error, rest_error),
    }


ROWS = [
    Row(
        "incline-stick", "incline", {"theta": STICK[0], "mu": STICK[1]}, 10.0, 0.01, creep_score((0, 1)),
        lambda: mj.incline(*STICK), lambda: scene_problem(load_scene("incline", theta=STICK[0], mu=STICK[1])),
        "creep 0 (mu 0.37 > tan 20 deg)",
    ),
    Row(
        "incline-slide", "incline", {"theta": SLIDE[0], "mu": SLIDE[1]}, 2.0, 0.01,
        drop_score(cs.slide_distance(*SLIDE, 2.0), 0),
        lambda: mj.incline(*SLIDE), lambda: scene_problem(load_scene("incline", theta=SLIDE[0], mu=SLIDE[1])),
        f"x(2 s) = {cs.slide_distance(*SLIDE, 2.0):.6f} m",
    ),
    Row(
        "sphere-spin", "sphere-spin", SPIN, 0.5, None, spin_score,
        lambda: mj.sphere_spin(**SPIN), lambda: scene_problem(load_scene("sphere-spin", **SPIN)),
        "t* = {:.6f} s, v* = {:.6f} m/s".format(*cs.rolling_onset(**SPIN)),
    ),
    Row(
        "bouncing-ball", "bouncing-ball", BALL, 1.6, None, ball_score,
        lambda: mj.bouncing_ball(**BALL), lambda: scene_problem(load_scene("bouncing-ball", **BALL)),
        f"apexes e^2k h, rest at {cs.bounce(**BALL)[1]:.6f} s",
    ),
    Row(
        "pinch-hold", "pinch", HOLD, 2.0, 0.01, creep_score((2,)),
        lambda: mj.pinch(**HOLD), lambda: pinch_problem(**HOLD), "creep 0 (2 mu F = 10 N >= m g = 4.9 N)",
    ),
    Row(
        "pinch-slide", "pinch", SLIP, 1.0, 0.01, drop_score(cs.pinch_drop(**SLIP, t=1.0), 2),
        lambda: mj.pinch(**SLIP), lambda: pinch_problem(**SLIP),
        f"z(1 s) = -{cs.pinch_drop(**SLIP, t=1.0):.6f} m",
    ),
]  # fmt: skip


# -- one run of each simulator: (errors, CPU s) -----------------------------------------------------------
def every(row: Row, dt: float) -> int:
    return 1 if row.sample is None else max(1, round(row.sample / dt))


def pinstab_run(row: Row, mode: str, dt: float) -> tuple[dict[str, float], float]:
    scene = load_scene(row.scene, **row.params)
    began = time.process_time()
    if mode == "event":
        run = simulate(scene, contacts="event", dt=row.sample or 1e-3, duration=row.duration)
    else:
        run = simulate(scene, contacts="stepping", dt=dt, duration=row.duration, record_every=every(row, dt))
    cpu = time.process_time() - began
    samples = cs.free_flyer_samples(scene.model, run.t, run.q, run.v)
    return row.score(samples, run.info.contact_events if mode == "event" else None), cpu


def mujoco_run(row: Row, settings: mj.MujocoSettings) -> tuple[dict[str, float], float]:
    samples, cpu = mj.run_mujoco(row.mujoco(), settings, row.duration, every(row, settings.dt))
    return row.score(samples, None), cpu


def admm_run(row: Row, settings: SteppingSettings) -> tuple[dict[str, float], float]:
    problem = row.admm()
    run = run_contacts(problem, settings, row.duration, every(row, settings.dt))
    return row.score(cs.free_flyer_samples(problem.model, run.t, run.q, run.v), None), run.cpu_s


def configurations(row: Row) -> dict[str, list[tuple[str, Callable[[], tuple[dict, float]], dict]]]:
    """Per simulator: (label, run, settings) of every configuration swept on ``row``."""
    frictionless = row.name == "bouncing-ball"
    mujoco = [
        mj.MujocoSettings(dt, impratio, noslip, timeconst=timeconst, solimp=solimp)
        for dt in MUJOCO_STEPS + ((1e-5,) if row.sample is None else ())
        for impratio in ((1.0,) if frictionless else IMPRATIOS)
        for noslip in ((0,) if frictionless else NOSLIP)
        for timeconst in TIMECONSTS
        for solimp in SOLIMPS
    ]
    return {
        "pinstab event": [("event, dop853 rtol 1e-10", lambda: pinstab_run(row, "event", 0.0), {"contacts": "event"})],
        "pinstab stepping": [
            (f"stepping, dt {dt:g} s", lambda dt=dt: pinstab_run(row, "stepping", dt), {"dt": dt}) for dt in STEPS
        ],
        "MuJoCo": [
            (
                s.label() + ("" if s.timeconst is None else f", timeconst {s.timeconst:g} s"),
                lambda s=s: mujoco_run(row, s),
                asdict(s),
            )
            for s in mujoco
        ],
        "ADMM": [
            (
                f"Moreau-Jean, dt {dt:g} s",
                lambda dt=dt: admm_run(row, SteppingSettings(dt)),
                asdict(SteppingSettings(dt)),
            )
            for dt in STEPS
        ],
    }


def attempt(run: Callable[[], tuple[dict, float]]) -> tuple[dict, float] | str:
    """The run's (errors, CPU s), or the reason it could not run (a scene or treatment not there yet)."""
    try:
        return run()
    except (PinstabError, ValueError) as exc:
        return str(exc).splitlines()[0]


def best(results: list[dict]) -> dict | None:
    """The most accurate run (ties within TIE: the cheaper)."""
    ran = [r for r in results if "errors" in r]
    if not ran:
        return None
    least = min(r["errors"]["error"] for r in ran)
    return min((r for r in ran if r["errors"]["error"] <= TIE * least + FLOOR), key=lambda r: r["cpu_s"])


def sweep_row(row: Row) -> dict[str, Any]:
    """Every configuration once, then the bests timed side by side."""
    print(f"== {row.name}: {row.exact}", flush=True)
    sides: dict[str, Any] = {}
    runs: dict[str, Callable] = {}
    for side, configs in configurations(row).items():
        results = []
        for label, run, settings in configs:
            outcome = attempt(run)
            if isinstance(outcome, str):
                print(f"  {side} {label}: skipped: {outcome}")
                results.append({"label": label, "settings": settings, "skipped": outcome})
                if side.startswith("pinstab"):
                    break  # the scene or the treatment is not there: the same for every step
                continue
            errors, cpu = outcome
            results.append({"label": label, "settings": settings, "errors": errors, "cpu_s": cpu})
            runs[f"{side}/{label}"] = run
            print(f"  {side:16s} {label:70s} error {errors['error']:9.2e}  CPU {cpu:7.3f} s", flush=True)
        chosen = best(results)
        sides[side] = {"runs": results, "best": None if chosen is None else chosen["label"]}
    timed = {side: runs[f"{side}/{data['best']}"] for side, data in sides.items() if data["best"] is not None}
    timed[COARSE] = runs[f"ADMM/{ADMM_LABEL.format(dt=STEPS[0])}"]  # the cheapest ADMM loop, beside its best
    times: dict[str, list[float]] = {side: [] for side in timed}
    for _ in range(ROUNDS):
        for side, run in timed.items():
            times[side].append(run()[1])
    sides["ADMM"]["coarse_cpu_s"] = min(times.pop(COARSE))
    for side, values in times.items():
        sides[side]["best_cpu_s"] = min(values)
        sides[side]["best_errors"] = next(r["errors"] for r in sides[side]["runs"] if r["label"] == sides[side]["best"])
    return {
        "name": row.name,
        "scene": row.scene,
        "params": row.params,
        "duration_s": row.duration,
        "exact": row.exact,
        "sides": sides,
    }


# -- table and chart --------------------------------------------------------------------------------------
SIDES = ("pinstab event", "pinstab stepping", "MuJoCo", "ADMM")


def cell(result: dict[str, Any], side: str) -> str:
    data = result["sides"][side]
    if data["best"] is None:
        reason = re.split("[:;]", data["runs"][0]["skipped"])[0]
        return f"skipped ({reason})"
    errors = ", ".join(f"{key} {value:.2g}" for key, value in data["best_errors"].items() if key != "error")
    label = "" if side == "pinstab event" else f"{data['best']}: "
    return f"{label}{errors}; **{data['best_cpu_s']:.3g} s**"


def verdict(result: dict[str, Any]) -> tuple[str, str]:
    """(pinstab event CPU / the ADMM loop's CPU, at its best and at its largest step; whether pinstab's
    event mode is the most accurate)."""
    sides = result["sides"]
    ours, admm = sides["pinstab event"], sides["ADMM"]
    if ours["best"] is None:
        return "-", "-"
    ratio = f"{ours['best_cpu_s'] / admm['best_cpu_s']:.2f} ({ours['best_cpu_s'] / admm['coarse_cpu_s']:.2f})"
    others = [sides[s]["best_errors"]["error"] for s in ("MuJoCo", "ADMM") if sides[s]["best"] is not None]
    return ratio, "yes" if ours["best_errors"]["error"] <= min(others) else "**no**"


def markdown(results: list[dict[str, Any]]) -> str:
    lines = [
        "| row | closed form | pinstab event | pinstab stepping | MuJoCo best | ADMM loop best "
        f"| event CPU / ADMM CPU (at dt {STEPS[0]:g} s) | pinstab most accurate |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for result in results:
        ratio, most = verdict(result)
        cells = " | ".join(cell(result, side) for side in SIDES)
        lines.append(f"| {result['name']} | {result['exact']} | {cells} | {ratio} | {most} |")
    return "\n".join(lines) + "\n"


def chart(results: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = dict(zip(SIDES, ("tab:blue", "tab:cyan", "tab:orange", "tab:green"), strict=True))
    figure, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    for ax, result in zip(axes.flat, results, strict=False):
        for side in SIDES:
            data = result["sides"][side]
            ran = [r for r in data["runs"] if "errors" in r]
            if not ran:
                continue
            ax.scatter(
                [r["cpu_s"] for r in ran],
                [max(r["errors"]["error"], FLOOR) for r in ran],
                s=12,
                alpha=0.35,
                color=colours[side],
            )
            error = max(data["best_errors"]["error"], FLOOR)
            ax.scatter(data["best_cpu_s"], error, s=90, color=colours[side], edgecolor="k", label=side)
        ax.set(xscale="log", yscale="log", title=result["name"], xlabel="CPU s")
        ax.set_ylabel("creep [m]" if "creep_m" in result["sides"]["ADMM"]["best_errors"] else "relative error")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.flat[len(results) :]:
        ax.axis("off")
    figure.suptitle(
        "Contacts against closed forms: error and CPU time (small: every swept setting, one run; large: the most "
        f"accurate, best of {ROUNDS} interleaved; an error of 0 drawn at {FLOOR:g})"
    )
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    print(f"-> {path}")


def main() -> None:
    chosen = sys.argv[1:]  # row names: run those only, write nothing
    began = time.perf_counter()
    results = [sweep_row(row) for row in ROWS if not chosen or row.name in chosen]
    table = markdown(results)
    print(table)
    if chosen:
        return
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "results.md").write_text(table)
    save_results(
        OUT / "results.json", {"rounds": ROUNDS, "tie": TIE, "rows": results, "wall_s": time.perf_counter() - began}
    )
    chart(results, OUT / "error_cost.png")


if __name__ == "__main__":
    main()

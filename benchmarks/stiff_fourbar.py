"""The stiff mechanism (issue 37): ``stiff-fourbar`` (the four-bar whose rocker is a spring-damper of 379 rad/s,
damping ratio 9.5; 2 DOF) over 10 s, every integrator at its best against SciPy's and MuJoCo's, side by side in one
run. The acceptance line: pinstab reaches 1e-6 rad in its coordinates at <= 1/3 the CPU time of SciPy's best
(``Radau`` or ``BDF`` over Pinocchio, at the cheapest tolerance reaching that error) and <= 1/10 of the best explicit
configuration pinstab itself has.

Rows, each swept over its knob (the cheapest configuration within TOLERANCE is its best):

* SciPy ``Radau``, ``BDF`` and ``DOP853`` over Pinocchio (:mod:`pinstab.bench.scipy_peer`: y = (q, v), y' = (v, a),
  a from ``pin.constraintDynamics`` with the spring-damper's joint torques; the implicit ones with ``jac=`` the
  exact rows of q' = v and the acceleration's by central differences), rtol = atol in RTOLS;
* pinstab's explicit integrators: ``rk4`` at RK4_DTS, the embedded pairs (``dopri5``, ``dop853``) at RTOLS;
* pinstab's implicit integrators (every registered integrator whose class says ``implicit = True``): the embedded
  ones (:func:`pinstab.integration.embedded_pairs`) at RTOLS, the fixed-step ones at IMPLICIT_DTS;
* MuJoCo (:mod:`pinstab.bench.mujoco_peer`: the same tree and inertias, the spring-damper as a spatial tendon with
  stiffness, damping and springlength) with ``implicitfast`` and ``implicit`` at MUJOCO_IMPLICIT_DTS and ``RK4`` at
  MUJOCO_RK4_DTS (when mujoco is installed).

Measured as ``pinstab bench`` measures (:func:`pinstab.bench.workprecision.run_config`): pinstab's whole
``simulate()`` call, SciPy's ``solve_ivp``, MuJoCo's stepping loop, CPU time (``time.process_time``). The error is
the largest coordinate error max |q - q_ref| [rad] over the samples (every 1 ms for fixed steps, every 10 ms from
the error-controlled runs' dense output) against the scene's exact reference (``pinstab run stiff-fourbar
--reference exact``: SciPy Radau at rtol = atol = 1e-12 on the open chain's ODE written with Pinocchio alone),
computed once in this run. Every configuration runs once in the order above; then the ones within TOLERANCE (the
candidates for "best") run ROUNDS - 1 more times, interleaved, and their median CPU time is kept.

    python benchmarks/stiff_fourbar.py                  # 10 s (~10 min); prints the table and the ratios
    python benchmarks/stiff_fourbar.py --duration 0.5   # a quick look
    python benchmarks/stiff_fourbar.py --save           # also writes benchmarks/results/stiff_fourbar.json and
                                                        # benchmarks/stiff-fourbar/work_precision.png (from a clean
                                                        # committed tree)
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from pinstab.bench import save_results
from pinstab.bench.scipy_peer import IMPLICIT_SCIPY_PEERS, SCIPY_METHODS
from pinstab.bench.workprecision import ADAPTIVE_OUTPUT_STEP, Config, Result, reference_motion, run_config
from pinstab.integration import INTEGRATORS, embedded_pairs
from pinstab.plotting import pyplot, save_figure

SCENE = "stiff-fourbar"
DURATION = 10.0  # [s]
TOLERANCE = 1e-6  # [rad] the error every row's best must reach
GOALS = {"scipy": 1 / 3, "explicit": 1 / 10}  # pinstab's best implicit over SciPy's best implicit, over its explicit
ROUNDS = 3
SAMPLE_STEP = 1e-3  # [s] the reference's samples (the fixed-step runs' error is measured on every one)
RTOLS = (1e-3, 1e-4, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 1e-10)  # half decades near 1e-6
RK4_DTS = (2e-4, 1e-4, 5e-5, 4e-5, 2.5e-5, 2e-5)  # [s] (RK4 is stable up to 0.31 ms on this scene)
IMPLICIT_DTS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5)  # [s] pinstab's fixed-step implicit schemes
MUJOCO_IMPLICIT_DTS = (1e-3, 1e-4, 1e-5, 1e-6)  # [s]
MUJOCO_RK4_DTS = (2e-4, 1e-4, 5e-5, 2e-5, 1e-5)  # [s]
EXPLICIT_FIXED = ("rk4",)
OUT = Path(__file__).parent / "results" / "stiff_fourbar.json"
CHART = Path(__file__).parent / "stiff-fourbar" / "work_precision.png"


def implicit_integrators() -> list[str]:
    """pinstab's registered integrators whose class says ``implicit = True``."""
    return [entry.name for entry in INTEGRATORS.entries() if getattr(entry.factory, "implicit", False)]


def configurations() -> dict[str, tuple[str, Config]]:
    """Every row: its label -> (its group, its configuration). Groups: ``scipy-radau``, ``scipy-bdf``,
    ``scipy-dop853``, ``pinstab explicit``, ``pinstab implicit``, ``mujoco <integrator>``."""
    rows: dict[str, tuple[str, Config]] = {}
    for peer, method in SCIPY_METHODS.items():
        for rtol in RTOLS:
            rows[f"{peer} rtol={rtol:g}"] = (
                peer,
                Config(peer, method.lower(), ADAPTIVE_OUTPUT_STEP, peer, 0.0, 0.0, rtol=rtol),
            )
    pairs, implicit = embedded_pairs(), implicit_integrators()
    explicit = [(name, "dt", dt) for name in EXPLICIT_FIXED for dt in RK4_DTS]
    explicit += [(name, "rtol", rtol) for name in pairs if name not in implicit for rtol in RTOLS]
    stiff = [(name, "rtol", rtol) for name in implicit if name in pairs for rtol in RTOLS]
    stiff += [(name, "dt", dt) for name in implicit if name not in pairs for dt in IMPLICIT_DTS]
    for group, runs in (("pinstab explicit", explicit), ("pinstab implicit", stiff)):
        for name, knob, value in runs:
            config = (
                Config("baumgarte", name, value)
                if knob == "dt"
                else Config("baumgarte", name, ADAPTIVE_OUTPUT_STEP, rtol=value)
            )
            rows[f"pinstab {name} {knob}={value:g}"] = (group, config)
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed: no MuJoCo rows (pip install 'pinstab[bench]')")
        return rows
    for scheme, dts in (
        ("implicitfast", MUJOCO_IMPLICIT_DTS),
        ("implicit", MUJOCO_IMPLICIT_DTS),
        ("rk4", MUJOCO_RK4_DTS),
    ):
        for dt in dts:
            rows[f"mujoco {scheme} dt={dt:g}"] = (
                f"mujoco {scheme}",
                Config("mujoco", scheme, dt, "mujoco", solref=(2 * dt, 1.0)),
            )
    return rows


def within(result: Result) -> bool:
    """Whether a run reached TOLERANCE."""
    return not result.diverged and result.trajectory_error <= TOLERANCE


def measure(duration: float) -> tuple[str, dict[str, dict[str, Any]]]:
    """Every row run once, those within TOLERANCE ROUNDS - 1 more times interleaved; returns the reference's kind and
    per label its group, configuration, CPU s per round, error [rad], evaluations and note."""
    reference = reference_motion(SCENE, {}, duration, exact_step=SAMPLE_STEP)
    rows = configurations()
    results: dict[str, Result] = {}
    cpu: dict[str, list[float]] = {}
    for label, (_, config) in rows.items():
        results[label] = run_config(SCENE, {}, config, duration, reference)
        cpu[label] = [results[label].cpu_per_sim_s * duration]
        print(f"  {label:40s} {cpu[label][0]:9.3f} CPU s  error {results[label].trajectory_error:9.3g}", flush=True)
    candidates = [label for label, result in results.items() if within(result)]
    for _ in range(ROUNDS - 1):
        for label in candidates:
            again = run_config(SCENE, {}, rows[label][1], duration, reference)
            cpu[label].append(again.cpu_per_sim_s * duration)
    table = {}
    for label, (group, _) in rows.items():
        result = results[label]
        table[label] = {
            "group": group,
            "config": result.row(),
            "cpu_s": float(np.median(cpu[label])),
            "cpu_s_rounds": cpu[label],
            "error": result.trajectory_error if math.isfinite(result.trajectory_error) else None,
            "evaluations": result.evaluations,
            "diverged": result.diverged,
            "note": result.note,
            "within": within(result),
        }
    return reference.kind, table


def best(table: dict[str, dict[str, Any]], groups: tuple[str, ...]) -> str | None:
    """The cheapest label within TOLERANCE among ``groups``, or None."""
    eligible = [label for label, row in table.items() if row["group"] in groups and row["within"]]
    return min(eligible, key=lambda label: table[label]["cpu_s"]) if eligible else None


def ratios(table: dict[str, dict[str, Any]]) -> tuple[dict[str, str | None], dict[str, dict[str, Any]]]:
    """The best of each group and the acceptance line's ratios (None where a side has no run within TOLERANCE)."""
    groups = sorted({row["group"] for row in table.values()})
    bests = {group: best(table, (group,)) for group in groups}
    bests["scipy implicit"] = best(table, IMPLICIT_SCIPY_PEERS)
    ours = bests.get("pinstab implicit")
    acceptance = {}
    for name, other in (("scipy", bests["scipy implicit"]), ("explicit", bests.get("pinstab explicit"))):
        value = None if ours is None or other is None else table[ours]["cpu_s"] / table[other]["cpu_s"]
        acceptance[f"pinstab implicit / {'scipy implicit' if name == 'scipy' else 'pinstab explicit'}"] = {
            "value": value,
            "goal": GOALS[name],
            "met": None if value is None else value <= GOALS[name],
        }
    return bests, acceptance


def chart(table: dict[str, dict[str, Any]], duration: float, reference: str) -> None:
    """Error against CPU s, one line per integrator of each group (dashed: the peers), the tolerance marked."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9.5, 5.5), dpi=110)
    ax.set_prop_cycle(color=plt.get_cmap("tab20").colors)
    lines: dict[str, list[dict[str, Any]]] = {}
    for row in table.values():
        if row["error"] is not None and row["error"] > 0 and not row["diverged"]:
            name = row["group"] if row["config"]["peer"] else f"pinstab {row['config']['integrator']}"
            lines.setdefault(name, []).append(row)
    for name, rows in sorted(lines.items()):
        rows.sort(key=lambda row: -(row["config"]["rtol"] or row["config"]["dt"]))  # along the knob
        ax.loglog(
            [row["cpu_s"] for row in rows],
            [row["error"] for row in rows],
            "--" if not name.startswith("pinstab") else "-",
            marker="s" if rows[0]["config"]["rtol"] is not None else "o",
            ms=4,
            label=name,
        )
    ax.axhline(TOLERANCE, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel(f"CPU time for {duration:g} s simulated [s]")
    ax.set_ylabel("max |q - q_ref| [rad]")
    ax.set_title(f"{SCENE}, {duration:g} s: work-precision (reference: {reference})", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), title="dashed: peers; squares: rtol")
    CHART.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, CHART)
    print(f"-> {CHART}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=DURATION, help=f"simulated time [s] (default {DURATION:g})")
    parser.add_argument("--save", action="store_true", help=f"write {OUT.name} and the chart")
    args = parser.parse_args(argv)
    print(f"{SCENE}, {args.duration:g} s; reference computed once; each row swept:")
    reference, table = measure(args.duration)
    bests, acceptance = ratios(table)
    print(
        f"\n{'configuration':40s} {'CPU s':>9s} {'error [rad]':>12s}  (median of {ROUNDS} rounds within {TOLERANCE:g})"
    )
    for label, row in table.items():
        error = "diverged" if row["diverged"] else f"{row['error']:.3g}"
        print(f"{label:40s} {row['cpu_s']:9.3f} {error:>12s}{'  *' if row['within'] else ''}")
    print(f"\nbest within {TOLERANCE:g} rad (cheapest of each group):")
    for group, label in bests.items():
        found = "none reaches it" if label is None else f"{label}: {table[label]['cpu_s']:.3f} CPU s"
        print(f"  {group:18s} {found}")
    missing = "n/a (no run within the tolerance)" if implicit_integrators() else "n/a (no implicit integrator yet)"
    for name, entry in acceptance.items():
        value = missing if entry["value"] is None else f"{entry['value']:.3f}"
        verdict = "" if entry["met"] is None else ("  MET" if entry["met"] else "  NOT MET")
        print(f"{name}: {value} (goal <= {entry['goal']:.3f}){verdict}")
    if args.save:
        save_results(
            OUT,
            {
                "scene": SCENE,
                "duration_s": args.duration,
                "tolerance": TOLERANCE,
                "rounds": ROUNDS,
                "reference": reference,
                "sample_step_s": SAMPLE_STEP,
                "rows": table,
                "best": bests,
                "acceptance": acceptance,
            },
        )
        chart(table, args.duration, reference)


if __name__ == "__main__":
    main()

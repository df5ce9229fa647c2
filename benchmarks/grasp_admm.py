"""allegro-sphere (the Allegro hand holding a ball on four sticking point contacts, pushed with 0.2 N),
2 s: ``pinstab.simulate()`` against a hand-written loop that steps the same hand and ball with
Pinocchio 4.1's ADMM contact solver (``pinstab.bench.admm_peer``), each at several settings.

Per run: CPU seconds per simulated second (``simulate()``: the whole call; the peer: its loop), the
largest contact-force difference to the reference run and to pinstab's best run at common times (every
10 ms), the creep (the largest distance between each contact's material points on ball and fingertip,
``FingertipContact.slip``) and the ball's displacement relative to the fingertips (the ball centre against
where the rigid motion best fitting the four fingertip points carries it). "Best" on each side: the
cheapest run whose forces are within FORCE_TARGET of the reference and whose creep is below CREEP_TARGET;
the two bests, and pinstab's defaults against the peer with the same scheme and step, are then timed
side by side, interleaved, median of ROUNDS.

    python benchmarks/grasp_admm.py    # prints the table, writes benchmarks/results/grasp_admm.json
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.assembly import assemble
from pinstab.bench import save_results
from pinstab.bench.admm_peer import PeerSettings, run_peer
from pinstab.errors import PinstabError
from pinstab.model import ConstrainedModel

SCENE = "allegro-sphere"
DURATION = 2.0  # [s]
GRID = 0.01  # [s] both sides keep a sample every GRID (the common times)
FORCE_TARGET = 1e-4  # [N] against the reference (normal forces 1.5 to 2.5 N)
CREEP_TARGET = 1e-6  # [m]
ROUNDS = 3
KP, KD = 100.0, 20.0  # [1/s^2], [1/s]: pinstab's default Baumgarte gains
REFERENCE = {"method": "baumgarte", "integrator": "dop853", "dt": 2.5e-3, "solver": "dense"}
PINSTAB_RUNS = [
    {"method": "baumgarte", "integrator": "rk4", "dt": 1e-3, "solver": None},  # the defaults
    {"method": "baumgarte", "integrator": "rk4", "dt": 1e-3, "solver": "dense"},
    {"method": "baumgarte", "integrator": "rk4", "dt": 2e-3, "solver": None},
    {"method": "baumgarte", "integrator": "rk4", "dt": 2.5e-3, "solver": None},
    {"method": "baumgarte", "integrator": "rk4", "dt": GRID / 3, "solver": None},
    {"method": "baumgarte", "integrator": "rk4", "dt": 5e-3, "solver": None},
    {"method": "baumgarte", "integrator": "dop853", "dt": 5e-3, "solver": None},
    {"method": "baumgarte", "integrator": "dop853", "dt": 1e-2, "solver": None},
    {"method": "baumgarte", "integrator": "dop853", "dt": 1e-2, "solver": "dense"},
    # error control: steps of the tolerance's choosing, samples every GRID from the dense output
    {"method": "baumgarte", "integrator": "dop853", "dt": 1e-2, "solver": None, "rtol": 1e-6},
    {"method": "baumgarte", "integrator": "dop853", "dt": 1e-2, "solver": None, "rtol": 1e-5},
    {"method": "baumgarte", "integrator": "semi-implicit-euler", "dt": 1e-3, "solver": None},
]
PEER_RUNS = [
    PeerSettings("rk4", 1e-3, KP, KD),
    PeerSettings("rk4", 2e-3, KP, KD),
    PeerSettings("rk4", 2e-3, KP, KD, tolerance=1e-10),
    PeerSettings("rk4", 2.5e-3, KP, KD),
    PeerSettings("rk4", GRID / 3, KP, KD),  # between 2.5 ms (within the targets) and 5 ms (3 % over the force target)
    PeerSettings("rk4", 5e-3, KP, KD),
    PeerSettings("semi-implicit-euler", 1e-3, KP, KD),
    PeerSettings("semi-implicit-euler", 5e-4, KP, KD),
    PeerSettings("semi-implicit-euler", 5e-4, 1e4, 200.0),
    PeerSettings("velocity-level", 1e-3, erp=0.2),
    PeerSettings("velocity-level", 1e-3, erp=1.0),
    PeerSettings("velocity-level", 1e-3, erp=0.2, compliance=1e-2),
    PeerSettings("velocity-level", 5e-4, erp=0.2),
    PeerSettings("velocity-level", 2.5e-4, erp=0.2),
]
OUT = Path(__file__).parent / "results" / "grasp_admm.json"


# -- creep ----------------------------------------------------------------------------------------------
def rigid_fit(before: np.ndarray, after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the rigid motion best carrying the points ``before`` (n, 3) to ``after`` [m] (Kabsch)."""
    centre_before, centre_after = before.mean(axis=0), after.mean(axis=0)
    u, _, vt = np.linalg.svd((before - centre_before).T @ (after - centre_after))
    rotation = vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))]) @ u.T
    return rotation, centre_after - rotation @ centre_before


def creep(model: ConstrainedModel, qs: np.ndarray) -> dict[str, Any]:
    """Over the states ``qs``: per contact the largest distance between its material points on ball
    and fingertip [m] (``FingertipContact.slip``), and the ball's largest displacement relative to the
    fingertips [m]: its centre against where the rigid motion best fitting the fingertip points carries
    the start's centre."""
    contacts = model.constraints.constraints
    ball = model.model.getFrameId(contacts[0].object_name)
    kin = model.kin
    slips = np.zeros((len(qs), len(contacts)))
    displacement = np.zeros(len(qs))
    start = None
    for k, q in enumerate(qs):
        kin.update_positions(q)
        slips[k] = [contact.slip(kin) for contact in contacts]
        tips = np.array([kin.placement(contact.finger_frame).translation for contact in contacts])
        centre = kin.placement(ball).translation.copy()
        if start is None:
            start = (tips, centre)
        rotation, shift = rigid_fit(start[0], tips)
        displacement[k] = np.linalg.norm(centre - rotation @ start[1] - shift)
    return {
        "max_slip_m": float(slips.max()),
        "max_slip_per_contact_m": {c.name: float(s) for c, s in zip(contacts, slips.max(axis=0), strict=True)},
        "final_slip_m": float(slips[-1].max()),
        "max_ball_displacement_m": float(displacement.max()),
    }


# -- runs -------------------------------------------------------------------------------------------------
def pinstab_run(scene: pinstab.Scene, config: dict[str, Any]) -> dict[str, Any]:
    """``simulate()`` with ``config``: CPU s, samples every GRID and their multipliers (not timed)."""
    began = time.process_time()
    trajectory = pinstab.simulate(
        scene,
        config["method"],
        config["integrator"],
        config["dt"],
        DURATION,
        solver=config["solver"],
        record_every=round(GRID / config["dt"]),
        rtol=config.get("rtol"),
    )
    cpu = time.process_time() - began
    return {"cpu_s": cpu, "q": trajectory.q, "forces": trajectory.multipliers, "path": trajectory.info.path}


def peer_run(scene: pinstab.Scene, start, settings: PeerSettings) -> dict[str, Any]:
    run = run_peer(scene, start.q, start.v, settings, DURATION, record_every=round(GRID / settings.dt))
    return {
        "cpu_s": run.cpu_s,
        "q": run.q,
        "forces": run.forces,
        "admm_iterations_mean": run.iterations[0],
        "admm_iterations_max": run.iterations[1],
        "admm_worst_primal": run.worst_primal,
        "admm_failed_solves": run.failed,
    }


def label(config: dict[str, Any] | PeerSettings) -> str:
    if isinstance(config, PeerSettings):
        extra = f"Kp {config.kp:g} Kd {config.kd:g}" if config.scheme != "velocity-level" else f"erp {config.erp:g}"
        if config.compliance:
            extra += f" compliance {config.compliance:g}"
        if config.tolerance != PeerSettings.tolerance:
            extra += f" tol {config.tolerance:g}"
        return f"ADMM {config.scheme} dt {config.dt * 1e3:g} ms {extra}"
    solver = config["solver"] or "default solver"
    control = f" rtol {config['rtol']:g}" if config.get("rtol") else ""
    return f"pinstab {config['method']} {config['integrator']} dt {config['dt'] * 1e3:g} ms{control} {solver}"


def summarize(raw: dict[str, Any], model: ConstrainedModel, reference: dict[str, Any]) -> dict[str, Any]:
    """CPU s per simulated s, force difference to the reference [N], creep; the samples are dropped."""
    summary = {key: value for key, value in raw.items() if key not in ("q", "forces")}
    summary["cpu_s_per_simulated_s"] = raw["cpu_s"] / DURATION
    summary["force_difference_to_reference_N"] = float(np.abs(raw["forces"] - reference["forces"]).max())
    summary["q_difference_to_reference"] = float(np.abs(raw["q"] - reference["q"]).max())
    summary.update(creep(model, raw["q"]))
    return summary


def measured(run) -> dict[str, Any] | None:
    """The run's result, or None with the reason printed (a run that fails is reported, not chosen)."""
    try:
        return run()
    except PinstabError as exc:
        print(f"  failed: {str(exc).splitlines()[0]}")
        return None


def sweep(scene, start, model, reference) -> tuple[dict[str, dict], dict[str, dict], dict[str, Any]]:
    """Every configuration once: (pinstab rows, peer rows, raw samples by label)."""
    rows: dict[str, dict[str, dict]] = {"pinstab": {}, "peer": {}}
    raw: dict[str, Any] = {}
    for side, configs in (("pinstab", PINSTAB_RUNS), ("peer", PEER_RUNS)):
        for config in configs:
            name = label(config)
            print(name, flush=True)
            if side == "pinstab":
                result = measured(lambda config=config: pinstab_run(scene, config))
            else:
                result = measured(lambda config=config: peer_run(scene, start, config))
            if result is None:
                rows[side][name] = {"failed": True}
                continue
            raw[name] = result
            rows[side][name] = summarize(result, model, reference)
    return rows["pinstab"], rows["peer"], raw


def cheapest(rows: dict[str, dict]) -> str:
    """The label of the cheapest run within both targets."""
    within = [
        name
        for name, row in rows.items()
        if not row.get("failed")
        and row["force_difference_to_reference_N"] <= FORCE_TARGET
        and row["max_slip_m"] <= CREEP_TARGET
    ]
    return min(within, key=lambda name: rows[name]["cpu_s_per_simulated_s"])


def side_by_side(scene, start, ours: dict[str, Any], theirs: PeerSettings) -> dict[str, Any]:
    """A pinstab run and a peer run timed interleaved, median of ROUNDS: CPU s per simulated s, ratio."""
    times: dict[str, list[float]] = {"pinstab": [], "peer": []}
    for _ in range(ROUNDS):
        times["pinstab"].append(pinstab_run(scene, ours)["cpu_s"])
        times["peer"].append(peer_run(scene, start, theirs)["cpu_s"])
    pinstab_s, peer_s = (float(np.median(times[side])) / DURATION for side in ("pinstab", "peer"))
    print(f"{label(ours)} against {label(theirs)}: {pinstab_s:.3f} / {peer_s:.3f} CPU s/s = {pinstab_s / peer_s:.2f}")
    return {
        "pinstab": label(ours),
        "peer": label(theirs),
        "pinstab_cpu_s_per_simulated_s": pinstab_s,
        "peer_cpu_s_per_simulated_s": peer_s,
        "ratio_pinstab_over_peer": pinstab_s / peer_s,
        "rounds": ROUNDS,
    }


def print_table(rows: dict[str, dict]) -> None:
    print(
        f"{'run':58s} {'CPU s/s':>8s} {'|df| ref N':>10s} {'|df| pinstab':>12s} {'max slip m':>10s} "
        f"{'ball rel m':>10s} {'ADMM it':>8s}"
    )
    for name, row in rows.items():
        if row.get("failed"):
            print(f"{name:58s} failed")
            continue
        iterations = f"{row['admm_iterations_mean']:.1f}" if "admm_iterations_mean" in row else ""
        print(
            f"{name:58s} {row['cpu_s_per_simulated_s']:8.3f} {row['force_difference_to_reference_N']:10.2e} "
            f"{row['force_difference_to_pinstab_best_N']:12.2e} {row['max_slip_m']:10.2e} "
            f"{row['max_ball_displacement_m']:10.2e} {iterations:>8s}"
        )


def main() -> None:
    scene = pinstab.load_scene(SCENE)
    model = ConstrainedModel(scene)
    start = assemble(model, scene.q0, scene.v0)
    print(label(REFERENCE) + " (reference)", flush=True)
    reference = pinstab_run(scene, REFERENCE)
    ours, theirs, raw = sweep(scene, start, model, reference)
    best_ours, best_theirs = cheapest(ours), cheapest(theirs)
    for name, row in {**ours, **theirs}.items():
        if not row.get("failed"):
            row["force_difference_to_pinstab_best_N"] = float(
                np.abs(raw[name]["forces"] - raw[best_ours]["forces"]).max()
            )
    ours_config = next(c for c in PINSTAB_RUNS if label(c) == best_ours)
    theirs_config = next(c for c in PEER_RUNS if label(c) == best_theirs)
    print_table({**ours, **theirs})
    print(f"best pinstab: {best_ours}\nbest peer:    {best_theirs}\nside by side, {ROUNDS} interleaved rounds:")
    ratios = {
        "best": side_by_side(scene, start, ours_config, theirs_config),
        "same scheme (pinstab's defaults)": side_by_side(scene, start, PINSTAB_RUNS[0], PEER_RUNS[0]),
    }
    reference_summary = {"config": label(REFERENCE), "cpu_s": reference["cpu_s"], **creep(model, reference["q"])}
    save_results(
        OUT,
        {
            "scene": SCENE,
            "duration_s": DURATION,
            "grid_s": GRID,
            "targets": {"force_N": FORCE_TARGET, "creep_m": CREEP_TARGET},
            "reference": reference_summary,
            "pinstab": ours,
            "peer": theirs,
            "best": {"pinstab": best_ours, "peer": best_theirs},
            "side_by_side": ratios,
        },
    )


if __name__ == "__main__":
    main()

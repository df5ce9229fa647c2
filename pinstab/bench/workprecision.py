"""Work-precision sweeps: CPU cost against accuracy for methods x integrators x steps, peers included.

Each configuration is simulated from the same assembled start; the metrics are CPU seconds per
simulated second (the whole ``simulate()`` call for pinstab; the peers' bare loops), position and
velocity drift, the trajectory error against a reference, and the energy error. The reference is an
independent minimal-coordinate model for the four-bar and the N-four-bar, else the scene with
``projection`` + ``dop853`` at a small step (stated in the results as ``reference``); every run keeps
the samples on the reference's grid. Configurations run on Dask (an embedded LocalCluster, or a scheduler address) or
serially; both give the same figures but the timings.
"""

from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..analysis import exact_name, exact_reference
from ..assembly import assemble
from ..errors import PinstabError
from ..files import atomic_output, check_output
from ..model import ConstrainedModel
from ..scene import load_scene
from ..simulate import MIN_RTOL, simulate
from ..trajectory import configurations_at
from . import stamped
from .cluster import dask_client, progress
from .mujoco_peer import run_mujoco
from .peers import PEER_SCHEMES, native_pinocchio
from .scipy_peer import SCIPY_METHODS, run_scipy

PEER_GAINS = (10.0, 2.0 * math.sqrt(10.0))  # Pinocchio's closed-chain example
SWEPT_KP = (10.0, 100.0, 1e3, 1e4)  # the hand-written loop's gains, Kd = 2 sqrt(Kp) (10: the example's Kd)
PEER_DTS = (4e-3, 2e-3, 1e-3, 7.5e-4, 5e-4, 2.5e-4)  # [s] the hand-written loop's steps
MUJOCO_INTEGRATORS = ("euler", "implicitfast", "rk4")
MUJOCO_DTS = (1e-3, 1e-4, 1e-5)  # [s], each with solref time constant 2 dt (MuJoCo's stiffest advised)
RTOLS = (1e-5, 1e-6, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 1e-10)  # error-controlled runs: pinstab's and SciPy's
ADAPTIVE_METHODS = ("baumgarte", "projection")  # pinstab's error-controlled runs (dop853)
SCIPY_KP = (0.0, 10.0, 100.0)  # the SciPy peer's Baumgarte gains, Kd = 2 sqrt(Kp)
ADAPTIVE_OUTPUT_STEP = 1e-2  # [s] the samples of error-controlled runs (their dense output)
EXACT_REFERENCE_STEP = 1e-4  # [s] samples of an exact reference (SciPy DOP853 at 1e-12 between them)
GENERIC_REFERENCE_STEP = 5e-4  # [s] projection + dop853 (7e-12 rad on the four-bar at 2e-3 against its reference)
MAX_RUN_STEPS = 10**8  # steps of one run of a sweep (the reference included): beyond, days of work


@dataclass(frozen=True)
class Config:
    """One run: a pinstab method (``peer`` None) or a peer (``pinocchio-native``, ``mujoco``, ``scipy-dop853``,
    ``scipy-radau``, ``scipy-bdf``) at gains (kp, kd); with ``rtol``, error-controlled (pinstab's ``--rtol``,
    SciPy's methods) and ``dt`` the step of its samples."""

    method: str
    integrator: str
    dt: float
    peer: str | None = None
    kp: float | None = None
    kd: float | None = None
    solref: tuple[float, float] | None = None
    rtol: float | None = None

    @property
    def curve(self) -> str:
        if self.peer is None:
            return f"{self.method} + {self.integrator}" + (" (rtol)" if self.rtol is not None else "")
        if self.peer in SCIPY_METHODS:
            return f"{self.peer} Kp={self.kp:g}"
        if self.peer == "mujoco":
            tied = self.solref is not None and math.isclose(self.solref[0], 2 * self.dt)
            return f"mujoco solref={'2 dt' if tied else f'{self.solref[0]:g}'} + {self.integrator}"
        return f"{self.peer} Kp={self.kp:g} + {self.integrator}"


@dataclass
class Result:
    """The measured figures of one configuration (NaN where a run diverged)."""

    config: Config
    cpu_per_sim_s: float = math.nan
    max_position_drift: float = math.nan
    max_velocity_drift: float = math.nan
    trajectory_error: float = math.nan
    energy_error: float = math.nan
    diverged: bool = False
    note: str = ""
    evaluations: int | None = None
    drift_series: list[float] = field(default_factory=list)
    drift_times: list[float] = field(default_factory=list)

    def row(self) -> dict[str, Any]:
        row = {**asdict(self.config), "curve": self.config.curve}
        for key in ("cpu_per_sim_s", "max_position_drift", "max_velocity_drift", "trajectory_error", "energy_error"):
            value = getattr(self, key)
            row[key] = value if math.isfinite(value) else None
        row.update(diverged=self.diverged, note=self.note, evaluations=self.evaluations)
        return row


@dataclass
class Reference:
    """The reference motion every configuration is compared with, sampled every ``dt`` [s]."""

    kind: str
    t: np.ndarray
    q: np.ndarray
    dt: float


def reference_motion(
    scene_name: str, parameters: dict[str, Any], duration: float, exact_step: float = EXACT_REFERENCE_STEP
) -> Reference:
    """The scene's exact motion where it has one (:data:`pinstab.analysis.EXACT_REFERENCES`: the four-bar's
    crank-angle equation, the N-four-bar's parallelogram pendulum, stiff-fourbar's spring chain), sampled every
    ``exact_step`` [s]; any other scene simulated with projection + dop853 at :data:`GENERIC_REFERENCE_STEP`."""
    scene = load_scene(scene_name, **parameters)
    start = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    if exact_name(scene) is not None:
        dt = exact_step
        t = np.arange(int(round(duration / dt)) + 1) * dt
        exact = exact_reference(scene, start.q, start.v, t)
        return Reference(exact.kind, t, exact.q, dt)
    dt = GENERIC_REFERENCE_STEP
    fine = simulate(scene, method="projection", integrator="dop853", dt=dt, duration=duration, contacts="held")
    return Reference(f"{scene.name} at dt = {dt:g} s with projection + dop853", fine.t, fine.q, dt)


def run_config(
    scene_name: str, parameters: dict[str, Any], config: Config, duration: float, reference: Reference
) -> Result:
    """Simulate one configuration and measure it (a pure function of its arguments, for Dask)."""
    import warnings

    from ..errors import UnstableGainsWarning

    scene = load_scene(scene_name, **parameters)
    result = Result(config)
    steps = int(round(duration / config.dt))
    every = max(1, round(reference.dt / config.dt))  # the samples the error is measured on
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnstableGainsWarning)
            if config.peer is None:
                start = time.process_time()
                traj = simulate(
                    scene,
                    method=config.method,
                    integrator=config.integrator,
                    dt=config.dt,
                    duration=duration,
                    record_every=every,
                    rtol=config.rtol,
                    contacts="held",  # the method's rows, whatever the scene's contacts
                    **({} if config.kp is None else {"kp": config.kp, "kd": config.kd}),
                )
                cpu = time.process_time() - start
                t, q, v = traj.t, traj.q, traj.v
                result.evaluations = traj.info.solver_statistics.solves
            else:
                start_state = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
                if config.peer in SCIPY_METHODS:
                    q, v, cpu, result.evaluations = run_scipy(
                        scene,
                        start_state.q,
                        start_state.v,
                        config.dt,
                        steps,
                        config.kp,
                        config.kd,
                        config.rtol,
                        config.peer,
                    )
                    t = np.arange(steps + 1) * config.dt
                elif config.peer == "mujoco":
                    q, v, cpu = run_mujoco(
                        scene, start_state.q, start_state.v, config.dt, steps, config.integrator, config.solref, every
                    )
                    t = np.arange(len(q)) * every * config.dt
                else:
                    q, v, cpu = native_pinocchio(
                        scene, start_state.q, start_state.v, config.dt, steps, config.kp, config.kd, config.integrator
                    )
                    t = np.arange(steps + 1) * config.dt
    except PinstabError as exc:
        result.diverged, result.note = True, f"{type(exc).__name__}: {exc}"[:200]
        return result
    metrics = _measure(scene, t, q, v, reference)
    if metrics is None:
        result.diverged, result.note = True, "non-finite state"
        return result
    result.cpu_per_sim_s = cpu / duration
    result.max_position_drift, result.max_velocity_drift, result.trajectory_error, result.energy_error, drift = metrics
    stride = max(1, len(t) // 400)
    result.drift_series, result.drift_times = drift, [float(x) for x in t[::stride]]
    return result


def _measure(scene, t, q, v, reference: Reference):
    if not (np.isfinite(q).all() and np.isfinite(v).all()):
        return None
    model = ConstrainedModel(scene)
    position, velocity, energy = [], [], []
    for qk, vk in zip(q, v, strict=True):
        position_drift, velocity_drift = model.violation(qk, vk, 0.0)
        position.append(position_drift)
        velocity.append(velocity_drift)
        energy.append(model.energy(qk, vk))
    error = _trajectory_error(scene.model, t, q, reference)
    thinned = position[:: max(1, len(position) // 400)]
    return max(position), max(velocity), error, float(np.max(np.abs(np.array(energy) - energy[0]))), thinned


def _trajectory_error(model: pin.Model, t: np.ndarray, q: np.ndarray, reference: Reference) -> float:
    """max |q - q_ref| [rad, m] over the samples on the reference's grid (all of them for steps that are
    multiples of its step; interpolated on the group where no sample falls on it)."""
    index = t / reference.dt
    on_grid = (np.abs(index - np.round(index)) < 1e-6) & (np.round(index) < len(reference.t))
    if on_grid.any():
        expected = reference.q[np.round(index[on_grid]).astype(int)]
        samples = q[on_grid]
    else:
        expected, samples = configurations_at(reference.t, reference.q, model, t), q
    return max(float(np.max(np.abs(pin.difference(model, a, b)))) for a, b in zip(samples, expected, strict=True))


def default_configs(
    methods: list[str],
    integrators: list[str],
    dts: list[float],
    mujoco: bool = True,
    peer_dts: tuple[float, ...] = PEER_DTS,
    mujoco_dts: tuple[float, ...] = MUJOCO_DTS,
    rtols: tuple[float, ...] = RTOLS,
    constrained: bool = True,
) -> list[Config]:
    """pinstab's methods x integrators x ``dts``, and its error-controlled dop853 (:data:`ADAPTIVE_METHODS`)
    at ``rtols``; SciPy's DOP853, Radau and BDF over Pinocchio at ``rtols`` and the gains :data:`SCIPY_KP`;
    the hand-written Pinocchio loop with semi-implicit Euler and RK4 at every one of ``peer_dts`` and the gains
    :data:`SWEPT_KP`; and (when installed and ``mujoco``) MuJoCo with its Euler, implicitfast and RK4
    integrators at ``mujoco_dts`` with ``solref`` time constant 2 dt. A scene without constraints
    (``constrained`` False) has no Baumgarte gain to sweep: its peers run at Kp = Kd = 0 only. Error-controlled
    runs are sampled every :data:`ADAPTIVE_OUTPUT_STEP`."""
    configs = [Config(m, i, dt) for m in methods for i in integrators for dt in dts]
    configs += [Config(m, "dop853", ADAPTIVE_OUTPUT_STEP, rtol=rtol) for m in ADAPTIVE_METHODS for rtol in rtols]
    configs += [
        Config(peer, method.lower(), ADAPTIVE_OUTPUT_STEP, peer, kp, 2.0 * math.sqrt(kp), rtol=rtol)
        for peer, method in SCIPY_METHODS.items()
        for kp in (SCIPY_KP if constrained else (0.0,))
        for rtol in rtols
    ]
    for kp in SWEPT_KP if constrained else (0.0,):
        kd = PEER_GAINS[1] if kp == PEER_GAINS[0] else 2.0 * math.sqrt(kp)
        configs += [
            Config("pinocchio-native", scheme, dt, "pinocchio-native", kp, kd)
            for scheme in PEER_SCHEMES
            for dt in peer_dts
        ]
    if mujoco and _has_mujoco():
        configs += [
            Config("mujoco", scheme, dt, "mujoco", solref=(2 * dt, 1.0))
            for scheme in MUJOCO_INTEGRATORS
            for dt in mujoco_dts
        ]
    return configs


def _has_mujoco() -> bool:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        return False
    return True


def sweep(
    scene_name: str,
    parameters: dict[str, Any],
    configs: list[Config],
    duration: float,
    scheduler: str | None = None,
    serial: bool = False,
    show_progress: bool = False,
) -> tuple[Reference, list[Result]]:
    """Run every configuration (on Dask unless ``serial``) and return the reference and results.

    Raises:
        PinstabError: no configuration, a duration or step out of range (:func:`check_sweep`), or a
            scheduler that cannot be reached.
    """
    check_sweep(configs, duration)
    reference = reference_motion(scene_name, parameters, duration)
    if serial:
        results = []
        for config in progress(configs, show_progress, "bench"):
            results.append(run_config(scene_name, parameters, config, duration, reference))
        return reference, results
    with dask_client(scheduler, "bench", "pip install 'pinstab[bench]' (or use --serial)") as client:
        from distributed import as_completed

        shared = client.scatter(reference, broadcast=True)
        futures = {
            client.submit(run_config, scene_name, parameters, c, duration, shared, pure=False): i
            for i, c in enumerate(configs)
        }
        results: list[Result | None] = [None] * len(configs)
        for future in progress(as_completed(futures), show_progress, "bench", total=len(configs)):
            results[futures[future]] = future.result()
    return reference, results  # type: ignore[return-value]


def check_sweep(configs: list[Config], duration: float) -> None:
    """Refuse a sweep before any work: no configuration, a duration [s] that is not a positive number, a
    configuration's step [s] that is not positive or longer than the duration, or a step (a configuration's
    or the reference's) that makes more than :data:`MAX_RUN_STEPS` steps over it."""
    if not configs:
        raise PinstabError("bench: no configuration to run")
    if isinstance(duration, bool) or not isinstance(duration, int | float) or not 0 < duration < math.inf:
        raise PinstabError(f"duration must be a positive number of seconds, got {duration!r}")
    for config in configs:
        label = f"step {config.dt!r} s of {config.curve}"
        if not 0 < config.dt < math.inf:
            raise PinstabError(f"{label} must be a positive number")
        if duration / config.dt < 0.5:
            raise PinstabError(f"{label} is longer than the duration {duration:g} s (no step to take)")
        if config.rtol is not None and not MIN_RTOL <= config.rtol < 1:
            raise PinstabError(f"rtol {config.rtol!r} of {config.curve} must be a number in [{MIN_RTOL:g}, 1)")
    finest = min([c.dt for c in configs] + [EXACT_REFERENCE_STEP, GENERIC_REFERENCE_STEP])
    if duration / finest > MAX_RUN_STEPS:
        raise PinstabError(
            f"{duration:g} s at the finest step, {finest:g} s (the runs' or the reference's), makes "
            f"{duration / finest:.3g} steps, more than the {MAX_RUN_STEPS:.0e} a run takes; use larger steps or a "
            "shorter duration"
        )


def check_tolerance(tolerance: float) -> None:
    """Refuse a trajectory-error tolerance [rad, m] that is not a positive number."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float) or not 0 < tolerance < math.inf:
        raise PinstabError(f"tolerance must be a positive number [rad, m], got {tolerance!r}")


def cheapest_within(
    results: list[Result], tolerance: float, peer: str | None, adaptive: bool | None = None
) -> Result | None:
    """The lowest-cost run of pinstab (``peer`` None) or of one peer (``pinocchio-native``, ``mujoco``,
    ``scipy-dop853``, ``scipy-radau``, ``scipy-bdf``) whose trajectory error is within ``tolerance`` [rad, m]
    (:func:`check_tolerance`); ``adaptive`` True or False keeps the error-controlled runs or the fixed-step ones
    only."""
    check_tolerance(tolerance)
    eligible = [
        r
        for r in results
        if r.config.peer == peer
        and (adaptive is None or (r.config.rtol is not None) == adaptive)
        and not r.diverged
        and r.trajectory_error <= tolerance
    ]
    return min(eligible, key=lambda r: r.cpu_per_sim_s) if eligible else None


PEERS = ("pinocchio-native", "mujoco", *SCIPY_METHODS)


def cheapest_table(results: list[Result], tolerance: float) -> dict[str, Any]:
    """The cheapest run within ``tolerance`` [rad, m] of pinstab (any), pinstab fixed-step, pinstab
    error-controlled and each peer (their rows, None where none is), and the cost ratios of pinstab's
    cheapest, and of its error-controlled cheapest, over each peer's."""
    table: dict[str, Any] = {}
    for label, adaptive in (("pinstab", None), ("pinstab-fixed-step", False), ("pinstab-rtol", True)):
        best = cheapest_within(results, tolerance, None, adaptive)
        table[label] = None if best is None else best.row()
    for peer in PEERS:
        best = cheapest_within(results, tolerance, peer)
        table[peer] = None if best is None else best.row()
        for label in ("pinstab", "pinstab-rtol"):
            ours = table[label]
            ratio = None if ours is None or best is None else ours["cpu_per_sim_s"] / best.cpu_per_sim_s
            table[f"cost_ratio_{label.replace('-', '_')}_over_{peer}"] = ratio
    return table


def make_output_folder(out_dir: Path) -> None:
    """Create ``out_dir`` (and its parents) if needed, and check that files can be written in it.

    Raises:
        PinstabError: a file on its path, no permission, no such place.
    """
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PinstabError(f"cannot create the output folder {out_dir}: {exc.strerror or exc}") from None
    check_output(out_dir / "results.json", ".json", "results")


def write_outputs(
    out_dir: Path, scene_name: str, reference: Reference, results: list[Result], extra: dict[str, Any]
) -> dict[str, Any]:
    """results.json, results.csv, work_precision.png and drift.png (when a run has a drift series) in ``out_dir``;
    returns the JSON.

    Raises:
        PinstabError: ``out_dir`` cannot be created (:func:`make_output_folder`).
    """
    make_output_folder(out_dir)
    rows = [r.row() for r in results]
    summary = {"scene": scene_name, "reference": reference.kind, **extra, "results": rows}
    with atomic_output(out_dir / "results.json", ".json", "results") as temp:
        Path(temp).write_text(json.dumps(stamped(summary), indent=1) + "\n")
    with atomic_output(out_dir / "results.csv", ".csv", "results") as temp, open(temp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with atomic_output(out_dir / "results.md", ".md", "results") as temp:
        Path(temp).write_text(_markdown(summary))
    _charts(out_dir, scene_name, reference, results)
    return summary


def _markdown(summary: dict[str, Any]) -> str:
    """The results as a Markdown table, cheapest first among those within the tolerance."""

    def number(value: Any) -> str:
        return "—" if value is None else f"{value:.2e}"

    lines = [
        f"# {summary['scene']}: work-precision, {summary['duration']:g} s simulated",
        "",
        f"Reference: {summary['reference']}. Cost: CPU seconds per simulated second.",
        "",
        "| configuration | dt [s] | rtol | cost [s/s] | trajectory error | max drift [m] | energy error [J] |",
        "|---|---|---|---|---|---|---|",
    ]
    rows = sorted(summary["results"], key=lambda r: (r["cpu_per_sim_s"] is None, r["cpu_per_sim_s"] or 0.0))
    for row in rows:
        status = " (diverged)" if row["diverged"] else ""
        lines.append(
            f"| {row['curve']}{status} | {row['dt']:g} | {'—' if row['rtol'] is None else format(row['rtol'], 'g')} | "
            f"{number(row['cpu_per_sim_s'])} | "
            f"{number(row['trajectory_error'])} | {number(row['max_position_drift'])} | {number(row['energy_error'])} |"
        )
    return "\n".join(lines) + "\n"


def _charts(out_dir: Path, scene_name: str, reference: Reference, results: list[Result]) -> None:
    from ..plotting import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10.5, 5.5), dpi=110)
    ax.set_prop_cycle(color=plt.get_cmap("tab20").colors)
    curves: dict[str, list[Result]] = {}
    for r in results:
        curves.setdefault(r.config.curve, []).append(r)
    for name, runs in sorted(curves.items()):
        runs = sorted(
            (r for r in runs if not r.diverged and r.trajectory_error > 0), key=lambda r: (r.config.rtol, r.config.dt)
        )
        if runs:
            config = runs[0].config
            style = "--" if config.peer else "-"
            marker = "s" if config.rtol is not None else "o"
            ax.loglog(
                [r.cpu_per_sim_s for r in runs],
                [r.trajectory_error for r in runs],
                style,
                marker=marker,
                ms=4 if config.rtol is not None else 3,
                lw=2.0 if config.rtol is not None else 1.2,
                label=name,
            )
    ax.set_xlabel("CPU time per simulated second [s/s]")
    ax.set_ylabel("trajectory error max |q - q_ref| [rad, m]")
    ax.set_title(f"{scene_name}: work-precision (reference: {reference.kind})", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(
        fontsize=7,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        title="dashed: peers; squares: error-controlled (rtol)",
        title_fontsize=7,
    )
    save_figure(fig, out_dir / "work_precision.png")

    # the drift of the runs with a drift series (peers at their first gains) at the smallest step among them
    drawn = [r for r in results if r.drift_series and (r.config.peer is None or r.config.kp == PEER_GAINS[0])]
    if not drawn:
        return
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    smallest = min(r.config.dt for r in drawn)
    for r in drawn:
        if r.config.dt == smallest:
            series = np.maximum(np.array(r.drift_series), np.finfo(float).tiny)
            ax.semilogy(r.drift_times, series, label=r.config.curve)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("position drift max |phi| [m]")
    ax.set_title(f"{scene_name}: drift at dt = {smallest:g} s", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, out_dir / "drift.png")

"""A biped MJCF (tests/data/mjcf_biped.xml: a pelvis fixed in the air, two legs of hip, knee and ankle hinges with
<default> classes, damping, springs about springref, frictionloss, armature, ranges limited="true", a keyframe and a
joint equality) read by pinstab and run with its joint limits and dry joint friction, against MuJoCo's run of the same
file (contacts off), and what ``pinstab check`` says of it."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from mujoco_twin import mujoco_run, twins, written

import pinstab
from pinstab.cli import main
from pinstab.trajectory import Trajectory

BIPED = Path(__file__).parent / "data" / "mjcf_biped.xml"
JOINTS = ["l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle"]


def _difference(path: Path) -> tuple[np.ndarray, np.ndarray, object]:
    """Each joint's largest |q_pinstab - qpos_MuJoCo| [rad] over 1 s from the keyframe (pinstab's default run, event
    path, at rtol 1e-11, sampled every 0.01 s), MuJoCo's positions and pinstab's run."""
    scene, model = twins(path)
    times, positions = mujoco_run(model, scene.q0, scene.v0, 1.0, every=100)
    run = pinstab.simulate(scene, duration=1.0, dt=float(times[1] - times[0]), rtol=1e-11, atol=1e-11)
    assert np.allclose(run.t, times, atol=1e-12)
    return np.max(np.abs(run.q - positions), axis=0), positions, run


def test_biped_agrees_with_mujoco():
    """Every joint within 1e-2 rad of MuJoCo's run over 1 s (measured: 2.2e-3 rad, r_knee, at 0.43 s). The run is
    pinstab's default (event-driven, for its joint friction), each evaluation the compiled core's, with limit impacts,
    sticks and slips; what remains is MuJoCo's soft limit: its r_knee passes its upper bound by 2.0e-3 rad (the file's
    solreflimit 0.0005 s, overdamped 3: near-rigid and inelastic, as pinstab's hard limits)."""
    difference, positions, run = _difference(BIPED)
    assert np.max(difference) <= 1e-2
    assert run.info.path == "contact-events" and "joint friction" in run.info.path_reason
    assert set(run.info.solver_statistics.status_counts) == {"contact modes, core"}
    events = run.info.contact_events
    assert {"l_knee upper", "r_knee upper", "l_ankle upper"} <= {e["contact"] for e in events if e["to"] == "active"}
    assert any(e["from"] == "sticking" and e["to"] == "sliding" for e in events)  # a stick breaks
    assert any("slip velocity reached zero" in e["cause"] for e in events)  # a slip stops
    scene = twins(BIPED)[0]
    overshoot = np.max(positions - scene.model.upperPositionLimit)  # MuJoCo's joints beyond their ranges [rad]
    assert 0.5 * np.max(difference) <= overshoot <= np.max(difference)


def test_mujoco_default_softness_is_the_difference(tmp_path):
    """The same file with MuJoCo's default soft-constraint parameters (solref 0.02 1 on limits, friction and the
    equality): MuJoCo's limits rebound and its held joints creep, and its run leaves pinstab's by 8.9e-2 rad (measured);
    the file's near-rigid parameters bring that to the 2.2e-3 rad above: the difference is MuJoCo's softness."""
    text = re.sub(r'\s*(solref|solimp)\w*="[^"]*"', "", BIPED.read_text())
    difference = _difference(written(tmp_path, "soft.xml", text))[0]
    assert np.max(difference) > 5e-2


def test_biped_read_as_mujoco_reads_it(capsys):
    """The classes' damping, springs (r_hip's springref -0.1 overriding its class's), frictionloss (r_ankle's 0
    overriding its class's), ranges and the keyframe are read; ``pinstab check`` notes nothing left out or not read
    (frictionloss was), only MuJoCo's soft parameters of the limits, friction and equality, and the start; ``run
    --contacts held`` and ``stepping`` refuse the friction (exit 2), naming the joints and the mode to use."""
    scene = twins(BIPED)[0]
    assert list(scene.model.names[1:]) == JOINTS
    frictions = {f.joint: f.friction for f in scene.forces if f.name.endswith("/frictionloss")}
    assert frictions == pytest.approx({"l_hip": 0.3, "l_knee": 0.2, "l_ankle": 0.05, "r_hip": 0.3, "r_knee": 0.2})
    springs = {f.name: (f.stiffness, f.reference, f.damping) for f in scene.forces if f.name.endswith("/spring")}
    assert springs["r_hip/spring"] == pytest.approx((2.0, -0.1, 0.05))
    assert springs["l_knee/spring"] == pytest.approx((0.0, 0.0, 0.1))
    np.testing.assert_array_equal(scene.q0, [0.9, -0.3, 0.2, -0.7, -1.6, 0.2])
    np.testing.assert_array_equal(scene.model.armature, [0.005, 0.005, 0.002, 0.005, 0.005, 0.002])
    assert main(["check", str(BIPED.with_suffix(".toml")), "--json"]) == 0
    notes = "\n".join(json.loads(capsys.readouterr().out)["robot_notes"])
    assert "left out" not in notes and "not read" not in notes
    assert "their frictionloss is held as hard dry friction" in notes
    for mode in ("held", "stepping"):  # the modes without joint friction refuse it, naming the joints and the mode
        assert main(["run", str(BIPED.with_suffix(".toml")), "--contacts", mode, "--duration", "0.1"]) == 2
        error = capsys.readouterr().err
        assert f"--contacts {mode}) cannot take dry joint friction" in error and "(joint r_knee)" in error


def test_core_modes_are_numpy_modes(monkeypatch):
    """The biped's run with each mode's evaluation by the compiled core (sticking frictions held as the core's rows, a
    slipping one's torque passed in) and by ModeDynamics' numpy solves: the same events and the same trajectory to
    1e-9 rad over 0.5 s (measured 3.3e-12 rad, 27 events)."""
    from pinstab.simulate import contacts as contacts_module
    from pinstab.solvers.contact_modes import ModeDynamics

    scene = twins(BIPED)[0]
    core = pinstab.simulate(scene, duration=0.5, dt=0.01)
    monkeypatch.setattr(contacts_module, "CoreModeDynamics", ModeDynamics)
    numpy = pinstab.simulate(scene, duration=0.5, dt=0.01)
    assert set(numpy.info.solver_statistics.status_counts) == {"contact modes"}
    assert [(e["contact"], e["to"]) for e in numpy.info.contact_events] == [
        (e["contact"], e["to"]) for e in core.info.contact_events
    ]
    np.testing.assert_allclose(numpy.q, core.q, rtol=0, atol=1e-9)


def test_saving_the_run_changes_nothing_in_it(tmp_path, capsys):
    """``run --save`` (issue 36: a run that succeeded without it exited 2, "lost rank"): the biped scene, whose joint
    equality couples two joints, runs 0.5 s with and without ``--save`` to exit 0 and the same figures to the last
    bit (the JSON but its timings and the saved path); the saved samples are the run's."""
    scene = str(BIPED.with_suffix(".toml"))
    results = []
    for extra in ([], ["--save", str(tmp_path / "run.npz")]):
        assert main(["run", scene, "--duration", "0.5", "--json", *extra]) == 0
        result = json.loads(capsys.readouterr().out)
        results.append({k: v for k, v in result.items() if k not in ("wall_s", "timings", "saved")})
    assert results[0] == results[1]
    saved = Trajectory.load(tmp_path / "run.npz")
    direct = pinstab.simulate(twins(BIPED)[0], duration=0.5)
    np.testing.assert_array_equal(saved.q, direct.q)

"""allegro-tilt (issue 21, 36): the Allegro sphere grasp tilted slowly slips at the tilt the grasp analysis
predicts for the hold's capped squeeze, ``--stop-on slip`` keeps the JSON, the saved run and the recording, and
without it the run goes on through the slip, the same to the last bit each time."""

from __future__ import annotations

import json

import numpy as np

from pinstab import cli
from pinstab.grasp import analyse_scene_grasps, tilt_at_first_slip
from pinstab.scene import load_scene
from pinstab.simulate import simulate
from pinstab.trajectory import Trajectory

OUTPUT_STEP = 0.01  # [s] the runs' --dt
AXIS = np.array([-1.0, 0.0, 0.0])


def slip_time(scene, tilt: float) -> float:
    """The time [s] at which the scene's tilt reaches ``tilt`` [deg]."""
    return (np.radians(tilt) - scene.tilt.start) / scene.tilt.rate


def test_the_tilted_grasp_slips_where_the_analysis_predicts(capsys, tmp_path):
    """``pinstab grasp allegro-tilt`` predicts, under the scene's tilt, when the hold lets go (its cones narrowed by
    HOLD_MARGIN: tilt_at_first_slip's tilt, at the scene's rate) and when the contacts' own cones would (3.4e-4 deg,
    1.7e-4 s later); the event-driven run's first slip is within 1e-6 s of the first."""
    scene = load_scene("allegro-tilt")
    assert cli.main(["grasp", "allegro-tilt", "--json"]) == 0
    predicted = json.loads(capsys.readouterr().out)["objects"]["ball"]["under_scene_tilt"]
    t_slip = predicted["hold_lets_go_t_s"]
    assert t_slip == slip_time(scene, tilt_at_first_slip(scene, AXIS))  # the hold's cones, from the untilted start
    own = analyse_scene_grasps(scene, tilt_axis=AXIS)["ball"].capacity.tilts["+axis"]
    assert predicted["first_slip_t_s"] == slip_time(scene, own) and predicted["first_slip_tilt_deg"] == own
    assert 1e-4 < predicted["first_slip_t_s"] - t_slip < 1e-3
    saved = tmp_path / "tilt.npz"
    argv = ["run", "allegro-tilt", "--contacts", "event", "--duration", "0.3", "--dt", str(OUTPUT_STEP)]
    code = cli.main([*argv, "--stop-on", "slip", "--json", "--save", str(saved), "--quiet"])
    out, err = capsys.readouterr()
    assert code == cli.EXIT_STOPPED == 4, err
    result = json.loads(out)
    slips = [e for e in result["contact_events"] if e["from"] == "sticking" and e["to"] == "sliding"]
    assert slips and result["stopped"]["reason"] == "slip"
    # the hold lets go there, and index, middle and ring slip at once; measured 1.1e-7 s (the prediction's
    # bisection is to 1e-6 deg, 5e-7 s)
    assert abs(slips[0]["t"] - t_slip) <= 1e-6
    assert {e["contact"] for e in slips if e["t"] == slips[0]["t"]} == {"index", "middle", "ring"}
    run = Trajectory.load(saved)
    assert run.t[-1] == result["t_end"] == slips[0]["t"]
    assert run.info.contact_events == result["contact_events"]


def test_the_run_goes_on_through_the_slip_the_same_each_time():
    """Without --stop-on the run goes on after the hold lets go: index, middle and ring slide and stop again (at
    0.303 s ring's slip is 1.1e-9 m/s, across its old direction, where no mode was consistent before it could stick);
    a second run of the same scene object gives the same events and states to the last bit (the hold holds
    again at its start)."""
    scene = load_scene("allegro-tilt")
    duration = 0.32
    runs = [simulate(scene, contacts="event", duration=duration, dt=OUTPUT_STEP) for _ in range(2)]
    first, second = (run.info.contact_events for run in runs)
    assert first == second
    np.testing.assert_array_equal(runs[0].q, runs[1].q)
    assert runs[0].t[-1] == duration
    slips = [e for e in first if e["to"] == "sliding"]
    assert abs(slips[0]["t"] - slip_time(scene, tilt_at_first_slip(scene, AXIS))) <= 1e-6
    hold = next(element for element in scene.forces if element.kind == "grasp-hold")
    assert hold.released == slips[0]["t"]  # it let go where the contacts slipped
    # each stops and sticks (ring at the event of middle's cone, its slip then 1.1e-9 m/s across its old direction)
    assert [(e["contact"], e["to"]) for e in first if e["from"] == "sliding"] == [
        ("index", "sticking"),
        ("middle", "sticking"),
        ("ring", "sticking"),
    ]
    for event in first:  # each stop sticks inside its cone
        if event["from"] == "sliding":
            normal, *tangential = event["force"]
            assert 0.8 * normal - np.hypot(*tangential) > 1e-3
    ball = scene.model.joints[scene.objects[0].joint].idx_q
    assert runs[0].q[-1, ball + 2] < runs[0].q[0, ball + 2] - 1e-3  # the sphere slid down more than a millimetre


def test_stop_on_slip_writes_the_recording(capsys, tmp_path):
    out = tmp_path / "tilt.html"
    argv = ["record", "allegro-tilt", "-o", str(out), "--contacts", "event", "--duration", "0.3", "--fps", "20"]
    code = cli.main([*argv, "--stop-on", "slip", "--json"])
    printed, err = capsys.readouterr()
    assert code == cli.EXIT_STOPPED, err
    assert json.loads(printed)["frames"] == 3  # 0, 0.05, 0.10 s, then the slip at 0.143 s
    assert "pinstab ready: allegro-tilt" in out.read_text()


def test_the_let_go_is_an_event_whatever_the_duration_and_output_step():
    """The hold's let-go is located by the event loop (issue 36's defect: it latched at the first evaluation that found
    no holding forces, also a stage of a rejected step, so that a run let go at 0.1167 s or 0.1432 s as --duration
    changed the steps): runs to 0.15, 0.2 and 0.3 s at output steps 0.01 and 0.001 s, whose steps differ, let go within
    1e-10 s of one another (measured 2.1e-12 s; events are located to 1e-12 s) and within 1e-6 s of the prediction
    (measured 5.3e-8 s), and report it as the hold's event."""
    scene = load_scene("allegro-tilt")
    predicted = slip_time(scene, tilt_at_first_slip(scene, AXIS))
    let_go = set()
    for duration, dt in ((0.15, 0.01), (0.2, 0.001), (0.3, 0.01)):
        run = simulate(scene, contacts="event", duration=duration, dt=dt, stop_on=("slip",))
        events = [e for e in run.info.contact_events if e["contact"] == "hold"]
        assert [(e["from"], e["to"]) for e in events] == [("holding", "let go")]
        assert events[0]["cause"] == "no forces inside the cones hold ball"
        let_go.add(events[0]["t"])
    assert max(let_go) - min(let_go) <= 1e-10
    assert all(abs(t - predicted) <= 1e-6 for t in let_go)

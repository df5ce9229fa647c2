"""The CLI of contacts that switch (issue 21, item 4: a lost grasp is a result): ``--contacts``, ``--stop-on``
with its exit code, the events in the JSON, the saved run and ``pinstab plot``, and runs that stop early
keeping what they computed. Times against closed forms."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

import pinstab.integration.events as events
from conftest import ROBOTS
from pinstab import cli
from pinstab.errors import PainleveError, PinstabError
from pinstab.simulate import simulate
from pinstab.trajectory import Trajectory

G = 9.81


def run_json(capsys, *argv: str) -> tuple[int, dict | None, str]:
    code = cli.main([*argv, *(["--quiet"] if argv[0] in cli.SIMULATING else [])])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if out.strip().startswith("{") else None), err


def test_stop_on_separation_ends_at_the_first_rebound_and_keeps_every_output(capsys, tmp_path):
    """A ball dropped from h rebounds at t0 = sqrt(2 h / g) with speed e sqrt(2 g h): the run ends there
    (exit 4), and the JSON, the --save file and the chart hold the run up to it."""
    height, e = 0.5, 0.6
    saved, chart = tmp_path / "ball.npz", tmp_path / "ball.png"
    code, result, err = run_json(
        capsys,
        *("run", "bouncing-ball", "--param", f"height={height}", "--param", f"restitution={e}"),
        *("--duration", "2", "--dt", "0.01", "--stop-on", "separation", "--json"),
        *("--save", str(saved), "--plot", str(chart)),
    )
    t0 = math.sqrt(2 * height / G)
    assert code == cli.EXIT_STOPPED == 4, err
    assert "stopped (--stop-on): separation at t = " in err
    assert abs(result["t_end"] - t0) <= 1e-8
    assert result["stopped"]["reason"] == "separation" and result["stopped"]["contact"] == "ground"
    assert [(x["from"], x["to"]) for x in result["contact_events"][1:]] == [
        ("separated", "closing"),
        ("closing", "separated"),
    ]
    run = Trajectory.load(saved)
    assert abs(run.t[-1] - t0) <= 1e-8 and run.t[-2] < t0
    assert abs(run.v[-1, 2] - e * math.sqrt(2 * G * height)) <= 1e-8 * math.sqrt(2 * G * height)
    assert run.info.contact_events == result["contact_events"] and run.info.stopped == result["stopped"]
    assert chart.stat().st_size > 0
    code, plotted, err = run_json(capsys, "plot", str(saved), "-o", str(tmp_path / "again.png"), "--json")
    assert code == 0, err
    assert plotted["contact_events"] == result["contact_events"] and plotted["t_end"] == run.t[-1]
    # recording the saved run reads it: exit 0, not the --stop-on of a run made now (it was exit 4)
    argv = ("record", "bouncing-ball", "--from", str(saved), "-o", str(tmp_path / "ball.html"), "--json")
    code, recorded, err = run_json(capsys, *argv)
    assert code == 0 and "--stop-on" not in err, err
    assert recorded["stopped"] == result["stopped"] and recorded["t_end"] == run.t[-1]


def test_stop_on_writes_the_recording_up_to_the_event(capsys, tmp_path):
    """``record --stop-on separation``: exit 4, the recording's frames at 20 fps up to t0 = sqrt(2 h / g)."""
    out = tmp_path / "ball.html"
    argv = ("record", "bouncing-ball", "-o", str(out), "--duration", "2", "--fps", "20", "--stop-on", "separation")
    code, result, err = run_json(capsys, *argv, "--json")
    assert code == cli.EXIT_STOPPED, err
    assert abs(result["t_end"] - math.sqrt(2 / G)) <= 1e-8
    assert result["frames"] == math.floor(math.sqrt(2 / G) * 20) + 1
    assert "pinstab ready: bouncing-ball" in out.read_text()


def test_stop_on_slip_is_the_friction_angle(capsys, tmp_path):
    """From rest on a slope theta, a box slips at once when mu < tan(theta) (exit 4 at t = 0, every corner
    sliding) and holds for the whole run when mu > tan(theta) (exit 0, no creep over 1e-10 m)."""
    theta = 0.5  # tan(theta) = 0.546
    slope = ("run", "incline", "--param", f"theta={theta}", "--duration", "1", "--dt", "0.1", "--stop-on", "slip")
    saved = tmp_path / "slip.npz"
    code, result, err = run_json(capsys, *slope, "--param", "mu=0.5", "--json", "--save", str(saved))
    assert code == cli.EXIT_STOPPED, err
    assert result["t_end"] == 0.0 and result["steps"] == 0
    assert {(x["contact"], x["to"]) for x in result["contact_events"]} == {(f"corner{k}", "sliding") for k in range(4)}
    assert result["stopped"]["reason"] == "slip"
    assert Trajectory.load(saved).info.stopped == result["stopped"]
    code, result, err = run_json(capsys, *slope, "--param", "mu=0.6", "--json", "--save", str(saved))
    assert code == cli.EXIT_OK, err
    assert result["t_end"] == 1.0 and result["stopped"] is None
    run = Trajectory.load(saved)
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-10


def test_a_thrown_box_does_not_slip(capsys):
    """Sliding from the start with a slip velocity is not a slip (the contact was never at rest): exit 0."""
    code, result, err = run_json(
        capsys, "run", "incline", "--param", "v_down=1.0", "--duration", "0.2", "--stop-on", "slip", "--json"
    )
    assert code == cli.EXIT_OK, err
    assert result["stopped"] is None and {x["to"] for x in result["contact_events"]} == {"sliding"}


def test_a_run_without_stop_on_lists_every_event(capsys):
    """The bouncing ball's impacts at t0 + 2 t0 (e + ... + e^k) and its rest at t0 (1 + e) / (1 - e), in the
    JSON; the text output lists the first events in a table."""
    height, e = 1.0, 0.5
    code, result, err = run_json(capsys, "run", "bouncing-ball", "--duration", "2", "--dt", "0.01", "--json")
    assert code == cli.EXIT_OK, err
    events_ = result["contact_events"]
    t0 = math.sqrt(2 * height / G)
    impacts = [x["t"] for x in events_ if x["to"] == "closing"]
    np.testing.assert_allclose(impacts[:5], [t0 + 2 * t0 * sum(e**j for j in range(1, k + 1)) for k in range(5)], 1e-8)
    assert events_[-1]["to"] == "sticking"
    assert abs(events_[-1]["t"] - t0 * (1 + e) / (1 - e)) <= 1e-6 * t0 * (1 + e) / (1 - e)
    assert result["stopped"] is None and result["t_end"] == 2.0
    code = cli.main(["run", "bouncing-ball", "--duration", "2", "--dt", "0.01", "--quiet"])
    text = capsys.readouterr().out
    assert code == cli.EXIT_OK
    assert f"contact events ({len(events_)}; slip in rad/s for torsion and rolling):" in text
    assert f"... and {len(events_) - cli.EVENT_ROWS} more" in text


def test_a_painleve_mid_run_keeps_the_partial_trajectory(capsys, tmp_path, monkeypatch):
    """No consistent mode at the first impact (a PainleveError made to happen there, t0 = sqrt(2 h / g)): exit 5,
    the JSON, the --save file and the recording hold the run up to the impact."""
    choose = events.choose_modes

    def paradox(dynamics, q, v, t, *slack):
        if t > 0.1:
            raise PainleveError(f"at t = {t:.9g} s no contact mode of ground is consistent", ["ground"], t)
        return choose(dynamics, q, v, t, *slack)

    monkeypatch.setattr(events, "choose_modes", paradox)
    saved, chart, page = tmp_path / "ball.npz", tmp_path / "ball.png", tmp_path / "ball.html"
    code, result, err = run_json(
        capsys, "run", "bouncing-ball", "--duration", "1", "--json", "--save", str(saved), "--plot", str(chart)
    )
    t0 = math.sqrt(2 / G)
    assert code == cli.EXIT_CONTACT_FAILED == 5, err
    assert "no contact mode of ground is consistent" in err and f"partial trajectory is saved to {saved}" in err
    assert abs(result["t_end"] - t0) <= 1e-8 and "no contact mode" in result["error"]
    assert result["stopped"]["reason"] == "contact failure" and result["stopped"]["error"] == "PainleveError"
    run = Trajectory.load(saved)
    assert abs(run.t[-1] - t0) <= 1e-8 and len(run.t) == math.floor(t0 / 1e-3) + 2  # 0, 1 ms, ..., the impact
    assert run.info.contact_events == result["contact_events"] and chart.stat().st_size > 0
    code, result, err = run_json(capsys, "record", "bouncing-ball", "-o", str(page), "--duration", "1", "--json")
    assert code == cli.EXIT_CONTACT_FAILED, err
    assert page.exists() and result["frames"] == math.floor(t0 * 30) + 1


def test_box_push_defaults_to_event_contacts_and_slides_as_the_closed_form(capsys, tmp_path):
    """box-push with 6 N > mu m g = 4.9 N: held contacts cannot hold it (exit 5, the start kept); event-driven
    ones, the default, slide it by x = (F - mu m g) t^2 / (2 m) (1e-8 relative at 1 s)."""
    scene = tmp_path / "push.toml"
    text = (ROBOTS / "box-push.toml").read_text().replace('"1 N"', '"6 N"')
    scene.write_text(text.replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/'))
    saved = tmp_path / "push.npz"
    code, result, err = run_json(capsys, "run", str(scene), "--json", "--save", str(saved))
    assert code == cli.EXIT_OK, err
    assert result["path"] == "contact-events"
    exact = (6.0 - 0.5 * G) / 2
    assert abs(Trajectory.load(saved).q[-1, 0] - exact) <= 1e-8 * exact
    code, result, err = run_json(capsys, "run", str(scene), "--contacts", "held", "--json", "--save", str(saved))
    assert code == cli.EXIT_CONTACT_FAILED and "sticking contacts cannot hold at t = 0 s" in err
    assert result["t_end"] == 0.0 and Trajectory.load(saved).info.stopped["error"] == "ContactInfeasibleError"


@pytest.mark.parametrize(
    ("argv", "phrases"),
    [
        (["run", "box-push", "--solver", "dense"], ["--solver", "--contacts held"]),
        (["run", "box-push", "--method", "projection", "--kp", "10"], ["--method, --kp", "event-driven"]),
        (["run", "fourbar", "--stop-on", "slip"], ["--stop-on slip", "held as constraint rows"]),
        (["run", "incline", "--contacts", "held", "--stop-on", "separation"], ["--contacts event"]),
    ],
)
def test_options_that_do_not_fit_the_contacts_are_refused(capsys, argv, phrases):
    code, _, err = run_json(capsys, *argv)
    assert code == cli.EXIT_BAD_INPUT and all(phrase in err for phrase in phrases), err


@pytest.mark.parametrize(("stop_on", "phrase"), [("slide", "'slide' is not a kind"), (3, "must name kinds")])
def test_bad_stop_on_is_named(stop_on, phrase):
    with pytest.raises(PinstabError, match=phrase):
        simulate("bouncing-ball", contacts="event", stop_on=stop_on)
    with pytest.raises(PinstabError, match="takes contacts='event'"):
        simulate("bouncing-ball", contacts="held", stop_on=("slip",))


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["record", "--help"]])
def test_help_documents_every_exit_code(capsys, argv):
    with pytest.raises(SystemExit):
        cli.main(argv)
    text = " ".join(capsys.readouterr().out.split())
    for phrase in ("0 success", "2 bad input", "3 divergence", "4 stopped at the contact event", "5 contacts"):
        assert phrase in text


def test_ctrl_c_in_an_event_driven_run_saves_the_samples_so_far(capsys, tmp_path, monkeypatch):
    """Ctrl-C at the first impact (t0 = 0.4515 s) of a run checked every 100 steps of 1 ms: exit 130, the --save
    file ends at the last checked state, t = 0.4 s, with the events up to then."""
    choose = events.choose_modes

    def interrupt(dynamics, q, v, t, *slack):
        if t > 0.1:
            raise KeyboardInterrupt
        return choose(dynamics, q, v, t, *slack)

    monkeypatch.setattr(events, "choose_modes", interrupt)
    saved = tmp_path / "ball.npz"
    assert cli.main(["run", "bouncing-ball", "--save", str(saved), "--quiet"]) == 130
    assert "interrupted at t = 0.4 s" in capsys.readouterr().err
    run = Trajectory.load(saved)
    assert run.t[-1] == pytest.approx(0.4, abs=1e-12) and len(run.t) == 401
    assert [(x["from"], x["to"]) for x in run.info.contact_events] == [("separated", "separated")]


def test_the_event_path_reports_the_dynamics_it_ran(capsys):
    """Event-driven contacts name what computed the accelerations (each contact's mode rows solved densely, no
    stabilization method or KKT backend) and count their evaluations as the held path does: DOP853 with FSAL makes
    12 per attempted step (they read ``method none`` and ``dynamics_evaluations 0``, the count of a Pinocchio
    solve the run never used)."""
    code, result, err = run_json(capsys, "run", "incline", "--contacts", "event", "--duration", "0.3", "--json")
    assert code == 0, err
    assert (result["method"], result["integrator"], result["solver"]) == ("contact-modes", "dop853", "dense")
    control = result["error_control"]
    attempts = control["steps_accepted"] + control["steps_rejected"]
    assert 11 * attempts <= result["dynamics_evaluations"] <= 14 * attempts + 10
    assert result["solver_status"] == {"contact modes": result["dynamics_evaluations"]}
    assert result["solver_worst_residual"] < 1e-9


@pytest.mark.parametrize("scene", ["incline", "sphere-spin"])
def test_the_text_summary_prints_plain_numbers(capsys, scene):
    """The error control's step sizes of an event run printed ``np.float64(0.0071...)`` in the text summary."""
    code = cli.main(["run", scene, "--duration", "0.3", "--quiet"])
    out = capsys.readouterr().out
    assert code == 0
    control = next(line for line in out.splitlines() if line.startswith("error_control"))
    assert "np." not in out and re.search(r"'smallest_step': [\d.e+-]+, 'largest_step': [\d.e+-]+}$", control)


def test_plot_of_a_run_that_meets_a_joint_limit(capsys, tmp_path):
    """panda-anchor swings into panda_joint6's upper limit at 0.274 s (an impact, then it leaves it): --plot draws the
    limit's events (it exited 2, 'has no plane contacts'), and the energy the chart balances holds: E(end) - E(0) is
    the impact's work to 1e-5 J (the error panel's scale: 2e-6 J)."""
    chart = tmp_path / "limits.png"
    code, result, _ = run_json(capsys, "run", "panda-anchor", "--duration", "0.3", "--json", "--plot", str(chart))
    assert code == 0 and chart.stat().st_size > 10_000
    impacts = [event for event in result["contact_events"] if event["cause"] == "impact" and "work" in event]
    assert [event["contact"] for event in impacts] == ["panda_joint6 upper"]
    assert abs(result["energy_end"] - result["energy_start"] - impacts[0]["work"]) <= 1e-5

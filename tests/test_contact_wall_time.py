"""Event-driven contacts whose computation must stay bounded. A slip that starts from rest at its cone's edge (its
direction turning within 1e-11 s at 1e-9 m/s) once took 149,058 steps and 4.5 min of wall time, then ended as a
crawl; its direction is now slaved to its slip acceleration while it is slower than GRAZING_SPEED
(pinstab.solvers.contact_modes): it slips through, and agrees with the time-stepping contacts extrapolated to dt = 0.
The crawl guard (a run whose steps stay below CRAWL_STEP ends with the contacts named) is tested with that treatment
off. Runs with many events and short steps after each still reach their end."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest
from fuzzing import toml_document
from test_fuzz_tables import SLOW_EVENTS, TILTED_PLANE

import pinstab.solvers.contact_modes
from pinstab import simulate
from pinstab.cli.dispatch import main
from pinstab.cli.exits import EXIT_CONTACT_FAILED
from pinstab.contact.modes import Mode
from pinstab.errors import ContactInfeasibleError
from pinstab.integration.events import CRAWL_STEP, CRAWL_STEPS
from pinstab.scene import scene_from_dict

SLIP_START = 0.028357162074  # [s] SLOW_EVENTS: front-left and front-right start sliding from rest (the run's event)

# a cylinder on three rim contacts, c0's plane tilted (normal [0, 0.1, 1]), c2 mu 3.6: 85 contact events and
# impacts in 0.12 s (once 145 s of wall time: a released contact closing again at once)
RIM_CONTACTS = copy.deepcopy(TILTED_PLANE)  # with c1's restitution as the fuzzer drew it (hang3.toml)
RIM_CONTACTS["contacts"][1]["restitution"] = 5.902272262763471e-227


# the slip ends of SLOW_EVENTS' slipping front corners [s] (measured; equal to 1e-10 s at GRAZING_SPEED 1e-6 to 1e-4)
SLIP_ENDS = {"front-right": 0.1028372871, "front-left": 0.1103853947}


@pytest.fixture
def no_grazing(monkeypatch) -> None:
    """The grazing-slip treatment off: a slip's direction is its velocity's from 1e-9 m/s on (the crawl returns)."""
    monkeypatch.setattr(pinstab.solvers.contact_modes, "GRAZING_SPEED", 0.0)


def test_a_slip_starting_from_rest_slips_through_to_its_ends() -> None:
    """SLOW_EVENTS to 0.12 s: both front corners start sliding at SLIP_START and stick again at SLIP_ENDS (to 1e-8 s),
    in well under the 149,058 steps of old."""
    trajectory = simulate(scene_from_dict(SLOW_EVENTS, name="slow"), contacts="event", duration=0.12)
    assert trajectory.t[-1] == pytest.approx(0.12)
    switches = [e for e in trajectory.info.contact_events if e["cause"] != "start"]
    assert [(e["contact"], e["to"]) for e in switches] == [
        ("front-left", Mode.SLIDING),
        ("front-right", Mode.SLIDING),
        ("front-right", Mode.STICKING),
        ("front-left", Mode.STICKING),
    ]
    assert switches[0]["t"] == switches[1]["t"] == pytest.approx(SLIP_START, abs=1e-11)
    for event in switches[2:]:
        assert event["t"] == pytest.approx(SLIP_ENDS[event["contact"]], abs=1e-8), event
    assert trajectory.info.error_control["steps_accepted"] < 5000


def test_the_grazing_slip_is_the_limit_of_time_stepping_and_repeats_to_the_bit() -> None:
    """SLOW_EVENTS at 0.05 s (0.022 s into the slip): the time-stepping contacts (order 1, an independent method: an
    impulse problem per step, no modes) at dt = 2e-5 and 1e-5 s are 6.9e-5 and 3.5e-5 m off the event-driven state,
    halving with dt; extrapolated to dt = 0 (2 q(dt/2) - q(dt)) they agree with it to 1.3e-9 m and 9.6e-8 m/s
    (asserted: 1e-8 m, 1e-6 m/s). Without the treatment the event-driven run ends as a crawl at 0.02836 s."""
    scene = scene_from_dict(SLOW_EVENTS, name="slow")
    event = simulate(scene, contacts="event", duration=0.05, dt=0.01)
    again = simulate(scene, contacts="event", duration=0.05, dt=0.01)
    assert np.array_equal(event.q, again.q) and np.array_equal(event.v, again.v)
    assert event.info.contact_events == again.info.contact_events
    coarse, fine = (simulate(scene, contacts="stepping", duration=0.05, dt=dt) for dt in (2e-5, 1e-5))
    assert 2e-5 < np.max(np.abs(fine.q[-1] - event.q[-1])) < 5e-5  # the stepping's own error, first order
    assert np.max(np.abs(2 * fine.q[-1] - coarse.q[-1] - event.q[-1])) < 1e-8
    assert np.max(np.abs(2 * fine.v[-1] - coarse.v[-1] - event.v[-1])) < 1e-6


def _crawl(scene: dict) -> ContactInfeasibleError:
    with pytest.raises(ContactInfeasibleError) as caught:
        simulate(scene_from_dict(scene, name="slow"), contacts="event", duration=0.12)
    return caught.value


@pytest.mark.usefixtures("no_grazing")
def test_a_crawling_slip_start_ends_with_the_sliding_contacts_named() -> None:
    """Without the grazing treatment, the two contacts that start sliding from rest at SLIP_START crawl at 1e-9 m/s
    (steps of 1e-11 to 1e-9 s): the run ends microseconds after it (not 149,058 steps later), naming them (sliding,
    slowest first) with their speeds."""
    error = _crawl(SLOW_EVENTS)
    assert error.contacts == ["front-right", "front-left"], error
    assert SLIP_START < error.time < SLIP_START + 1e-5, error.time
    message = str(error)
    assert f"{CRAWL_STEPS} steps in a row shorter than {CRAWL_STEP:g} s" in message
    speed = re.search(r"front-right sliding at ([0-9.e+-]+) m/s", message)
    assert speed is not None and "--contacts stepping" in message, message
    assert 5e-10 <= float(speed.group(1)) <= 2e-9  # the slip threshold's order: 1e-9 m/s (9.9e-10 measured)


@pytest.mark.usefixtures("no_grazing")
def test_the_crawl_ends_at_the_same_instant_every_time() -> None:
    assert str(_crawl(SLOW_EVENTS)) == str(_crawl(SLOW_EVENTS))


@pytest.mark.usefixtures("no_grazing")
def test_the_command_line_exits_5_with_the_contacts_named(tmp_path, capsys) -> None:
    scene = tmp_path / "slow.toml"
    scene.write_text(toml_document(SLOW_EVENTS), encoding="utf-8")
    saved = tmp_path / "run.npz"
    code = main(["run", str(scene), "--contacts", "event", "--duration", "0.12", "--save", str(saved), "--quiet"])
    err = capsys.readouterr().err
    assert code == EXIT_CONTACT_FAILED, err
    assert "front-right" in err and "Traceback" not in err
    assert saved.exists()  # the run up to the stop is kept


def test_many_events_with_short_steps_after_each_reach_the_end() -> None:
    """RIM_CONTACTS: each impact restarts the steps from 1e-11 s; the run is not taken for a crawl."""
    trajectory = simulate(scene_from_dict(RIM_CONTACTS, name="rim"), contacts="event", duration=0.12)
    assert trajectory.t[-1] == pytest.approx(0.12)
    assert len(trajectory.info.contact_events) > 20

"""Event-driven contacts whose computation must stay bounded: a slip that crawls at 1e-9 m/s (its direction turning
within 1e-11 s) ends with the contacts named instead of 149,058 steps and 4.5 min of wall time; runs with many
events and short steps after each still reach their end."""

from __future__ import annotations

import copy
import re

import pytest
from fuzzing import toml_document
from test_fuzz_tables import SLOW_EVENTS, TILTED_PLANE

from pinstab import simulate
from pinstab.cli.dispatch import main
from pinstab.cli.exits import EXIT_CONTACT_FAILED
from pinstab.errors import ContactInfeasibleError
from pinstab.integration.events import CRAWL_STEP, CRAWL_STEPS
from pinstab.scene import scene_from_dict

SLIP_START = 0.028357162074  # [s] SLOW_EVENTS: front-left and front-right start sliding from rest (the run's event)

# a cylinder on three rim contacts, c0's plane tilted (normal [0, 0.1, 1]), c2 mu 3.6: 85 contact events and
# impacts in 0.12 s (once 145 s of wall time: a released contact closing again at once)
RIM_CONTACTS = copy.deepcopy(TILTED_PLANE)  # with c1's restitution as the fuzzer drew it (hang3.toml)
RIM_CONTACTS["contacts"][1]["restitution"] = 5.902272262763471e-227


def _crawl(scene: dict) -> ContactInfeasibleError:
    with pytest.raises(ContactInfeasibleError) as caught:
        simulate(scene_from_dict(scene, name="slow"), contacts="event", duration=0.12)
    return caught.value


def test_a_crawling_slip_start_ends_with_the_sliding_contacts_named() -> None:
    """The two contacts that start sliding from rest at SLIP_START crawl at 1e-9 m/s (steps of 1e-11 to 1e-9 s):
    the run ends microseconds after it (not 149,058 steps later), naming them (sliding, slowest first) with their
    speeds."""
    error = _crawl(SLOW_EVENTS)
    assert error.contacts == ["front-right", "front-left"], error
    assert SLIP_START < error.time < SLIP_START + 1e-5, error.time
    message = str(error)
    assert f"{CRAWL_STEPS} steps in a row shorter than {CRAWL_STEP:g} s" in message
    speed = re.search(r"front-right sliding at ([0-9.e+-]+) m/s", message)
    assert speed is not None and "--contacts stepping" in message, message
    assert 5e-10 <= float(speed.group(1)) <= 2e-9  # the slip threshold's order: 1e-9 m/s (9.9e-10 measured)


def test_the_crawl_ends_at_the_same_instant_every_time() -> None:
    assert str(_crawl(SLOW_EVENTS)) == str(_crawl(SLOW_EVENTS))


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

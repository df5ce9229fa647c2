"""Event-driven contacts whose computation must stay bounded: a slip that crawls at 1e-9 m/s (its direction turning
within 1e-11 s) ends with the contacts named instead of 149,058 steps and 4.5 min of wall time; runs with many
events and short steps after each still reach their end."""

from __future__ import annotations

import pytest
from fuzzing import toml_document
from test_fuzz_tables import SLOW_EVENTS

from pinstab import simulate
from pinstab.cli.dispatch import main
from pinstab.cli.exits import EXIT_CONTACT_FAILED
from pinstab.errors import ContactInfeasibleError
from pinstab.integration.events import CRAWL_STEP, CRAWL_STEPS
from pinstab.scene import scene_from_dict

SLIP_START = 0.028357162074  # [s] SLOW_EVENTS: front-left and front-right start sliding from rest (the run's event)

# a cylinder on three rim contacts, c0's plane tilted (normal [0, 0.1, 1]), c2 mu 3.6: 85 contact events and
# impacts in 0.12 s (once 145 s of wall time: a released contact closing again at once)
RIM_CONTACTS = {
    "gravity": [0.0, 0.0, -9.81],
    "robot": {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"},
    "objects": [
        {
            "name": "crate",
            "shape": "cylinder",
            "radius": 0.5,
            "length": 1.0,
            "density": 10.0,
            "position": [-2.220446049250313e-16, 0.0, 0.5],
        }
    ],
    "contacts": [
        {
            "name": "c0",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [0.49916897037816105, 0.0, -0.4993263445673763],
            "normal": [0.0, 0.1, 1.0],
        },
        {
            "name": "c1",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [-0.2520565321046346, 0.43086803371098975, -0.49972481093414123],
            "mu": 0.0,
            "restitution": 5.902272262763471e-227,
        },
        {
            "name": "c2",
            "kind": "plane-contact",
            "frame_a": "crate",
            "offset_a": [-0.2451304106703497, -0.4357878862067941, -0.5],
            "mu": 3.608306522193498,
            "facets": 15,
        },
    ],
}


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
    assert "front-right sliding at 1e-09 m/s" in message and "--contacts stepping" in message


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

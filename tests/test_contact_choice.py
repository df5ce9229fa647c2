"""The contact treatment a run takes (``pinstab.simulate.choice``): a scene whose contacts can switch switches by
default (event-driven; time-stepping beyond MAX_EVENT_CONTACTS declared ones), holding them is asked for (the
option, or the scene's ``[run] contacts``), and the run's JSON says which, how chosen and why; ``simulate(scene)``
and ``pinstab run`` take the same."""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from fuzzing import cli, toml_document

from conftest import ROBOTS
from pinstab import Trajectory, load_scene, simulate
from pinstab.errors import PinstabError, SceneError
from pinstab.scene import scene_from_dict
from pinstab.simulate import MAX_EVENT_CONTACTS, contact_choice


@pytest.mark.parametrize(
    ("name", "treatment", "chosen"),
    [
        ("bouncing-ball", "event", "automatic"),
        ("box-push", "event", "automatic"),
        ("allegro-tilt", "event", "automatic"),  # its grasp contacts switch by default (it held them, exit 5 at a slip)
        ("box-stack", "event", "automatic"),  # 20 found from geometry
        ("allegro-sphere", "held", "scene"),  # [run] contacts = "held"
    ],
)
def test_a_scene_whose_contacts_switch_switches_by_default(name, treatment, chosen):
    choice = contact_choice(load_scene(name))
    assert (choice.treatment, choice.chosen) == (treatment, chosen), choice


def test_no_contacts_no_choice():
    assert contact_choice(load_scene("fourbar")) is None


def test_many_declared_contacts_step_in_time_and_others_keep_them_held():
    """Nine declared plane contacts: time-stepping; contacts beside a closure: held,
    naming the closure."""
    push = load_scene("box-push")
    nine = dataclasses.replace(push, constraints=[*push.constraints, *push.constraints, push.constraints[0]])
    assert len(nine.constraints) == MAX_EVENT_CONTACTS + 1
    choice = contact_choice(nine)
    assert (choice.treatment, choice.chosen) == ("stepping", "automatic") and "9 contacts" in choice.why
    fourbar = load_scene("fourbar")
    mixed = dataclasses.replace(push, constraints=[*push.constraints, *fourbar.constraints])
    choice = contact_choice(mixed)
    assert choice.treatment == "held" and fourbar.constraints[0].name in choice.why


def test_a_grasp_contact_without_modes_keeps_the_contacts_held_naming_it():
    """allegro-tilt with its index contact rigid (a model with no event-driven modes): held, naming the contact and
    its model; with it point-friction again, the contacts switch."""
    data = tomllib.loads((ROBOTS / "allegro-tilt.toml").read_text(encoding="utf-8"))
    index = next(entry for entry in data["contacts"] if entry.get("name") == "index")
    point_friction = dict(index)
    index["model"] = "rigid"
    del index["mu"]
    choice = contact_choice(scene_from_dict(data, "rigid-index", ROBOTS))
    assert choice.treatment == "held" and choice.why == "grasp contact index is rigid: no event-driven modes", choice
    index.update(point_friction)
    assert contact_choice(scene_from_dict(data, "index", ROBOTS)).treatment == "event"


def test_simulate_without_contacts_runs_the_treatment_the_scene_asks_for():
    """box-push with ``[run] contacts = "stepping"``: ``simulate(scene)`` (contacts None) steps in time as the scene
    asks, equal to the last bit to the run asked for stepping; asked for held, it holds."""
    data = tomllib.loads((ROBOTS / "box-push.toml").read_text(encoding="utf-8"))
    data = {"run": {"contacts": "stepping"}, **data}
    scene = scene_from_dict(data, "box-push-stepping", ROBOTS)
    default = simulate(scene, duration=0.05)
    stepping = simulate(scene, contacts="stepping", duration=0.05)
    assert default.info.contact_treatment["treatment"] == "stepping"
    assert default.info.contact_treatment["chosen"] == "scene"
    assert np.array_equal(default.q, stepping.q) and np.array_equal(default.v, stepping.v)
    assert simulate(scene, contacts="held", duration=0.05).info.contact_treatment["treatment"] == "held"


def test_auto_runs_the_scenes_choice_to_the_last_bit_and_reports_it():
    """simulate(contacts="auto") on bouncing-ball is the event-driven run (equal to the last bit) and says so, as does
    simulate() without contacts; asked for held, the run says it was asked."""
    scene = load_scene("bouncing-ball")
    auto = simulate(scene, contacts="auto", duration=0.5)
    event = simulate(scene, contacts="event", duration=0.5)
    assert np.array_equal(auto.q, event.q) and np.array_equal(auto.v, event.v)
    assert auto.info.contact_treatment == {
        "treatment": "event",
        "chosen": "automatic",
        "why": auto.info.contact_treatment["why"],
    }
    assert event.info.contact_treatment["chosen"] == "asked"
    default = simulate(scene, duration=0.5)
    assert np.array_equal(default.q, event.q) and default.info.contact_treatment == auto.info.contact_treatment
    assert simulate(scene, contacts="held", duration=0.01).info.contact_treatment == {
        "treatment": "held",
        "chosen": "asked",
        "why": "asked for held",
    }


def nine_corner_box(folder: Path) -> Path:
    """box-push on nine points of its bottom face (MAX_EVENT_CONTACTS + 1 declared contacts), as a scene file."""
    data = tomllib.loads((ROBOTS / "box-push.toml").read_text(encoding="utf-8"))
    data["robot"]["urdf"] = str(ROBOTS / data["robot"]["urdf"])
    corner = data["contacts"][0]
    points = [(x, y) for x in (-0.1, 0.0, 0.1) for y in (-0.05, 0.0, 0.05)]
    data["contacts"] = [{**corner, "name": f"p{k}", "offset_a": [x, y, -0.025]} for k, (x, y) in enumerate(points)]
    path = folder / "nine.toml"
    path.write_text(toml_document(data), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("name", "treatment", "chosen"),
    [
        ("bouncing-ball", "event", "automatic"),
        ("nine", "stepping", "automatic"),
        ("hand-cube", "stepping", "scene"),
        ("allegro-sphere", "held", "scene"),
    ],
)
def test_simulate_and_run_take_the_same_treatment(name, treatment, chosen, tmp_path):
    """``simulate(scene)`` (contacts None, its default) and ``pinstab run`` without --contacts: the same treatment,
    reported alike in ``info.contact_treatment`` and the JSON, and the same samples to the last bit."""
    source = str(nine_corner_box(tmp_path)) if name == "nine" else name
    api = simulate(load_scene(source), duration=0.02)
    saved = tmp_path / "run.npz"
    ran = cli(["run", source, "--duration", "0.02", "--json", "--quiet", "--save", str(saved)])
    assert ran.code == 0, ran
    reported = api.info.contact_treatment
    assert (reported["treatment"], reported["chosen"]) == (treatment, chosen), reported
    assert json.loads(ran.out)["contact_treatment"] == reported
    run = Trajectory.load(saved)
    assert run.info.contact_treatment == reported
    assert np.array_equal(api.t, run.t) and np.array_equal(api.q, run.q) and np.array_equal(api.v, run.v)


def test_the_scene_asks_and_a_wrong_ask_is_refused():
    with pytest.raises(SceneError, match="run.contacts: unknown treatment 'rigid'; valid: held, event, stepping"):
        scene_from_dict({"run": {"contacts": "rigid"}, "robot": {"name": "panda"}})
    with pytest.raises(PinstabError, match="contacts: unknown treatment 'rigid'; valid: held, event, stepping, auto"):
        simulate(load_scene("bouncing-ball"), contacts="rigid", duration=0.01)


def test_the_cli_json_reports_the_choice():
    """``run --json`` without --contacts: the scene's choice, with why; with --contacts held: asked."""
    ran = cli(["run", "box-push", "--duration", "0.05", "--json", "--quiet"])
    assert ran.code == 0
    report = json.loads(ran.out)
    assert report["contact_treatment"]["treatment"] == "event" and report["contact_treatment"]["chosen"] == "automatic"
    ran = cli(["run", "box-push", "--duration", "0.05", "--json", "--quiet", "--contacts", "held"])
    assert ran.code == 0 and json.loads(ran.out)["contact_treatment"] == {
        "treatment": "held",
        "chosen": "asked",
        "why": "asked for held",
    }


def test_held_options_on_switching_contacts_are_refused():
    """box-push (event-driven by default): a solver, a method other than the default and the method's options belong
    to held rows; with event-driven or time-stepping contacts they are refused, naming them and contacts='held' (they
    were ignored); asked for held, they run."""
    with pytest.raises(PinstabError, match=r"^solver: scene box-push's contacts are event \(4 contacts.*'held'"):
        simulate("box-push", solver="dense", duration=0.01)
    with pytest.raises(PinstabError, match=r"^method, kp: scene box-push's contacts are event \(asked for\)"):
        simulate("box-push", contacts="event", method="projection", kp=1.0, duration=0.01)
    with pytest.raises(PinstabError, match=r"^solver_options: scene box-push's contacts are stepping"):
        simulate("box-push", contacts="stepping", solver_options={"eps_abs": 1e-9}, duration=0.01)
    held = simulate("box-push", contacts="held", method="projection", solver="proxsuite", duration=0.01)
    assert (held.info.method, held.info.solver) == ("projection", "proxsuite")

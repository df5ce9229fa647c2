"""Start checks and ranges of scene tables (issue 34): a start inside a plane is measured against the bodies' own
extent wherever the scene lies, objects' dimensions and masses have a floor, applied loads a ceiling; each boundary
value still runs (finite, no penetration, no energy gained)."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from fuzzing import cli, contact_gaps, mechanical_energy, toml_document

from conftest import ROBOTS
from pinstab.errors import DivergenceError, SceneError
from pinstab.forces.base import MAX_LOAD
from pinstab.scene import load_scene
from pinstab.simulate.api import simulate
from pinstab.tables import SceneTables, scene_size
from pinstab.trajectory import Trajectory
from pinstab.units import MIN_LENGTH, MIN_MASS

STAND = {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"}
FAR = 1e6  # [m] the largest coordinate a scene may give (units.MAX_COORDINATE)


def ball_scene(y: float, height: float, normal: list[float]) -> dict:
    """A 0.4 m, 89 kg ball at (-1, y, height) over a plane contact of ``normal`` through the origin."""
    return {
        "gravity": [0.0, 0.0, -9.81],
        "robot": STAND,
        "objects": [{"name": "crate", "shape": "sphere", "radius": 0.4, "mass": 89.0, "position": [-1.0, y, height]}],
        "contacts": [{"name": "c0", "kind": "plane-contact", "frame_a": "crate", "normal": normal}],
    }


def write(scene: dict, folder: Path, name: str = "scene") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    return path


def run(path: Path, contacts: str, folder: Path, duration: float = 0.12):
    """``pinstab run`` with ``--contacts``: (exit code, message, trajectory or None)."""
    saved = folder / f"{path.stem}-{contacts}.npz"
    outcome = cli(["run", str(path), "--contacts", contacts, "--duration", str(duration), "--save", str(saved)])
    return outcome.code, outcome.message, Trajectory.load(saved) if outcome.code == 0 else None


@pytest.mark.parametrize("y", [0.0, FAR])
def test_start_inside_its_plane_is_refused_wherever_the_scene_lies(y: float, tmp_path: Path) -> None:
    """The ball's centre on a plane facing down: 0.4 m inside, refused at y = 0 and at y = 1e6 m alike (at 1e6 m the
    size had counted the distance from the origin: a 100 m tolerance, and time-stepping threw it out with 7.1 MJ)."""
    with pytest.raises(SceneError, match=r"contact 'c0': the contact point starts 0\.4 m inside its plane.* \(1 m\)"):
        load_scene(write(ball_scene(y, 0.4, [0.0, 0.0, -1.0]), tmp_path))


@pytest.mark.parametrize("contacts", ["stepping", "event"])
def test_ball_on_its_plane_far_from_the_origin_runs_as_at_the_origin(contacts: str, tmp_path: Path) -> None:
    """The ball touching its plane (centre 0.4 m above the plane z = 0, as a vertex 0.4 m below it; the plane's
    point under the ball): taken at y = 0 and at y = 1e6 m, with the same size (1 m) and the same motion (the plane's
    point on the world is measured from the bodies: at 1e6 m it was refused as 1e6 m from the origin)."""
    ends = []
    for y in (0.0, FAR):
        scene = ball_scene(y, 0.4, [0.0, 0.0, 1.0])
        scene["contacts"][0]["offset_a"] = [0.0, 0.0, -0.4]
        scene["contacts"][0]["point"] = [-1.0, y, 0.0]
        path = write(scene, tmp_path, f"ball{y:g}")
        loaded = load_scene(path)
        assert scene_size(loaded.model, loaded.q0) == 1.0
        code, message, trajectory = run(path, contacts, tmp_path)
        assert code == 0, message
        ends.append(trajectory.q[-1] - loaded.q0)
    np.testing.assert_allclose(ends[0], ends[1], atol=1e-9)


def test_box_push_moved_a_million_metres_keeps_its_size() -> None:
    """box-push's size at the origin and with its box at x = 1e6 m (the diagonal from the origin was 1e6 m)."""
    scene = load_scene(ROBOTS / "box-push.toml")
    moved = scene.q0.copy()
    moved[0] += FAR
    assert scene_size(scene.model, moved) == scene_size(scene.model, scene.q0) == 1.0


def test_points_on_the_world_are_measured_from_the_bodies(tmp_path: Path) -> None:
    """A point on the world next to a ball at y = 1e6 m is within reach; 10 sizes beyond the ball it is not; a point
    on the ball keeps the reach of its frame's origin."""
    loaded = load_scene(write(ball_scene(FAR, 0.4, [0.0, 0.0, 1.0]), tmp_path))
    tables = SceneTables(loaded.model, loaded.q0)
    tables.within_reach(np.array([-1.0, FAR + 5.0, 0.0]), "near", on_world=True)
    with pytest.raises(SceneError, match=r"far = \[-1, 1\.00001e\+06, 0\] m lies 11 m from the scene's bodies"):
        tables.within_reach(np.array([-1.0, FAR + 11.0, 0.0]), "far", on_world=True)
    with pytest.raises(SceneError, match=r"on_body = \[0, 1e\+06, 0\] m lies 1e\+06 m from its frame's origin"):
        tables.within_reach(np.array([0.0, FAR, 0.0]), "on_body")


def crate(shape: str, **keys: object) -> dict:
    """A scene of one object ``crate`` (100 kg unless ``mass`` is given) on the plane z = 0."""
    entry = {"name": "crate", "shape": shape, "mass": 100.0, "position": [0.0, 0.0, 1.0], **keys}
    return {"gravity": [0.0, 0.0, -9.81], "robot": STAND, "objects": [entry]}


@pytest.mark.parametrize(
    ("keys", "phrase"),
    [
        # was: LinAlgError in the time-stepping Cholesky (a cylinder of radius 1e-300 m)
        ({"shape": "cylinder", "radius": 1e-300, "length": 0.02}, "object 'crate'.radius = 1e-300 m is outside"),
        ({"shape": "sphere", "radius": 5e-324}, "object 'crate'.radius = 4.94e-324 m is outside"),
        ({"shape": "cylinder", "radius": 0.1, "length": MIN_LENGTH * 0.999}, "object 'crate'.length = 9.99e-07 m"),
        ({"shape": "box", "size": [1.0, 1e-7, 1.0]}, "object 'crate'.size[1] = 1e-07 m is outside"),
        ({"shape": "sphere", "radius": MIN_LENGTH}, None),
    ],
)
def test_object_dimensions_have_a_floor(keys: dict, phrase: str | None, tmp_path: Path) -> None:
    """Dimensions below a micrometre are refused by name with the range [1e-06, 1e+12] m; a micrometre is taken."""
    path = write(crate(**keys), tmp_path)
    if phrase is None:
        assert load_scene(path).objects[0].mass == 100.0
        return
    with pytest.raises(SceneError, match=r"allowed range \[1e-06, 1e\+12\] m: thinner than a micrometre") as caught:
        load_scene(path)
    assert phrase in str(caught.value)


@pytest.mark.parametrize(("moments", "taken"), [([1e-12, 1.0, 1.0], True), ([0.99e-12, 1.0, 1.0], False)])
def test_a_given_inertia_is_at_least_a_micrometre_cubes(moments: list, taken: bool, tmp_path: Path) -> None:
    """6 kg: the floor is 6 (1e-6)^2 / 6 = 1e-12 kg m^2 (a cube of side 1e-6 m); just below it, refused by name."""
    path = write(crate("sphere", radius=0.1, mass=6.0, inertia=[*moments, 0.0, 0.0, 0.0]), tmp_path)
    if taken:
        load_scene(path)
        return
    with pytest.raises(SceneError, match=r"object 'crate'\.inertia: its smallest principal moment 9\.9e-13 kg m\^2"):
        load_scene(path)


@pytest.mark.parametrize("mass", [1e-12, 5e-324])
def test_object_mass_below_a_microgram_is_refused_by_name(mass: float, tmp_path: Path) -> None:
    """1e-12 kg made a false Painleve paradox and 5e-324 kg a LinAlgError (units.MIN_MASS)."""
    path = write(crate("box", size=[1.0, 1.0, 0.2], mass=mass), tmp_path)
    with pytest.raises(SceneError, match=rf"object 'crate'\.mass = {mass:.3g} kg is outside the allowed range \[1e-09"):
        load_scene(path)


GRAIN = {  # a micrometre grain of a microgram, both floors, sliding on the plane with friction
    "gravity": [0.0, 0.0, -9.81],
    "robot": STAND,
    "objects": [{"name": "grain", "shape": "sphere", "radius": MIN_LENGTH, "mass": MIN_MASS, "position": [0, 0, 1e-6]}],
    "contacts": [{"name": "c0", "kind": "plane-contact", "frame_a": "grain", "radius": MIN_LENGTH, "mu": 0.3}],
    "initial": {"v": {"grain": [0.01, 0.0, 0.0, 0.0, 0.0, 0.0]}},
}
NEEDLE = {  # a 100 kg needle of radius 1e-6 m and length 1 m lying 1 cm above the plane on its two ends
    "gravity": [0.0, 0.0, -9.81],
    "robot": STAND,
    "objects": [
        {
            "name": "needle",
            "shape": "cylinder",
            "radius": MIN_LENGTH,
            "length": 1.0,
            "mass": 100.0,
            "position": [0.0, 0.0, MIN_LENGTH + 0.01],
            "rpy": [0.0, math.pi / 2, 0.0],
        }
    ],
    "contacts": [
        {"name": f"c{k}", "kind": "plane-contact", "frame_a": "needle", "offset_a": [0, 0, end], "radius": MIN_LENGTH}
        for k, end in enumerate((-0.5, 0.5))
    ],
}


@pytest.mark.parametrize("contacts", ["stepping", "event"])
@pytest.mark.parametrize("scene", [GRAIN, NEEDLE], ids=["grain", "needle"])
def test_bodies_at_the_floors_run(scene: dict, contacts: str, tmp_path: Path) -> None:
    """At the floors the runs end at 0.12 s with no energy gained and no depth past 1e-10 m (measured: the grain's
    deepest 5e-11 m event-driven, the needle's 3e-13 m)."""
    path = write(scene, tmp_path)
    code, message, trajectory = run(path, contacts, tmp_path)
    assert code == 0, message
    loaded = load_scene(path)
    energy = mechanical_energy(loaded, trajectory.q, trajectory.v)
    assert trajectory.t[-1] == pytest.approx(0.12)
    assert energy.max() <= energy[0] * (1.0 + 1e-9)
    assert contact_gaps(loaded, trajectory.q).min() >= -1e-10


BOX_PUSH = tomllib.loads((ROBOTS / "box-push.toml").read_text())
BOX_PUSH["robot"]["urdf"] = str(ROBOTS / BOX_PUSH["robot"]["urdf"])


def pushed(force: list[float]) -> dict:
    scene = copy.deepcopy(BOX_PUSH)
    scene["forces"][0]["force"] = force
    return scene


@pytest.mark.parametrize(
    ("force", "phrase"),
    [
        # was: ZeroDivisionError in integration/adaptive.py initial_step
        ([11.0, 1e200, -3.1], "|force 'push'.force| = 1e+200 N is outside the allowed range [0, 1e+06] N"),
        ([0.0, 0.0, -MAX_LOAD * 1.000001], "|force 'push'.force| = 1e+06 N is outside"),
    ],
)
def test_external_force_beyond_a_meganewton_is_refused(force: list, phrase: str, tmp_path: Path) -> None:
    path = write(pushed(force), tmp_path)
    for argv in (["check", str(path)], ["run", str(path), "--contacts", "event"]):
        outcome = cli(argv)
        assert outcome.code == 2 and phrase in outcome.message, outcome


@pytest.mark.parametrize(
    ("change", "phrase"),
    [
        ({"moment": [0.0, 2e6, 0.0]}, "|force 'push'.moment| = 2e+06 N m is outside"),
        ({"force": [1e308, 1e308, 0.0]}, "|force 'push'.force| = 1.41421e+308 N is outside"),
    ],
)
def test_external_moment_and_overflowing_force_are_refused(change: dict, phrase: str, tmp_path: Path) -> None:
    scene = pushed([1.0, 0.0, 0.0])
    scene["forces"][0].update(change)
    with pytest.raises(SceneError) as caught:
        load_scene(write(scene, tmp_path))
    assert phrase in str(caught.value)


@pytest.mark.parametrize(
    ("force", "phrase"),
    [({"torque": -2e6}, "|force 'drive'.torque| = 2e+06 N m or N"), ({"table": [[0, 1], [1, 3e6]]}, "table[1] torque")],
)
def test_joint_torque_beyond_the_ceiling_is_refused(force: dict, phrase: str, tmp_path: Path) -> None:
    """slider-crank's drive torque, constant or a table, past 1e6 N m."""
    scene = tomllib.loads((ROBOTS / "slider-crank.toml").read_text())
    drive = next(f for f in scene["forces"] if f["kind"] == "joint-torque")
    drive.pop("torque", None)
    drive.update(force, name="drive")
    scene["robot"]["urdf"] = str(ROBOTS / scene["robot"]["urdf"])
    with pytest.raises(SceneError, match="outside the allowed range") as caught:
        load_scene(write(scene, tmp_path))
    assert phrase in str(caught.value)


@pytest.mark.parametrize("contacts", ["stepping", "event", "held"])
def test_a_meganewton_press_holds_the_box(contacts: str, tmp_path: Path) -> None:
    """box-push pressed into its table with MAX_LOAD: the box stays on its table (measured: within 2e-9 m)."""
    code, message, trajectory = run(write(pushed([0.0, 0.0, -MAX_LOAD]), tmp_path), contacts, tmp_path)
    assert code == 0, message
    np.testing.assert_allclose(trajectory.q[:, :3], [[0.0, 0.0, 0.025]] * len(trajectory.t), atol=1e-8)


def test_generator_velocity_named_by_its_parameter() -> None:
    """incline's v_down = 1e200 (was ZeroDivisionError with event contacts and 60 s held): the parameter named."""
    outcome = cli(["run", "incline", "--param", "v_down=1e200", "--contacts", "event"])
    assert outcome.code == 2 and "generator incline: parameter v_down must be a number in [-1000000" in outcome.message


def test_first_step_of_infinite_rates_is_a_named_divergence() -> None:
    """Past the load check (a wrench set in the model, 1e300 N): the event path's first step is a DivergenceError,
    not ZeroDivisionError."""
    scene = load_scene(ROBOTS / "box-push.toml")
    next(f for f in scene.forces if f.name == "push").wrench[:3] = [11.0, 1e300, -3.1]
    with pytest.raises(DivergenceError):
        simulate(scene, duration=0.01, contacts="event")

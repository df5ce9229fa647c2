"""An object's URDF file (``[[objects]] shape = "urdf"``) read by the scene's URDF reader and held to the checks of
a robot's URDF (issue 34): each hostile file refused by name (``object 'crate'.urdf``), exit 2, before any work;
the bounds' own values load; a valid file gives the body Pinocchio's own parser gives."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
from test_catalogue import Case, run_case

from conftest import ROBOTS
from pinstab.readers.bounds import MAX_BODIES, MAX_FILE_BYTES, MAX_TREE_DEPTH, MAX_XML_NESTING
from pinstab.scene import load_scene

OWNER = "object 'crate'.urdf"
UNIT_INERTIA = ("0.01", "0.01", "0.01")


def scene_text(urdf: str = '"crate.urdf"') -> str:
    """A four-bar robot and one URDF object ``crate`` whose ``urdf`` is ``urdf`` (TOML), relative to the scene."""
    return (
        f'name = "crate-scene"\n[robot]\nurdf = "{ROBOTS / "urdf" / "fourbar.urdf"}"\n'
        f'[[objects]]\nname = "crate"\nshape = "urdf"\nurdf = {urdf}\nposition = [0.0, 0.0, 1.0]\n'
    )


def link(name: str, mass: str = "1", moments: tuple[str, str, str] = UNIT_INERTIA, inner: str = "") -> str:
    """A link of ``mass`` [kg] and principal ``moments`` [kg m^2] (its centre 0.1 m along x), holding ``inner``."""
    ixx, iyy, izz = moments
    return (
        f'<link name="{name}"><inertial><origin xyz="0.1 0 0"/><mass value="{mass}"/>'
        f'<inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial>{inner}</link>'
    )


def joint(name: str, parent: str, child: str, kind: str = "fixed") -> str:
    """A joint of ``kind`` placing ``child`` 1 cm above ``parent``, turned 0.3 rad about x."""
    return (
        f'<joint name="{name}" type="{kind}"><origin xyz="0 0 0.01" rpy="0.3 0 0"/>'
        f'<parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/></joint>'
    )


def urdf(*elements: str) -> str:
    """A URDF document of ``elements`` (links and joints)."""
    return '<?xml version="1.0"?><robot name="crate">' + "".join(elements) + "</robot>"


def star(links: int) -> str:
    """``links`` links, each fixed to the first."""
    return urdf(*(link(f"l{i}") for i in range(links)), *(joint(f"j{i}", "l0", f"l{i}") for i in range(1, links)))


def chain(depth: int) -> str:
    """A chain of ``depth`` fixed joints (``depth + 1`` links)."""
    return urdf(
        *(link(f"l{i}") for i in range(depth + 1)), *(joint(f"j{i}", f"l{i - 1}", f"l{i}") for i in range(1, depth + 1))
    )


def nested(levels: int) -> str:
    """A link whose <visual> holds elements nested so that the document is ``levels`` deep (urdfdom ignores them)."""
    inner = "<x>" * (levels - 3) + "</x>" * (levels - 3)  # <robot><link><visual> and the rest
    return urdf(
        link("a", inner=f"<visual><origin xyz='0 0 0'/>{inner}<geometry><sphere radius='0.1'/></geometry></visual>")
    )


def object_case(name: str, phrase: str, content: str | bytes, urdf_value: str = '"crate.urdf"', argv: str = "") -> Case:
    """``pinstab check`` (or ``argv``) of the crate scene whose object file is ``content``."""
    return Case(
        name,
        argv or "check {tmp}/s.toml",
        "SceneError",
        phrase,
        files=(("s.toml", scene_text(urdf_value)), ("crate.urdf", content)),
    )


LATIN1 = urdf(link("caf\xe9")).replace('version="1.0"', 'version="1.0" encoding="ISO-8859-1"').encode("latin-1")
CASES = [
    object_case("mass -1", f"{OWNER} link 'a': mass -1.0 kg is negative", urdf(link("a", mass="-1"))),
    object_case(  # the body's total mass (1 kg) is positive: Pinocchio summed the links without a word
        "a fixed child of mass -1",
        f"{OWNER} link 'b': mass -1.0 kg is negative",
        urdf(link("a", mass="2"), link("b", mass="-1"), joint("j", "a", "b")),
    ),
    object_case("mass nan", f"{OWNER} link 'a': mass 'nan' is not a finite number", urdf(link("a", mass="nan"))),
    object_case(
        "mass beyond the ceiling", f"{OWNER} link 'a': mass = 1e+13 kg is outside", urdf(link("a", mass="1e13"))
    ),
    object_case(
        "inertia not PSD",
        f"{OWNER} link 'a': inertia is not positive semidefinite: principal moments [-1.0, 1.0, 1.0] kg m^2",
        urdf(link("a", moments=("-1", "1", "1"))),
    ),
    object_case(
        "inertia against the triangle inequality",
        f"{OWNER} link 'a': inertia violates the triangle inequality: principal moments [1.0, 1.0, 3.0] kg m^2",
        urdf(link("a", moments=("1", "1", "3"))),
    ),
    object_case("10000 links", f"10000 links, more than the limit of {MAX_BODIES}", star(10_000)),
    object_case(
        "a chain 2000 deep",
        f"the kinematic tree is 2000 joints deep, deeper than the limit of {MAX_TREE_DEPTH}",
        chain(2000),
    ),
    object_case(
        "nested too deep",
        f"<x> is nested {MAX_XML_NESTING + 1} elements deep, deeper than the limit of {MAX_XML_NESTING}",
        nested(MAX_XML_NESTING + 1),
    ),
    object_case(
        "binary",
        "byte 1 (0xff) is not UTF-8: a URDF file is UTF-8 text",
        b"\x00\xff\xfe\x89PNG\r\n" + bytes(range(256)),
    ),
    object_case(  # tinyxml2 would take the bytes as UTF-8 whatever the declaration says
        "Latin-1 declared", f"byte {LATIN1.index(0xE9)} (0xe9) is not UTF-8", LATIN1
    ),
    object_case("not XML", f"{OWNER}: the URDF cannot be read: syntax error: line 1, column 0", "this is not xml"),
    object_case(
        "a link defined twice", f"{OWNER}: link 'a' is defined twice", urdf(link("a"), link("a"), joint("j", "a", "a"))
    ),
    object_case(
        "a joint to a missing link",
        f"{OWNER} joint 'j': child link 'z' does not exist; links: a",
        urdf(link("a"), joint("j", "a", "z")),
    ),
    object_case(
        "a moving joint",
        f"{OWNER}: an object is one rigid body, but joint 'j' of crate.urdf moves",
        urdf(link("a"), link("b"), joint("j", "a", "b", kind="continuous")),
    ),
    object_case("no mass", f"{OWNER}: the links of crate.urdf have no mass", urdf(link("a", mass="0"))),
    object_case(
        "a missing mesh",
        f"{OWNER}: the URDF cannot be read: Mesh nowhere.stl could not be found",
        urdf(link("a", inner='<collision><geometry><mesh filename="nowhere.stl"/></geometry></collision>')),
    ),
    object_case("missing file", "does not exist", urdf(link("a")), urdf_value='"absent.urdf"'),
    object_case("not a path", f"{OWNER} must be a path string, got 5", urdf(link("a")), urdf_value="5"),
    object_case(  # refused at load: no run file written
        "run with mass -1",
        f"{OWNER} link 'a': mass -1.0 kg is negative",
        urdf(link("a", mass="-1")),
        argv="run {tmp}/s.toml --duration 0.01 --save {tmp}/r.npz",
    ),
]


def test_cases_are_distinct():
    assert len({case.name for case in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_hostile_object_file_is_refused_by_name(case, tmp_path, capsys):
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (2, case.error), err
    assert case.phrase in err and OWNER in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "r.npz").exists()


def test_a_robot_file_in_latin_1_is_refused_by_the_same_rule(tmp_path, capsys):
    """The robot's URDF and an object's are read by one reader: the same check, named for the robot."""
    scene = 'name = "latin"\n[robot]\nurdf = "latin.urdf"\n'
    case = Case(
        "robot in Latin-1", "check {tmp}/s.toml", "SceneError", "", files=(("s.toml", scene), ("latin.urdf", LATIN1))
    )
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (2, "SceneError"), err
    assert f"robot: URDF {tmp_path / 'latin.urdf'}: byte {LATIN1.index(0xE9)} (0xe9) is not UTF-8" in err


def test_a_100_mb_object_file_is_refused_before_it_is_read(tmp_path, capsys):
    """A sparse file of 100 MB (stat says so; nothing is read): named with its size and the limit."""
    with open(tmp_path / "big.urdf", "wb") as handle:
        handle.truncate(100_000_000)
    case = Case("100 MB", "check {tmp}/s.toml", "SceneError", "", files=(("s.toml", scene_text('"big.urdf"')),))
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (2, "SceneError"), err
    assert f"{OWNER}: URDF {tmp_path / 'big.urdf'}: " in err
    assert f"has 100000000 bytes, more than the limit of {MAX_FILE_BYTES} bytes" in err


def test_a_chain_that_overflows_pinocchio_is_refused_in_a_fresh_process(tmp_path):
    """A chain 4000 deep (4001 links, within the bound on links) ends Pinocchio's recursive URDF parser in a
    segmentation fault (exit -11 with an 8 MB stack): the command ends in exit 2 and the named error instead."""
    (tmp_path / "s.toml").write_text(scene_text())
    (tmp_path / "crate.urdf").write_text(chain(4000))
    done = subprocess.run(
        [sys.executable, "-m", "pinstab.cli", "check", str(tmp_path / "s.toml")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 2, done.stderr
    assert f"{OWNER}: URDF {tmp_path / 'crate.urdf'}: the kinematic tree is 4000 joints deep" in done.stderr
    assert "Traceback" not in done.stderr


def load(tmp_path, content: str | bytes):
    """The crate scene with ``content`` as the object's file."""
    (tmp_path / "s.toml").write_text(scene_text())
    target = tmp_path / "crate.urdf"
    target.write_bytes(content) if isinstance(content, bytes) else target.write_text(content)
    return load_scene(tmp_path / "s.toml")


def assert_same_body(scene, path) -> None:
    """The object's inertia and shapes are those of Pinocchio's own parse of ``path`` (its links summed on the
    universe joint), to the last bit."""
    item = scene.objects[0]
    reference = pin.buildModelFromUrdf(str(path))
    inertia, expected = scene.model.inertias[item.joint], reference.inertias[0]
    assert inertia.mass == expected.mass > 0
    np.testing.assert_array_equal(inertia.lever, expected.lever)
    np.testing.assert_array_equal(inertia.inertia, expected.inertia)
    collision = pin.buildGeomFromUrdf(reference, str(path), pin.GeometryType.COLLISION, package_dirs=[str(path.parent)])
    assert len(item.geometries) == len(collision.geometryObjects)
    for (shape, placement), geometry in zip(item.geometries, collision.geometryObjects, strict=True):
        assert type(shape) is type(geometry.geometry)
        np.testing.assert_array_equal(placement.homogeneous, geometry.placement.homogeneous)


@pytest.mark.parametrize("name", ["box.urdf", "striped-ball.urdf"])
def test_bundled_object_files_load_as_pinocchio_reads_them(name, tmp_path):
    path = ROBOTS / "urdf" / name
    (tmp_path / "s.toml").write_text(scene_text(f'"{path}"'))
    assert_same_body(load_scene(tmp_path / "s.toml"), path)


def test_a_composite_object_is_its_links_summed(tmp_path):
    """Links of 2 kg and 0.5 kg fixed 1 cm apart: the mass 2.5 kg and the centre of mass (0.1 m along x, 0.5/2.5 of
    1 cm up) in closed form, the rest as Pinocchio's own parse."""
    scene = load(
        tmp_path,
        urdf(
            link("a", mass="2", inner="<collision><geometry><box size='0.1 0.2 0.3'/></geometry></collision>"),
            link("b", mass="0.5", inner="<collision><geometry><sphere radius='0.05'/></geometry></collision>"),
            joint("j", "a", "b"),
        ),
    )
    inertia = scene.model.inertias[scene.objects[0].joint]
    assert inertia.mass == pytest.approx(2.5, rel=1e-15)
    lever_b = pin.SE3(pin.rpy.rpyToMatrix(0.3, 0.0, 0.0), np.array([0.0, 0.0, 0.01])) * np.array([0.1, 0.0, 0.0])
    np.testing.assert_allclose(inertia.lever, (2.0 * np.array([0.1, 0.0, 0.0]) + 0.5 * lever_b) / 2.5, atol=1e-15)
    assert_same_body(scene, tmp_path / "crate.urdf")
    assert scene.objects[0].mass == pytest.approx(2.5, rel=1e-15)


@pytest.mark.parametrize(
    ("make", "bound", "phrase"),
    [
        (star, MAX_BODIES, f"{MAX_BODIES + 1} links, more than the limit of {MAX_BODIES}"),
        (chain, MAX_TREE_DEPTH, f"{MAX_TREE_DEPTH + 1} joints deep, deeper than the limit of {MAX_TREE_DEPTH}"),
        (nested, MAX_XML_NESTING, f"nested {MAX_XML_NESTING + 1} elements deep, deeper than the limit"),
    ],
    ids=["links", "depth", "nesting"],
)
def test_object_files_at_a_bound_load_one_more_is_refused(make, bound, phrase, tmp_path, capsys):
    """At the bound: the body Pinocchio reads; one link, joint or level more: refused by name."""
    assert_same_body(load(tmp_path, make(bound)), tmp_path / "crate.urdf")
    code, error, err = run_case(object_case("one more", phrase, make(bound + 1)), tmp_path, capsys)
    assert (code, error) == (2, "SceneError") and phrase in err and OWNER in err, err


def test_an_object_file_of_the_most_bytes_allowed_loads(tmp_path, capsys):
    """A file of exactly MAX_FILE_BYTES (a box padded with spaces) loads as Pinocchio reads it; one byte more is
    refused."""
    body = urdf(link("a", inner="<collision><geometry><box size='0.1 0.2 0.3'/></geometry></collision>"))
    padded = body.replace("</robot>", " " * (MAX_FILE_BYTES - len(body)) + "</robot>")
    assert len(padded.encode()) == MAX_FILE_BYTES
    assert_same_body(load(tmp_path, padded), tmp_path / "crate.urdf")
    phrase = f"has {MAX_FILE_BYTES + 1} bytes, more than the limit of {MAX_FILE_BYTES} bytes"
    code, error, err = run_case(object_case("one byte more", phrase, padded + " "), tmp_path, capsys)
    assert (code, error) == (2, "SceneError") and phrase in err and OWNER in err, err

"""Robot readers without silent wrong physics, recursion or blow-ups (issue 34): one mass and inertia check for
URDF, SDF and MJCF (pinstab.readers.inertia), and the bounds of pinstab.readers.bounds on a robot file's bytes,
nesting, bodies, joints and depth, and on MJCF includes. Each refusal is a command line ending in its named error
(exit 2, a phrase naming the file, the item and the value or limit, no traceback, under 10 s); each bound's largest
allowed model still loads."""

from __future__ import annotations

import time

import numpy as np
import pytest
from test_catalogue import Case, run_case

from pinstab.errors import SceneError
from pinstab.readers import read_robot
from pinstab.readers.bounds import MAX_BODIES, MAX_FILE_BYTES, MAX_TREE_DEPTH, MAX_XML_NESTING, tree_depth
from pinstab.readers.mjcf_bodies import check_compiled
from pinstab.readers.mjcf_xml import MAX_INCLUDE_DEPTH, MAX_INCLUDED_FILES, read_document

INERTIAL = '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>'
URDF_INERTIAL = (
    '<inertial><mass value="{mass}"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>'
)
SDF_INERTIAL = "<inertial><mass>{mass}</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy><izz>0.1</izz></inertia></inertial>"


# -- robot files -------------------------------------------------------------------------------
def mjcf_body(inner: str, compiler: str = "", before: str = "") -> str:
    """One body ``b`` on a slide joint holding ``inner`` (its inertial, geoms); ``before`` its <worldbody>."""
    return (
        f'<mujoco model="one"><compiler angle="radian"{compiler}/>{before}<worldbody><body name="b">'
        f'<joint name="j" type="slide" axis="0 0 1"/>{inner}</body></worldbody></mujoco>'
    )


def mjcf_nested(bodies: int, joints: bool = True) -> str:
    """``bodies`` bodies nested in one another (each on a hinge when ``joints``)."""
    joint = '<joint name="j{i}" axis="0 1 0"/>' if joints else ""
    opening = "".join(f'<body name="b{i}" pos="0 0 0.1">{joint.format(i=i)}{INERTIAL}' for i in range(bodies))
    return f'<mujoco model="deep"><worldbody>{opening}{"</body>" * bodies}</worldbody></mujoco>'


def mjcf_wide(bodies: int) -> str:
    """``bodies`` bodies: one on a slide joint, the others fixed to it."""
    leaves = "".join(f'<body name="b{i}" pos="0 0 0.1">{INERTIAL}</body>' for i in range(1, bodies))
    return mjcf_body(INERTIAL + leaves)


def urdf_tree(links: int, chain: bool, mass: str = "1") -> str:
    """``links`` links: a chain (each on the one before) or a star (each on the first), revolute joints."""
    inertial = URDF_INERTIAL.format(mass=mass)
    parts = [f'<robot name="tree"><link name="l0">{inertial}</link>']
    for k in range(1, links):
        parent = f"l{k - 1}" if chain else "l0"
        parts.append(
            f'<link name="l{k}">{inertial}</link><joint name="j{k}" type="revolute"><parent link="{parent}"/>'
            f'<child link="l{k}"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/>'
            '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        )
    return "".join([*parts, "</robot>"])


def sdf_tree(links: int, chain: bool, mass: str = "1") -> str:
    """``links`` links, the first on the world: a chain or a star, revolute joints."""
    inertial = SDF_INERTIAL.format(mass=mass)
    parts = ['<sdf version="1.6"><model name="tree">']
    parts += [f"<link name='l{k}'><pose>0 0 {-0.1 * k} 0 0 0</pose>{inertial}</link>" for k in range(links)]
    for k in range(links):
        parent = "world" if k == 0 else f"l{k - 1}" if chain else "l0"
        parts.append(
            f"<joint name='j{k}' type='revolute'><parent>{parent}</parent><child>l{k}</child>"
            "<axis><xyz>0 1 0</xyz></axis></joint>"
        )
    return "".join([*parts, "</model></sdf>"])


def robot_case(name: str, key: str, text: str, error: str, phrase: str, argv: str = "check {tmp}/s.toml") -> Case:
    """``argv`` on a scene whose robot is the file ``text`` (``robot.<key>``, written as {tmp}/robot.<key>)."""
    scene = f'[robot]\n{key} = "robot.{key}"\n'
    return Case(name, argv, error, phrase, files=(("s.toml", scene), (f"robot.{key}", text)))


def fan_out(levels: int) -> tuple[tuple[str, str], ...]:
    """robot.mjcf including level0.xml, which includes level1.xml 10 times, and so on."""
    files = [("robot.mjcf", mjcf_body(INERTIAL, before='<include file="level0.xml"/>'))]
    for k in range(levels):
        inner = f'<include file="level{k + 1}.xml"/>' * 10 if k + 1 < levels else "<default/>"
        files.append((f"level{k}.xml", f"<mujoco>{inner}</mujoco>"))
    return tuple(files)


def include_chain(files: int) -> tuple[tuple[str, str], ...]:
    """robot.mjcf including inc0.xml, which includes inc1.xml, and so on: ``files`` included files."""
    chain = [("robot.mjcf", mjcf_body(INERTIAL, before='<include file="inc0.xml"/>'))]
    for k in range(files):
        inner = f'<include file="inc{k + 1}.xml"/>' if k + 1 < files else "<default/>"
        chain.append((f"inc{k}.xml", f"<mujoco>{inner}</mujoco>"))
    return tuple(chain)


MJCF_SCENE = ("s.toml", '[robot]\nmjcf = "robot.mjcf"\n')
NEGATIVE_DIAGONAL = "principal moments [-1.0, 1.0, 1.0] kg m^2"

CASES = [
    # the issue's examples: Pinocchio's parser ran these with mass 0 and inertia [0, 1, 1]
    robot_case(
        "MJCF inertial mass -0.5",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="-0.5" diaginertia="0.1 0.1 0.1"/>'),
        "SceneError",
        "robot.mjcf body 'b': mass -0.5 kg is negative",
    ),
    robot_case(
        "MJCF diaginertia -1 1 1",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1" diaginertia="-1 1 1"/>'),
        "SceneError",
        f"body 'b': inertia is not positive semidefinite: {NEGATIVE_DIAGONAL}",
    ),
    robot_case(
        "MJCF fullinertia -1 1 1",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1" fullinertia="-1 1 1 0 0 0"/>'),
        "SceneError",
        f"body 'b': inertia is not positive semidefinite: {NEGATIVE_DIAGONAL}",
    ),
    robot_case(  # eigenvalues of [[1, 2, 0], [2, 1, 0], [0, 0, 1]]: 1 - 2, 1, 1 + 2
        "MJCF fullinertia off-diagonal",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1" fullinertia="1 1 1 2 0 0"/>'),
        "SceneError",
        "inertia is not positive semidefinite: principal moments [-1.0, 1.0, 3.0] kg m^2",
    ),
    robot_case(  # MuJoCo refuses it too ("inertia must satisfy A + B >= C")
        "MJCF inertia triangle",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1" diaginertia="1 1 3"/>'),
        "SceneError",
        "body 'b': inertia violates the triangle inequality: principal moments [1.0, 1.0, 3.0] kg m^2",
    ),
    robot_case(
        "MJCF inertial mass beyond the ceiling",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1e13" diaginertia="0.1 0.1 0.1"/>'),
        "SceneError",
        "body 'b': mass = 1e+13 kg is outside the allowed range [0, 1e+12] kg",
    ),
    robot_case(  # Pinocchio's parser would take 1 kg m^2 about each axis, MuJoCo 0
        "MJCF inertial without inertia",
        "mjcf",
        mjcf_body('<inertial pos="0 0 0" mass="1"/>'),
        "SceneError",
        "body 'b': <inertial> gives neither diaginertia nor fullinertia",
    ),
    # the inertia Pinocchio's parser infers from geoms: a geom of negative density made a body of mass -48 kg
    robot_case(
        "MJCF geom density negative",
        "mjcf",
        mjcf_body('<geom type="box" size="0.1 0.2 0.3" density="-1000"/>'),
        "SceneError",
        "geom number 0 of body 'b': density -1000.0 kg/m^3 is negative",
    ),
    robot_case(
        "MJCF geom mass negative",
        "mjcf",
        mjcf_body('<geom name="g" type="box" size="0.1 0.2 0.3" mass="-2"/>'),
        "SceneError",
        "geom 'g': mass -2.0 kg is negative",
    ),
    robot_case(
        "MJCF geom size negative",
        "mjcf",
        mjcf_body('<geom type="box" size="-0.1 0.2 0.3"/>'),
        "SceneError",
        "geom number 0 of body 'b': size -0.1 m is negative",
    ),
    robot_case(
        "MJCF geom density from a default class",
        "mjcf",
        mjcf_body('<geom type="sphere" size="0.1"/>', before='<default><geom density="-1"/></default>'),
        "SceneError",
        "geom number 0 of body 'b': density -1.0 kg/m^3 is negative",
    ),
    robot_case(  # each value within range, their product not: 1e12 kg/m^3 x (2 x 100 m)^3 = 8e18 kg
        "MJCF inertia compiled from geoms beyond the ceiling",
        "mjcf",
        mjcf_body('<geom type="box" size="100 100 100" density="1e12"/>'),
        "SceneError",
        "the bodies on joint 'j' (as Pinocchio's MJCF parser compiled them): mass = 8e+18 kg is outside",
    ),
    # numbers Pinocchio's parser reads as memory it never wrote (pos="1 2": z = 2e243) or cuts (MuJoCo refuses both)
    robot_case(
        "MJCF body pos of 2 numbers",
        "mjcf",
        mjcf_body(INERTIAL).replace('<body name="b">', '<body name="b" pos="1 2">'),
        "SceneError",
        "robot.mjcf body 'b': pos='1 2' is not 3 finite numbers",
    ),
    robot_case(
        "MJCF inertial pos empty",
        "mjcf",
        mjcf_body('<inertial pos="" mass="1" diaginertia="1 1 1"/>'),
        "SceneError",
        "inertial number 0 of body 'b': pos='' is not 3 finite numbers",
    ),
    robot_case(
        "MJCF default joint axis of 4 numbers",
        "mjcf",
        mjcf_body(INERTIAL, before='<default><joint axis="0 0 1 0"/></default>'),
        "SceneError",
        "joint number 0 of default 'main': axis='0 0 1 0' is not 3 finite numbers",
    ),
    robot_case(
        "MJCF geom quat nan",
        "mjcf",
        mjcf_body(INERTIAL + '<geom name="g" type="sphere" size="0.1" quat="1 nan 0 0"/>'),
        "SceneError",
        "geom 'g': quat='1 nan 0 0' is not 4 finite numbers",
    ),
    robot_case(  # Pinocchio's parser ended in an IndexError (std::out_of_range), MuJoCo refuses it
        "MJCF class not defined",
        "mjcf",
        mjcf_body(INERTIAL).replace('type="slide"', 'type="slide" class="nowhere"'),
        "SceneError",
        "joint 'j': class='nowhere' is not a default class; classes: main",
    ),
    # the same mass refused by every reader, in the same words
    robot_case(
        "URDF mass -0.5", "urdf", urdf_tree(2, True, mass="-0.5"), "SceneError", "link 'l0': mass -0.5 kg is negative"
    ),
    robot_case(
        "SDF mass -0.5", "sdf", sdf_tree(2, True, mass="-0.5"), "SceneError", "link 'l0': mass -0.5 kg is negative"
    ),
    robot_case(
        "SDF mass beyond the ceiling",
        "sdf",
        sdf_tree(2, True, mass="1e13"),
        "SceneError",
        "sdf link 'l0': mass = 1e+13 kg is outside the allowed range [0, 1e+12] kg",
    ),
    # depth: RecursionError in the readers before, a crash in Pinocchio's parsers beyond about 3500
    robot_case(
        "SDF chain of 1200 links",
        "sdf",
        sdf_tree(1200, True),
        "SceneError",
        f"robot.sdf: the kinematic tree is 1200 joints deep, deeper than the limit of {MAX_TREE_DEPTH}",
    ),
    robot_case(
        "URDF chain deeper than the bound",
        "urdf",
        urdf_tree(MAX_TREE_DEPTH + 2, True),
        "SceneError",
        f"the kinematic tree is {MAX_TREE_DEPTH + 1} joints deep, deeper than the limit of {MAX_TREE_DEPTH}",
    ),
    robot_case(
        "MJCF of 1001 nested bodies",
        "mjcf",
        mjcf_nested(MAX_TREE_DEPTH + 1, joints=False),
        "SceneError",
        f"robot.mjcf: the kinematic tree is {MAX_TREE_DEPTH + 1} joints deep",
    ),
    robot_case(  # within the depth; the Data Pinocchio's MJCF parser builds (33 GB resident) is not
        "MJCF of 1000 nested bodies",
        "mjcf",
        mjcf_nested(1000),
        "MemoryBudgetError",
        "Pinocchio's MJCF parser on",
        argv="check {tmp}/s.toml --memory-limit 16GB",
    ),
    # size
    robot_case(
        "URDF of too many links",
        "urdf",
        urdf_tree(MAX_BODIES + 1, False),
        "SceneError",
        f"{MAX_BODIES + 1} links, more than the limit of {MAX_BODIES}",
    ),
    robot_case(
        "SDF of too many links",
        "sdf",
        sdf_tree(MAX_BODIES + 1, False),
        "SceneError",
        f"{MAX_BODIES + 1} links, more than the limit of {MAX_BODIES}",
    ),
    robot_case(
        "MJCF of too many bodies",
        "mjcf",
        mjcf_wide(MAX_BODIES + 1),
        "SceneError",
        f"robot.mjcf: {MAX_BODIES + 1} bodies, more than the limit of {MAX_BODIES}",
    ),
    robot_case(
        "URDF nested beyond the bound",
        "urdf",
        urdf_tree(1, True).replace("</link>", "<a>" * MAX_XML_NESTING + "</a>" * MAX_XML_NESTING + "</link>"),
        "SceneError",
        f"<a> is nested {MAX_XML_NESTING + 2} elements deep, deeper than the limit of {MAX_XML_NESTING}",
    ),
    robot_case(
        "MJCF nested beyond the bound besides its bodies",
        "mjcf",
        mjcf_body(INERTIAL + "<a>" * MAX_XML_NESTING + "</a>" * MAX_XML_NESTING),
        "SceneError",
        f"is nested {MAX_XML_NESTING + 2} elements deep besides the <body> elements",
    ),
    # copies: refused before the elements are copied (a copy of elements 200 000 deep crashed Python)
    Case(
        "copies of a URDF nested 200000 deep",
        "check {tmp}/s.toml",
        "SceneError",
        "robot.copies: the robot's URDF: <a> is nested 200002 elements deep",
        files=(
            ("s.toml", '[robot]\nurdf = "robot.urdf"\ncopies = [{ prefix = "a_" }]\n'),
            ("robot.urdf", urdf_tree(1, True).replace("</link>", "<a>" * 200000 + "</a>" * 200000 + "</link>")),
        ),
    ),
    Case(
        "copies of too many links",
        "check {tmp}/s.toml",
        "SceneError",
        f"robot.copies: {1 + 2 * 2100} links in 2 copies, more than the limit of {MAX_BODIES}",
        files=(
            ("s.toml", '[robot]\nurdf = "robot.urdf"\ncopies = [{ prefix = "a_" }, { prefix = "b_" }]\n'),
            ("robot.urdf", urdf_tree(2100, False)),
        ),
    ),
    # includes
    Case(
        "MJCF includes fanning out 10 per level",
        "check {tmp}/s.toml",
        "SceneError",
        f"more than {MAX_INCLUDED_FILES} files included into",
        files=(MJCF_SCENE, *fan_out(6)),
    ),
    Case(
        "MJCF includes nested beyond the bound",
        "check {tmp}/s.toml",
        "SceneError",
        f"<include file='inc{MAX_INCLUDE_DEPTH}.xml'>: includes nested more than {MAX_INCLUDE_DEPTH} deep",
        files=(MJCF_SCENE, *include_chain(MAX_INCLUDE_DEPTH + 1)),
    ),
    Case(
        "MJCF include cycle",
        "check {tmp}/s.toml",
        "SceneError",
        "inc1.xml: <include file='inc0.xml'>: the file includes itself (",
        files=(
            MJCF_SCENE,
            ("robot.mjcf", mjcf_body(INERTIAL, before='<include file="inc0.xml"/>')),
            ("inc0.xml", '<mujoco><include file="inc1.xml"/></mujoco>'),
            ("inc1.xml", '<mujoco><include file="inc0.xml"/></mujoco>'),
        ),
    ),
    Case(
        "MJCF include beyond the bytes",
        "check {tmp}/s.toml",
        "SceneError",
        f"more than the limit of {MAX_FILE_BYTES} bytes a robot's files may have together",
        files=(
            MJCF_SCENE,
            ("robot.mjcf", mjcf_body(INERTIAL, before='<include file="big.xml"/>')),
            ("big.xml", "<mujoco>" + " " * MAX_FILE_BYTES + "</mujoco>"),
        ),
    ),
    Case(
        "MJCF include missing",
        "check {tmp}/s.toml",
        "SceneError",
        "<include file='absent.xml'>: included file",
        files=(MJCF_SCENE, ("robot.mjcf", mjcf_body(INERTIAL, before='<include file="absent.xml"/>'))),
    ),
    Case(  # the error names the included file the body comes from
        "MJCF body of an included file with mass -1",
        "check {tmp}/s.toml",
        "SceneError",
        "part.xml body 'part': mass -1.0 kg is negative",
        files=(
            MJCF_SCENE,
            ("robot.mjcf", mjcf_body(INERTIAL + '<include file="part.xml"/>')),
            (
                "part.xml",
                '<mujoco><body name="part"><inertial pos="0 0 0" mass="-1" diaginertia="1 1 1"/></body></mujoco>',
            ),
        ),
    ),
]


def test_cases_are_distinct():
    assert len({case.name for case in CASES}) == len(CASES)


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_bad_robot_file_ends_in_its_named_error(case, tmp_path, capsys):
    start = time.perf_counter()
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (case.code, case.error), err
    assert case.phrase in err and "Traceback" not in err
    assert time.perf_counter() - start < 10.0


def test_mjcf_compiled_placements_are_checked_finite(tmp_path):
    """The last guard, after Pinocchio's parser: a placement it compiled to NaN (from any attribute it misreads)."""
    (tmp_path / "robot.mjcf").write_text(mjcf_body(INERTIAL))
    document = read_document(tmp_path / "robot.mjcf")
    model = read_robot({"mjcf": "robot.mjcf"}, tmp_path).model
    check_compiled(document, model)
    model.jointPlacements[1].translation = np.array([0.0, np.nan, 0.0])
    with pytest.raises(SceneError, match="the bodies on joint 'j' .*: a placement or centre of mass is not finite"):
        check_compiled(document, model)


# -- the largest models allowed load -------------------------------------------------------------
def _read(tmp_path, key: str, text: str):
    (tmp_path / f"robot.{key}").write_text(text)
    start = time.perf_counter()
    robot = read_robot({key: f"robot.{key}"}, tmp_path)
    assert time.perf_counter() - start < 10.0
    return robot


def test_urdf_chain_as_deep_as_the_bound_loads(tmp_path):
    model = _read(tmp_path, "urdf", urdf_tree(MAX_TREE_DEPTH + 1, True)).model
    assert model.njoints - 1 == MAX_TREE_DEPTH
    assert all(model.parents[joint] == joint - 1 for joint in range(1, model.njoints))


def test_sdf_chain_as_deep_as_the_bound_loads(tmp_path):
    robot = _read(tmp_path, "sdf", sdf_tree(MAX_TREE_DEPTH, True))
    assert robot.model.njoints - 1 == MAX_TREE_DEPTH  # the first link on the world, each on the one before
    assert all(robot.model.parents[joint] == joint - 1 for joint in range(1, robot.model.njoints))
    assert [robot.model.names[joint] for joint in (1, MAX_TREE_DEPTH)] == ["j0", f"j{MAX_TREE_DEPTH - 1}"]


def test_mjcf_bodies_nested_as_deep_as_the_bound_load(tmp_path):
    model = _read(tmp_path, "mjcf", mjcf_nested(MAX_TREE_DEPTH, joints=False)).model
    assert model.existFrame(f"b{MAX_TREE_DEPTH - 1}")
    assert model.inertias[0].mass == pytest.approx(MAX_TREE_DEPTH)  # every body fixed to the world, 1 kg each


@pytest.mark.parametrize(
    ("key", "text"),
    [("urdf", urdf_tree(MAX_BODIES, False)), ("sdf", sdf_tree(MAX_BODIES, False)), ("mjcf", mjcf_wide(MAX_BODIES))],
)
def test_robot_of_the_most_bodies_allowed_loads(tmp_path, key, text):
    model = _read(tmp_path, key, text).model
    masses = sum(inertia.mass for inertia in model.inertias)
    assert masses == pytest.approx(MAX_BODIES)  # 1 kg each


def test_mjcf_parser_memory_within_the_budget_loads(tmp_path):
    """Thirty joints (the Data of Pinocchio's MJCF parser: kilobytes) pass the same check as the refused 1000."""
    assert _read(tmp_path, "mjcf", mjcf_nested(30)).model.nv == 30


# -- includes ----------------------------------------------------------------------------------
def test_included_bodies_and_assets_reach_pinocchio_as_mujoco_reads_them(tmp_path):
    """Pinocchio's MJCF parser ignores <include>: it is given the document with its includes inlined. Included
    files' own includes are relative to the model's folder, as MuJoCo reads them."""
    mujoco = pytest.importorskip("mujoco")
    (tmp_path / "parts").mkdir()
    (tmp_path / "robot.mjcf").write_text(mjcf_body(INERTIAL + '<include file="parts/arm.xml"/>'))
    arm = '<body name="arm" pos="0 0 0.5"><joint name="ja" axis="0 1 0"/>{}<include file="hand.xml"/></body>'
    (tmp_path / "parts" / "arm.xml").write_text(f"<mujoco>{arm.format(INERTIAL)}</mujoco>")
    hand = '<body name="hand" pos="0.3 0 0"><joint name="jh" axis="1 0 0"/><geom type="box" size="0.1 0.2 0.3"/></body>'
    (tmp_path / "hand.xml").write_text(f"<mujoco>{hand}</mujoco>")
    model = read_robot({"mjcf": "robot.mjcf"}, tmp_path).model
    reference = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.mjcf"))
    assert [model.names[j] for j in range(1, model.njoints)] == ["j", "ja", "jh"]
    for body in ("b", "arm", "hand"):
        joint = model.frames[model.getFrameId(body)].parentJoint
        assert model.inertias[joint].mass == pytest.approx(reference.body(body).mass[0], rel=1e-12)
    assert model.inertias[3].mass == pytest.approx(1000 * 0.2 * 0.4 * 0.6)  # the hand's box of water


def test_included_mesh_is_found_from_the_models_folder(tmp_path):
    """An included <asset> names a mesh in the model's meshdir: the geometry finds it there."""
    pin = pytest.importorskip("pinocchio")
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "cube.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    )
    (tmp_path / "robot.mjcf").write_text(
        mjcf_body(INERTIAL + '<geom type="mesh" mesh="cube"/>', ' meshdir="assets"', '<include file="asset.xml"/>')
    )
    (tmp_path / "asset.xml").write_text('<mujoco><asset><mesh name="cube" file="cube.obj"/></asset></mujoco>')
    robot = read_robot({"mjcf": "robot.mjcf"}, tmp_path)
    geometry = robot.geometry(robot.model, pin.GeometryType.VISUAL, robot.package_dirs)
    assert [item.meshPath for item in geometry.geometryObjects] == [str(tmp_path / "assets" / "cube.obj")]


def test_includes_as_many_and_as_deep_as_the_bounds_load(tmp_path):
    for name, text in include_chain(MAX_INCLUDE_DEPTH):
        (tmp_path / name).write_text(text)
    assert read_robot({"mjcf": "robot.mjcf"}, tmp_path).model.nv == 1
    wide = "".join('<include file="empty.xml"/>' for _ in range(MAX_INCLUDED_FILES))
    (tmp_path / "empty.xml").write_text("<mujoco><default/></mujoco>")
    (tmp_path / "wide.mjcf").write_text(mjcf_body(INERTIAL, before=wide))
    assert read_robot({"mjcf": "wide.mjcf"}, tmp_path).model.nv == 1
    (tmp_path / "wider.mjcf").write_text(mjcf_body(INERTIAL, before=wide + '<include file="empty.xml"/>'))
    with pytest.raises(SceneError, match=f"more than {MAX_INCLUDED_FILES} files included into"):
        read_robot({"mjcf": "wider.mjcf"}, tmp_path)


def test_robot_files_of_the_most_bytes_allowed_load(tmp_path):
    """The model's file and its include together: exactly MAX_FILE_BYTES load, one byte more is refused."""
    main = mjcf_body(INERTIAL, before='<include file="big.xml"/>').encode()
    (tmp_path / "robot.mjcf").write_bytes(main)
    padding = MAX_FILE_BYTES - len(main) - len(b"<mujoco></mujoco>")
    (tmp_path / "big.xml").write_bytes(b"<mujoco>" + b" " * padding + b"</mujoco>")
    assert read_robot({"mjcf": "robot.mjcf"}, tmp_path).model.nv == 1
    (tmp_path / "big.xml").write_bytes(b"<mujoco>" + b" " * (padding + 1) + b"</mujoco>")
    with pytest.raises(SceneError, match=f"big.xml has {padding + 18} bytes \\(after {len(main)} bytes"):
        read_robot({"mjcf": "robot.mjcf"}, tmp_path)


# -- the depth of a tree -------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("parents", "depth"),
    [
        ({}, 0),
        ({"b": "a"}, 1),
        ({"d": "c", "c": "b", "b": "a", "e": "a"}, 3),  # the longest of two branches
        ({"b": "a", "c": "a", "d": "a"}, 1),
        ({"a": "b", "b": "a", "c": "a"}, 3),  # a cycle counts its joints once
    ],
)
def test_tree_depth_counts_the_joints_of_the_longest_path(parents, depth):
    assert tree_depth(parents) == depth


def test_tree_depth_of_a_long_chain_without_recursion():
    links = 200_000
    assert tree_depth({f"l{k}": f"l{k - 1}" for k in range(1, links)}) == links - 1
    assert tree_depth({f"l{k}": "l0" for k in range(1, links)}) == 1

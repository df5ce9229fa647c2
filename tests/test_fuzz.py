"""Property-based fuzzing (issue 13, item 2): scene files and user constraint callables.

The property, for everything a user can hand to pinstab: the outcome is a success or a
:class:`~pinstab.errors.PinstabError` with a non-empty message, never another exception and never a
non-finite result returned silently.

* Scene files: the bundled scenes (``robots/*.toml``) mutated (a key deleted, inserted or emptied, a value
  replaced by one of another type, a huge, negative or non-finite number, a string with a wrong unit, a
  name swapped for another scene's frame or joint, an array entry duplicated, a value nested deeply), small
  documents generated from scratch, and TOML text with bytes inserted or removed. Each goes through
  :func:`~pinstab.scene.scene_from_dict`, the file through ``pinstab check FILE --json`` in process, and a
  scene that loads through a few simulated steps.
* User constraints (:class:`~pinstab.HolonomicConstraint`, :class:`~pinstab.PfaffianConstraint`) on the
  point-mass pendulum: callables that return wrong shapes, wrong dtypes, non-finite values, lists, None or
  scalars, or raise, possibly only after some good calls; wrong ``rows`` / ``nv`` declarations. A callable
  that raises must become a :class:`~pinstab.errors.ConstraintError` naming the constraint and the callable,
  the original exception chained as its cause.

The number of examples comes from the Hypothesis profile (tests/conftest.py, ``HYPOTHESIS_PROFILE``).
"""

from __future__ import annotations

import copy
import datetime
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fuzzing import assert_error, check_file, toml_document
from hypothesis import given
from hypothesis import strategies as st

from conftest import DATA, ROBOTS
from pinstab import AssemblyError, HolonomicConstraint, PfaffianConstraint, assemble, simulate
from pinstab.actuation import ACTUATION_KEYS
from pinstab.constraints import CONSTRAINT_KINDS
from pinstab.contact.objects import OBJECT_KEYS
from pinstab.errors import ConstraintError, PinstabError, SceneError
from pinstab.forces import FORCE_KINDS
from pinstab.model import ConstrainedModel
from pinstab.scene import INITIAL_KEYS, ROBOT_KEYS, TOP_KEYS, Scene, load_scene, scene_from_dict
from pinstab.units import UNITS

DT = 1e-3
SCENE_FILES = sorted(ROBOTS.glob("*.toml"))
SCENES: dict[str, dict[str, Any]] = {path.stem: tomllib.loads(path.read_text()) for path in SCENE_FILES}
TEXTS: dict[str, str] = {path.stem: path.read_text() for path in SCENE_FILES}


# -- what the fuzzer draws from ------------------------------------------------------------------------
def _walk(node: Any) -> list[Any]:
    """Every value below ``node`` (and the keys of its tables), depth first."""
    found: list[Any] = []
    stack = [node]
    while stack:
        value = stack.pop()
        found.append(value)
        if isinstance(value, dict):
            found += list(value)
            stack += list(value.values())
        elif isinstance(value, list):
            stack += value
    return found


def _scene_keys() -> list[str]:
    keys = {key for data in SCENES.values() for value in _walk(data) if isinstance(value, dict) for key in value}
    return sorted(keys | TOP_KEYS | ROBOT_KEYS | INITIAL_KEYS | OBJECT_KEYS | ACTUATION_KEYS | {"link_length"})


KEYS = _scene_keys()
# frame, joint, object, kind and other names of every scene, so that a name can move to where it is wrong
NAMES = sorted(
    {value for data in SCENES.values() for value in _walk(data) if isinstance(value, str) and len(value) < 60}
    | set(CONSTRAINT_KINDS)
    | set(FORCE_KINDS)
    | {"world", "universe", "", "root_joint"}
)
UNIT_NAMES = sorted({unit for units in UNITS.values() for unit in units} | {"", "furlong", "M", "DEG", "m/s^3"})
SPECIAL_VALUES: list[Any] = [
    0,
    -1,
    1,
    3,
    2**63 - 1,
    -(2**63),
    1e308,
    -1e308,
    5e-324,
    -0.0,
    True,
    False,
    "",
    " ",
    "nan m",
    "inf deg",
    "-inf N",
    "1e999 mm",
    "1 m m",
    "m 1",
    "0x10 m",
    "1_000 m",
    "\u0663 m",
    "1,5 m",
    "NaN",
    "abc",
    "\u00fcn\u00efc\u00f6d\u00e9 \u2713",
    "\x00",
    "-1 kg",
    "0 kg",
    "1e-300 m",
    "30 deg",
    "15 mm",
    datetime.date(2000, 1, 1),
    datetime.time(12, 30),
    [],
    {},
    [[]],
    [{}],
    {"": {}},
    [0.0, 0.0],
    [1.0, 2.0, 3.0],
    [1.0, "x", 3.0],
    [math.nan, 0.0, 0.0],
]
scalars = st.one_of(
    st.sampled_from(SPECIAL_VALUES),
    st.sampled_from(NAMES),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(),
    st.text(max_size=8),
    st.builds(lambda x, unit: f"{x:g} {unit}", st.floats(), st.sampled_from(UNIT_NAMES)),
)
values = st.recursive(
    scalars,
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=6), children, max_size=3)
    ),
    max_leaves=8,
)


def _paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    """The paths (keys and indices) of every value below ``node``."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    found = []
    for key, child in items:
        found.append((*prefix, key))
        found += _paths(child, (*prefix, key))
    return found


def _at(root: Any, path: tuple) -> Any:
    for key in path:
        root = root[key]
    return root


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


Draw = Callable[[st.SearchStrategy], Any]


def _pick(draw: Draw, data: dict, wanted: Callable[[Any], bool]) -> tuple | None:
    """A path to a value for which ``wanted`` holds (None when there is none)."""
    paths = [path for path in _paths(data) if wanted(_at(data, path))]
    return draw(st.sampled_from(paths)) if paths else None


def _delete(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: True)
    if path is not None:
        del _at(data, path[:-1])[path[-1]]


def _replace(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: True)
    if path is not None:
        _at(data, path[:-1])[path[-1]] = copy.deepcopy(draw(values))  # a drawn table may be mutated later


def _insert(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: isinstance(value, dict))
    target = data if path is None or draw(st.booleans()) else _at(data, path)
    target[draw(st.sampled_from(KEYS) | st.text(max_size=6))] = copy.deepcopy(draw(values))


def _rename(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: isinstance(value, str))
    if path is not None:
        _at(data, path[:-1])[path[-1]] = draw(st.sampled_from(NAMES))


def _empty(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: isinstance(value, (dict, list)))
    if path is not None:
        _at(data, path[:-1])[path[-1]] = type(_at(data, path))()


def _duplicate(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: isinstance(value, list) and len(value) > 0)
    if path is not None:
        array = _at(data, path)
        array.insert(draw(st.integers(0, len(array))), copy.deepcopy(draw(st.sampled_from(array))))


def _nest(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, lambda value: True)
    if path is not None:
        value = _at(data, path)
        for _ in range(draw(st.integers(1, 30))):
            value = [value] if draw(st.booleans()) else {"x": value}
        _at(data, path[:-1])[path[-1]] = value


def _unit(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, _is_number)
    if path is not None:
        _at(data, path[:-1])[path[-1]] = f"{_at(data, path)} {draw(st.sampled_from(UNIT_NAMES))}"


def _scale(draw: Draw, data: dict) -> None:
    path = _pick(draw, data, _is_number)
    if path is not None:
        factor = draw(st.sampled_from([-1.0, 0.0, 1e-12, 1e6, 1e300, math.nan, math.inf, -math.inf]))
        _at(data, path[:-1])[path[-1]] = _at(data, path) * factor


MUTATIONS = (_delete, _replace, _insert, _rename, _empty, _duplicate, _nest, _unit, _scale)


@st.composite
def mutated_scenes(draw: Draw) -> dict[str, Any]:
    """A bundled scene's content with one to three mutations."""
    data = copy.deepcopy(SCENES[draw(st.sampled_from(sorted(SCENES)))])
    for _ in range(draw(st.integers(1, 3))):
        draw(st.sampled_from(MUTATIONS))(draw, data)
    return data


URDFS = sorted(str(path.relative_to(ROBOTS)) for path in (ROBOTS / "urdf").glob("*.urdf"))
ENTRY = st.dictionaries(
    st.sampled_from(["name", "kind", "frame", "frame_a", "frame_b", "joint", "object", "offset_a", "mu", "radius"]),
    st.sampled_from(NAMES) | values,
    max_size=5,
)
small_scenes = st.fixed_dictionaries(
    {"robot": st.fixed_dictionaries({"urdf": st.sampled_from(URDFS)}, optional={"free_flyer": st.booleans()})},
    optional={
        "gravity": values,
        "closures": st.lists(ENTRY, max_size=2),
        "contacts": st.lists(ENTRY, max_size=2),
        "forces": st.lists(ENTRY, max_size=2),
        "objects": st.lists(ENTRY, max_size=1),
        "actuation": values,
        "initial": st.dictionaries(st.sampled_from(["q", "v"]), st.dictionaries(st.sampled_from(NAMES), values)),
        "generator": st.dictionaries(st.sampled_from(["name", "N", "link_length", "link_mass"]), values),
    },
)


# -- running a scene the way a user does ---------------------------------------------------------------
@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder for written scene files, its ``urdf`` folder the bundled one (relative paths resolve)."""
    folder = tmp_path_factory.mktemp("fuzz")
    (folder / "urdf").symlink_to(ROBOTS / "urdf", target_is_directory=True)
    return folder


def run_briefly(scene: Scene) -> None:
    """A few steps: a finite trajectory or a PinstabError."""
    try:
        trajectory = simulate(scene, dt=DT, duration=5 * DT)
    except PinstabError as exc:
        assert_error(exc)
    else:
        assert np.all(np.isfinite(trajectory.q)) and np.all(np.isfinite(trajectory.v))


def exercise_scene(data: dict[str, Any], folder: Path, steps: bool = True) -> Scene | None:
    """Load ``data`` in process, then as a file through ``load_scene`` and ``pinstab check``; simulate a
    scene that loads. Returns the scene from ``data`` (None when it is refused)."""
    try:
        scene = scene_from_dict(data, name="fuzz", base_dir=ROBOTS)
    except PinstabError as exc:
        assert_error(exc)
        scene = None
    path = folder / "fuzz.toml"
    path.write_text(toml_document(data), encoding="utf-8")
    try:
        load_scene(path)
    except PinstabError as exc:
        assert_error(exc)
    check_file(path)
    if scene is not None and steps:
        run_briefly(scene)
    return scene


# -- scene files -------------------------------------------------------------------------------------
@given(data=mutated_scenes())
def test_mutated_bundled_scenes_load_or_refuse(data: dict[str, Any], scene_dir: Path) -> None:
    exercise_scene(data, scene_dir)


@given(data=small_scenes)
def test_generated_scenes_load_or_refuse(data: dict[str, Any], scene_dir: Path) -> None:
    exercise_scene(data, scene_dir)


@given(
    name=st.sampled_from(sorted(TEXTS)),
    edits=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 8), st.text(max_size=4)), min_size=1, max_size=3),
)
def test_edited_scene_text_loads_or_refuses(name: str, edits: list[tuple[float, int, str]], scene_dir: Path) -> None:
    """Characters cut from and typed into a bundled scene file."""
    text = TEXTS[name]
    for where, cut, typed in edits:
        at = int(where * len(text))
        text = text[:at] + typed + text[at + cut :]
    path = scene_dir / "edited.toml"
    path.write_text(text, encoding="utf-8")
    try:
        load_scene(path)
    except PinstabError as exc:
        assert_error(exc)
    check_file(path)


def test_toml_writer_round_trips_every_bundled_scene() -> None:
    for name, data in SCENES.items():
        assert tomllib.loads(toml_document(data)) == data, name


# -- user constraint callables -----------------------------------------------------------------------
LENGTH = 0.8
START = {"q": {"x": LENGTH * math.sin(0.9), "y": -LENGTH * math.cos(0.9)}, "v": {"x": 0.5}}
GOOD_HOLONOMIC: dict[str, Callable[..., Any]] = {
    "residual": lambda q, t: np.array([q[0] ** 2 + q[1] ** 2 - LENGTH**2]),
    "jacobian": lambda q, t: np.array([[2 * q[0], 2 * q[1]]]),
    "drift": lambda q, v, t: np.array([2 * (v[0] ** 2 + v[1] ** 2)]),
    "time_derivative": lambda q, t: np.zeros(1),
}
# the rod at velocity level: d/dt (x^2 + y^2) = 2 x vx + 2 y vy = 0
GOOD_PFAFFIAN: dict[str, Callable[..., Any]] = {
    "matrix": GOOD_HOLONOMIC["jacobian"],
    "drift": GOOD_HOLONOMIC["drift"],
    "bias": GOOD_HOLONOMIC["time_derivative"],
}
EXCEPTIONS = (
    ZeroDivisionError,
    KeyError,
    IndexError,
    ValueError,
    TypeError,
    AttributeError,
    RuntimeError,
    AssertionError,
    FloatingPointError,
    RecursionError,
    NotImplementedError,
    np.linalg.LinAlgError,
    StopIteration,
    ConstraintError,
)


class BadArray:
    """An object that numpy asks for its array, and that fails to give it."""

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        raise ZeroDivisionError("no array here")


class BadFloat:
    """An object that fails to become a float."""

    def __float__(self) -> float:
        raise OverflowError("no float here")


def _shaped(shape: tuple[int, ...], fill: float) -> np.ndarray:
    return np.full(shape, fill)


bad_returns = st.one_of(
    st.sampled_from(
        [
            None,
            0,
            0.5,
            math.nan,
            math.inf,
            "abc",
            "1.0",
            b"1",
            [],
            [1.0],
            [[1.0, 2.0]],
            [[1.0, 2.0], [3.0]],
            [None],
            ["1.0"],
            [10**400],
            {"a": 1},
            (1.0,),
            1j,
            np.array([1j]),
            np.array([[1j, 0.0]]),
            np.array(["1.0"]),
            np.array([True]),
            np.array([[1, 2]]),
            np.array([1.0], dtype=np.float16),
            np.array([1.0], dtype=object),
            np.float64(0.5),
            np.array(0.5),
            np.ma.masked_array([1.0], mask=[True]),
            BadArray(),
            [BadFloat()],
            np.zeros((1, 2, 1)),
            np.zeros((2, 1)),
            np.zeros((1, 3)),
            np.zeros(0),
        ]
    ),
    st.builds(
        _shaped,
        st.lists(st.integers(0, 3), max_size=3).map(tuple),
        st.sampled_from([0.0, 1.0, -1e300, 1e308, math.nan, math.inf, -math.inf]),
    ),
)


@dataclass
class Misbehaviour:
    """What a user callable does wrong, after ``good_calls`` right answers: return ``value``, or raise
    ``raises`` when it is set."""

    good_calls: int
    value: Any
    raises: type[Exception] | None
    raised: Exception | None = None

    def wrap(self, good: Callable[..., Any]) -> Callable[..., Any]:
        """``good`` until it has answered ``good_calls`` times, then the misbehaviour (the exception raised
        is kept in ``raised``)."""
        calls = [0]

        def callable_(*args: Any) -> Any:
            calls[0] += 1
            if calls[0] <= self.good_calls:
                return good(*args)
            if self.raises is not None:
                self.raised = self.raises("fuzzed failure")
                raise self.raised
            return self.value

        return callable_


misbehaviours = st.builds(
    Misbehaviour,
    st.sampled_from([0, 1, 3, 20]),
    bad_returns,
    st.none() | st.sampled_from(EXCEPTIONS),
)


def point_mass() -> Scene:
    """The point mass of tests/data/point_mass.urdf at the rod's length from the origin, no constraint."""
    data = {"robot": {"urdf": str(DATA / "point_mass.urdf")}, "gravity": [0.0, -9.81, 0.0], "initial": START}
    return scene_from_dict(data, name="pendulum")


def check_user_constraint(
    constraint: HolonomicConstraint | PfaffianConstraint, method: str, wrong: str, misbehaviour: Misbehaviour | None
) -> None:
    """Simulate the point mass with ``constraint`` (whose callable ``wrong`` misbehaves): a finite trajectory
    or a PinstabError; a raising callable is a ConstraintError naming the constraint and the callable, its
    exception chained."""
    scene = point_mass()
    try:
        scene.add_constraint(constraint)
        trajectory = simulate(scene, method=method, dt=DT, duration=5 * DT)
    except PinstabError as exc:
        assert_error(exc)
        raised = None if misbehaviour is None else misbehaviour.raised
        if raised is not None:
            assert isinstance(exc, ConstraintError) and exc.__cause__ is raised, repr(exc)
            assert f"constraint {constraint.name!r}" in str(exc) and f"{wrong}()" in str(exc), str(exc)
    else:
        assert misbehaviour is None or misbehaviour.raised is None, "a raising callable went unnoticed"
        assert np.all(np.isfinite(trajectory.q)) and np.all(np.isfinite(trajectory.v))


USER_CONSTRAINTS = {  # kind -> (constructor from callables, well-behaved callables)
    "holonomic": (lambda callables: HolonomicConstraint("rod", 1, nv=2, **callables), GOOD_HOLONOMIC),
    "pfaffian": (lambda callables: PfaffianConstraint("rolling", 1, nv=2, **callables), GOOD_PFAFFIAN),
}


@pytest.mark.parametrize("kind", sorted(USER_CONSTRAINTS))
@given(data=st.data(), misbehaviour=misbehaviours, method=st.sampled_from(["baumgarte", "projection", "none"]))
def test_misbehaving_user_callables(kind: str, data: st.DataObject, misbehaviour: Misbehaviour, method: str) -> None:
    make, good = USER_CONSTRAINTS[kind]
    wrong = data.draw(st.sampled_from(sorted(good)), label="wrong")
    callables = dict(good)
    callables[wrong] = misbehaviour.wrap(callables[wrong])
    check_user_constraint(make(callables), method, wrong, misbehaviour)


declarations = st.one_of(st.integers(-2, 4), st.sampled_from([1.0, 1.5, "1", "one", None, True, math.nan, [1]]))


@given(
    rows=declarations,
    nv=declarations,
    name=st.sampled_from(["rod", "", None, 3]),
    holonomic=st.booleans(),
    residual=st.sampled_from([GOOD_HOLONOMIC["residual"], None, 1.0, "residual"]),
)
def test_user_constraint_declarations(rows: Any, nv: Any, name: Any, holonomic: bool, residual: Any) -> None:
    """Rows, nv and name declared wrong, a callable that is not one: refused or simulated."""
    try:
        if holonomic:
            constraint = HolonomicConstraint(
                name, rows, residual, GOOD_HOLONOMIC["jacobian"], GOOD_HOLONOMIC["drift"], nv
            )
        else:
            constraint = PfaffianConstraint(name, rows, GOOD_PFAFFIAN["matrix"], GOOD_PFAFFIAN["drift"], nv)
    except PinstabError as exc:
        assert_error(exc)
        return
    check_user_constraint(constraint, "baumgarte", "", None)


# -- regressions: the bugs the fuzzer found, each with its error and a phrase of its message ---------------
def _point_mass_with(constraint: HolonomicConstraint | PfaffianConstraint) -> Scene:
    scene = point_mass()
    scene.add_constraint(constraint)
    return scene


def _raising(q: np.ndarray, t: float) -> np.ndarray:
    return np.array([1.0 / 0.0])


def test_raising_user_callable_is_a_constraint_error_naming_it() -> None:
    """Was: the callable's ZeroDivisionError escaped from the step."""
    callables = dict(GOOD_HOLONOMIC, jacobian=_raising)
    with pytest.raises(ConstraintError, match=r"constraint 'rod': the user callable jacobian\(\) raised ZeroDivision"):
        simulate(_point_mass_with(HolonomicConstraint("rod", 1, nv=2, **callables)), dt=DT, duration=5 * DT)
    with pytest.raises(ConstraintError) as caught:
        simulate(_point_mass_with(HolonomicConstraint("rod", 1, nv=2, **callables)), dt=DT, duration=5 * DT)
    assert isinstance(caught.value.__cause__, ZeroDivisionError)


@pytest.mark.parametrize(
    ("value", "phrase"),
    [
        (np.array([[1j, 0.0]]), "dtype complex128, not an array of real numbers"),  # was: imaginary part dropped
        (np.array([["1.0", "2.0"]]), "not an array of real numbers"),  # was: strings read as numbers
        ([[None, 1.0]], "not an array of real numbers"),  # was: TypeError
        (BadArray(), "BadArray, not an array of real numbers"),  # was: the object's ZeroDivisionError
        ([[BadFloat(), 1.0]], "not an array of real numbers"),  # was: OverflowError
    ],
)
def test_user_callable_returning_no_real_array_is_refused(value: Any, phrase: str) -> None:
    constraint = PfaffianConstraint("rolling", 1, lambda q, t: value, GOOD_PFAFFIAN["drift"], nv=2)
    with pytest.raises(ConstraintError, match=phrase):
        simulate(_point_mass_with(constraint), dt=DT, duration=5 * DT)


@pytest.mark.parametrize(
    ("arguments", "phrase"),
    [
        (dict(rows="one"), "rows must be a whole number >= 1, got 'one'"),  # was: ValueError from int()
        (dict(rows=None), "rows must be a whole number >= 1, got None"),  # was: TypeError from int()
        (dict(rows=-1), "rows must be a whole number >= 1"),  # was: ValueError, negative dimensions
        (dict(rows=1.5), "rows must be a whole number >= 1"),  # was: read as 1
        (dict(nv=[2]), "nv must be a whole number >= 1"),  # was: TypeError from int()
        (dict(residual="residual"), "residual must be a callable, got str"),  # was: TypeError at the first step
        (dict(drift=None), "drift must be a callable, got NoneType"),
        (dict(name=""), "name must be a non-empty string"),
    ],
)
def test_user_constraint_declared_wrong_is_refused(arguments: dict[str, Any], phrase: str) -> None:
    declared = dict(name="rod", rows=1, nv=2, **GOOD_HOLONOMIC) | arguments
    with pytest.raises(ConstraintError, match=phrase):
        HolonomicConstraint(**declared)


def test_user_constraint_for_another_nv_is_refused() -> None:
    """Was: ValueError broadcasting its (1, 3) Jacobian into the model's 2 columns."""
    callables = dict(GOOD_HOLONOMIC, jacobian=lambda q, t: np.zeros((1, 3)))
    scene = _point_mass_with(HolonomicConstraint("rod", 1, nv=3, **callables))
    with pytest.raises(ConstraintError, match="'rod' is declared for nv = 3, but the model has nv = 2"):
        simulate(scene, dt=DT, duration=5 * DT)


def test_projection_of_a_huge_residual_is_a_pinstab_error() -> None:
    """A residual of -1e300 under ``projection``: Gauss-Newton's least squares does not converge (was a
    LinAlgError)."""
    callables = dict(GOOD_HOLONOMIC, residual=lambda q, t: np.array([-1e300]))
    scene = _point_mass_with(HolonomicConstraint("rod", 1, nv=2, **callables))
    with pytest.raises(PinstabError, match="projection failed: the constraint rows are not finite"):
        simulate(scene, method="projection", dt=DT, duration=5 * DT, assemble_initial=False)


def _changed(name: str, path: tuple, value: Any) -> dict[str, Any]:
    """Bundled scene ``name`` with the value at ``path`` replaced."""
    data = copy.deepcopy(SCENES[name])
    _at(data, path[:-1])[path[-1]] = value
    return data


@pytest.mark.parametrize(
    ("name", "path", "value", "phrase"),
    [
        # was: TypeError, unhashable type, in a dictionary lookup
        ("allegro-lift", ("contacts", 0, "object"), {}, "contact 'index'.object: {} is not an object of the scene"),
        ("allegro-sphere", ("forces", 0, "object"), ["ball"], "force 'hold'.object: ['ball'] is not an object"),
        ("allegro-sphere", ("forces", 0, "contacts"), [{}], "force 'hold'.contacts: {} is not a grasp contact"),
        ("allegro-sphere", ("contacts", 0, "model"), [], "contact 'index': unknown contact model []"),
        # was: no end (a URDF of 2 * 10**7 + 1 links, a cone of 10**9 facets)
        ("nfourbar", ("generator", "N"), 10**7, "parameter N must be at most 1000"),
        ("box-push", ("contacts", 0, "facets"), 10**9, "needs at least 3 facets (at most 1000), got 1000000000"),
        ("allegro-lift", ("forces", 0, "facets"), 10**9, "facets must be a whole number >= 3 (at most 1000)"),
        # was: RuntimeError from Pinocchio, "The 3d inertia should be symmetric"
        ("allegro-box", ("objects", 0, "size"), [1e300, 1e300, 1e300], "object 'box'.size = 1e+300 m is outside"),
    ],
)
def test_scene_values_that_crashed_are_refused(name: str, path: tuple, value: Any, phrase: str) -> None:
    with pytest.raises(SceneError) as caught:
        scene_from_dict(_changed(name, path, value), name="fuzz", base_dir=ROBOTS)
    assert phrase in str(caught.value)


@pytest.mark.parametrize(
    ("data", "error", "phrase"),
    [
        # was: LinAlgError "Singular matrix" inverting the mass matrix (a massless free-flyer root)
        (
            {"robot": {"urdf": "urdf/appell-plate.urdf", "free_flyer": True}},
            SceneError,
            "mass matrix is singular at the assembled configuration (smallest eigenvalue",
        ),
        # was: LinAlgError "SVD did not converge" projecting the initial velocity; now refused at load (beyond the
        # scene's reach)
        (_changed("fourbar", ("closures", 0, "offset_a"), [1e308, 0, 0]), SceneError, "lies 1e+308 m from its frame"),
        # was: a NaN velocity residual, printed as null by ``pinstab check --json``; now refused at load
        (_changed("fourbar", ("initial", "v", "crank"), 1e308), SceneError, "initial.v.crank: 1e+308 is outside"),
    ],
)
def test_assembly_failures_that_crashed_are_pinstab_errors(data: dict[str, Any], error: type, phrase: str) -> None:
    with pytest.raises(error) as caught:
        scene = scene_from_dict(data, name="fuzz", base_dir=ROBOTS)
        assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    assert phrase in str(caught.value)


def test_assembly_of_a_non_finite_velocity_is_an_assembly_error() -> None:
    """The guard behind the scene's ranges: a velocity no scene can give (the API's assemble takes any)."""
    scene = scene_from_dict(_changed("fourbar", ("initial", "v", "crank"), 1.0), name="fuzz", base_dir=ROBOTS)
    with pytest.raises(AssemblyError, match="constraint 'coupler-rocker'"):
        assemble(ConstrainedModel(scene), scene.q0, np.full_like(scene.v0, 1e308))

"""The layers as import-linter contracts, import cycles, and registries that take extensions from
outside the package (a stabilizer registered here reaches simulate(), the CLI and the stability map)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_hold():
    """``lint-imports`` with the contracts in pyproject.toml: the layers from the CLI down to errors,
    the core never importing the CLI, the viewer or the benchmarks, acyclic siblings."""
    command = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or shutil.which("lint-imports")
    assert command, "import-linter is not installed (pip install -e '.[test]')"
    result = subprocess.run([command, "--no-cache"], cwd=ROOT, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "3 kept, 0 broken" in result.stdout


def strongly_connected(graph: grimp.ImportGraph) -> list[set[str]]:
    """Tarjan's strongly connected components of the module graph with more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []
    counter = [0]

    def visit(module: str) -> None:
        index[module] = low[module] = counter[0]
        counter[0] += 1
        stack.append(module)
        on_stack.add(module)
        for imported in graph.find_modules_directly_imported_by(module):
            if imported not in index:
                visit(imported)
                low[module] = min(low[module], low[imported])
            elif imported in on_stack:
                low[module] = min(low[module], index[imported])
        if low[module] == index[module]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == module:
                    break
            if len(component) > 1:
                found.append(component)

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for module in sorted(graph.modules):
        if module not in index:
            visit(module)
    return found


def test_no_import_cycle_among_pinstab_modules():
    """Every module of the package, TYPE_CHECKING imports included: no strongly connected component."""
    graph = grimp.build_graph("pinstab", cache_dir=None)
    assert len(graph.modules) > 40
    assert strongly_connected(graph) == []


def test_cycle_finder_finds_a_cycle():
    """The check above can fail: a graph with a cycle a -> b -> c -> a is reported."""
    graph = grimp.ImportGraph()
    for name in ("a", "b", "c", "d"):
        graph.add_module(name)
    graph.add_import(importer="a", imported="b")
    graph.add_import(importer="b", imported="c")
    graph.add_import(importer="c", imported="a")
    graph.add_import(importer="c", imported="d")
    assert strongly_connected(graph) == [{"a", "b", "c"}]


INITIAL = {"q": {"x": 1.2, "y": -0.9}, "v": {"x": 0.3}}


def readme_example() -> str:
    """The Python block after the ``extending-example`` marker in docs/guide/extending.md."""
    text = (ROOT / "docs" / "guide" / "extending.md").read_text()
    after = text.split("<!-- extending-example -->", 1)[1]
    return after.split("```python\n", 1)[1].split("```", 1)[0]


@pytest.fixture
def spring_method():
    """The documentation's extension, registered for one test and removed after it."""
    from pinstab.stabilizers import STABILIZERS

    namespace: dict = {}
    exec(compile(readme_example(), "docs/guide/extending.md", "exec"), namespace)  # noqa: S102 (the docs' own code)
    try:
        yield namespace
    finally:
        STABILIZERS.unregister("spring")


def test_a_stabilizer_registered_outside_the_package_reaches_simulate_the_cli_and_the_map(spring_method, capsys):
    import numpy as np

    from pinstab import load_scene, simulate
    from pinstab.analysis.stability_map import stability_map
    from pinstab.cli import main

    # simulate(): the docs' block ran it; the same gains through baumgarte give the same motion
    ours = spring_method["traj"]
    builtin = simulate("fourbar", method="baumgarte", kp=400.0, kd=40.0, duration=1.0)
    np.testing.assert_allclose(ours.q, builtin.q, rtol=0, atol=1e-12)
    assert ours.info.method == "spring" and ours.info.parameters == {"kp": 400.0, "kd": 40.0}
    # the CLI: its --method choices and --kp/--kd flags come from the registry
    assert (
        main(["run", "fourbar", "--method", "spring", "--kp", "400", "--kd", "40", "--duration", "0.2", "--json"]) == 0
    )
    result = json.loads(capsys.readouterr().out)
    assert result["method"] == "spring" and result["max_position_drift"] < 1e-8
    assert main(["run", "fourbar", "--method", "spring", "--decay", "0.2", "--duration", "0.2"]) == 2
    assert "method 'spring' takes no option 'decay'" in capsys.readouterr().err
    # the stability map: its prediction from the method's own deviation gains equals baumgarte's
    scene = load_scene("fourbar")
    options = dict(integrator="semi-implicit-euler", dt_range=(1e-3, 2e-2), gain_range=(1e2, 1e6), grid=3, steps=20)
    mine, reference = (
        stability_map(scene, method="spring", **options),
        stability_map(scene, method="baumgarte", **options),
    )
    assert [c.predicted_radius for c in mine.cells] == pytest.approx([c.predicted_radius for c in reference.cells])
    assert [c.observed for c in mine.cells] == [c.observed for c in reference.cells]


def test_a_constraint_kind_registered_outside_the_package_is_read_from_scene_tables():
    """A scene-file kind is one registration: here a fixed distance between two frame points, read
    from its own table keys. A point mass held at 1.5 m from the ground frame by it moves exactly like
    the pendulum written with a user HolonomicConstraint (the same phi = |p|^2 - l^2)."""
    import numpy as np

    from conftest import DATA, pendulum_scene
    from pinstab import CONSTRAINT_KINDS, simulate
    from pinstab.constraints import Constraint, VelocityTerms
    from pinstab.errors import SceneError
    from pinstab.scene import scene_from_dict

    class Distance(Constraint):
        holonomic, rows, force_frame = True, 1, "along the line a-b (tension > 0)"

        def __init__(self, name, frame_a, frame_b, length):
            self.name, self.frame_a, self.frame_b, self.length = name, frame_a, frame_b, length

        def _line(self, kin):
            return kin.placement(self.frame_a).translation - kin.placement(self.frame_b).translation

        def residual(self, kin, q, t):
            return np.array([self._line(kin) @ self._line(kin) - self.length**2])

        def velocity_terms(self, kin, q, t):
            jac = kin.jacobian(self.frame_a)[:3] - kin.jacobian(self.frame_b)[:3]
            return VelocityTerms((2 * self._line(kin) @ jac)[None, :], np.zeros(1))

        def drift(self, kin, q, v, t):
            jac = kin.jacobian(self.frame_a)[:3] - kin.jacobian(self.frame_b)[:3]
            rate = jac @ v
            accel = kin.drift_acceleration(self.frame_a).linear - kin.drift_acceleration(self.frame_b).linear
            return np.array([2 * rate @ rate + 2 * self._line(kin) @ accel])

    def parse(entry, tables, name, where):
        tables.check_keys(entry, {"name", "kind", "frame_a", "frame_b", "offset_a", "offset_b", "length"}, where)
        frames = [
            tables.point_frame(
                entry[f"frame_{s}"], tables.placement(entry, f"offset_{s}", f"rpy_{s}", where), f"{name}/{s}", where
            )
            for s in ("a", "b")
        ]
        return Distance(name, *frames, tables.quantity(entry.get("length", 0.0), "length", f"{where}.length"))

    CONSTRAINT_KINDS.register("distance", parse, summary="two frame points at a fixed distance")
    try:
        rod = {"name": "rod", "kind": "distance", "frame_a": "mass", "frame_b": "ground", "length": "1.5 m"}
        data = {"robot": {"urdf": str(DATA / "point_mass.urdf")}, "gravity": [0.0, -9.81, 0.0], "initial": INITIAL}
        with pytest.raises(SceneError, match="unknown key 'size'"):
            scene_from_dict({**data, "closures": [{**rod, "size": 1}]})
        registered = simulate(scene_from_dict({**data, "closures": [rod]}), method="baumgarte", duration=1.0)
        reference = simulate(pendulum_scene(1.5, 9.81, INITIAL), method="baumgarte", duration=1.0)
        assert registered.info.row_kinds == {"rod": "equality"}
        np.testing.assert_allclose(registered.q, reference.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(registered.multipliers, reference.multipliers, rtol=1e-9, atol=1e-9)
    finally:
        CONSTRAINT_KINDS.unregister("distance")

"""Set-up: the README's two commands, what .ci/run runs, the build requirements and the benchmark results' stamps."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import tomllib
from pathlib import Path

import numpy as np
import pytest
from packaging.requirements import Requirement

from pinstab.bench import save_results
from pinstab.bench.provenance import SOURCE

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def _name(requirement: str) -> str:
    return re.match(r"[A-Za-z0-9_.-]+", requirement).group(0).lower()


def _readme_commands() -> tuple[str, str]:
    """The README's main-job and test commands, as ``benchmarks/setup_sequence.py`` reads and runs them."""
    spec = importlib.util.spec_from_file_location("setup_sequence", ROOT / "benchmarks" / "setup_sequence.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.readme_commands()


def test_the_build_group_is_the_build_systems_requirements_with_cmake_and_ninja():
    """--no-build-isolation builds with what the venv holds: the group must give what an isolated build gets."""
    group = PROJECT["dependency-groups"]["build"]
    system = PROJECT["build-system"]["requires"]
    assert [r for r in group if _name(r) not in ("cmake", "ninja")] == system
    assert {_name(r) for r in group} - {_name(r) for r in system} == {"cmake", "ninja"}


def test_the_readme_starts_with_the_main_job_and_the_test_command_and_ci_runs_the_latter():
    main_job, tests = _readme_commands()
    assert main_job.endswith("pinstab run fourbar --duration 10 --json")
    assert tests.endswith(".venv/bin/python -m pytest")
    assert "--no-build-isolation -e ." in main_job and "--group build" in main_job
    assert tests in (ROOT / ".ci" / "run").read_text()


def test_the_main_job_pulls_in_no_mujoco_dask_or_pyarrow():
    core = {_name(r) for r in PROJECT["project"]["dependencies"]}
    assert not core & {"mujoco", "dask", "pyarrow", "matplotlib", "sphinx"}


def test_lowest_constraints_pin_every_lower_bound():
    """The lowest-versions job pins each declared lower bound, the core's and every extra's the tests pull in."""
    done = subprocess.run(
        ["python", str(ROOT / ".ci" / "lowest_constraints.py")], capture_output=True, text=True, check=True
    )
    pins = dict(line.split("==") for line in done.stdout.split())
    optional = PROJECT["project"]["optional-dependencies"]
    declared = PROJECT["project"]["dependencies"] + [r for extra in optional.values() for r in extra]
    for requirement in (r for r in map(Requirement, declared) if r.name != "pinstab"):
        lowest = [spec.version for spec in requirement.specifier if spec.operator in (">=", "==")]
        assert pins[requirement.name.lower()] == lowest[0], requirement


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def test_save_results_stamps_the_commit_and_versions(tmp_path):
    save_results(tmp_path / "r.json", {"x": 1})
    written = json.loads((tmp_path / "r.json").read_text())
    assert written["x"] == 1
    stamp = written["provenance"]
    assert stamp["commit"] == _git("rev-parse", "HEAD")
    assert stamp["versions"]["numpy"] == np.__version__
    assert stamp["dirty"] == bool(_git("status", "--porcelain", "--untracked-files=no", "--", *SOURCE))


RESULTS = sorted(p for p in (ROOT / "benchmarks").rglob("*.json"))


@pytest.mark.parametrize("path", RESULTS, ids=[str(p.relative_to(ROOT / "benchmarks")) for p in RESULTS])
def test_every_committed_benchmark_result_carries_a_commit_of_this_history(path):
    """A result names the clean commit that produced it, and that commit is in this repository's history."""
    stamp = json.loads(path.read_text()).get("provenance")
    assert stamp, f"{path.name} has no provenance: re-run its benchmark"
    assert stamp["dirty"] is False, f"{path.name} was produced from source with uncommitted changes"
    assert subprocess.run(["git", "merge-base", "--is-ancestor", stamp["commit"], "HEAD"], cwd=ROOT).returncode == 0
    assert {"pin", "numpy", "scipy", "proxsuite"} <= set(stamp["versions"])

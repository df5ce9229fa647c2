"""The limits a process really has (issue 23, item 5): the memory cgroup (v2 and v1, read from a fake /sys
tree: no cgroup can be set on this machine without touching the session's own), RLIMIT_AS under
``prlimit --as`` (a real limit, in a subprocess), a MemoryError during a run turned into a named
MemoryBudgetError that keeps the samples, and scene values that would overflow the dynamics refused by name."""

from __future__ import annotations

import resource
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pinstab.memory
from pinstab import MemoryBudgetError, SceneError, Trajectory, load_scene, simulate
from pinstab.cli import main
from pinstab.integration.records import Records
from pinstab.integration.stepping import CHECK_STEPS, StepLoop
from pinstab.memory import limits
from pinstab.memory.limits import memory_sources, tightest

ROBOTS = Path(__file__).resolve().parent.parent / "robots"
GB = 10**9
CLI = "import sys; from pinstab.cli import main; sys.exit(main())"
SOURCES = (
    "from pinstab.memory.limits import tightest; s = tightest(); "
    "size = [l for l in open('/proc/self/status') if l.startswith('VmSize:')][0].split()[1]; "
    "print(s.name, s.limit, s.free, int(size) * 1024)"
)


def fake_tree(root: Path, cgroup: str, files: dict[str, str], meminfo_kb: int = 16_000_000) -> Path:
    """A root directory with /proc/self/cgroup, /proc/meminfo and the given files under it."""
    (root / "proc/self").mkdir(parents=True)
    (root / "proc/self/cgroup").write_text(cgroup)
    (root / "proc/meminfo").write_text(f"MemTotal: 32000000 kB\nMemAvailable: {meminfo_kb} kB\n")
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def v2_tree(root: Path) -> Path:
    """cgroup v2, the process in /work/job: the job limited to 1 GB (400 MB used, 100 MB of it reclaimable
    cache: 700 MB free), its parent /work to 500 MB (300 MB used: 200 MB free, the tightest)."""
    mount = "sys/fs/cgroup"
    return fake_tree(
        root,
        "0::/work/job\n",
        {
            f"{mount}/cgroup.controllers": "memory\n",
            f"{mount}/work/memory.max": f"{GB // 2}\n",
            f"{mount}/work/memory.current": f"{3 * GB // 10}\n",
            f"{mount}/work/job/memory.max": f"{GB}\n",
            f"{mount}/work/job/memory.current": f"{4 * GB // 10}\n",
            f"{mount}/work/job/memory.stat": f"anon 300000000\ninactive_file {GB // 10}\nactive_file 0\n",
        },
    )


def python_under_address_limit(code: str, *args: str, limit: int = 2 * GB) -> subprocess.CompletedProcess:
    """``python -c code args`` under RLIMIT_AS = ``limit`` [bytes]: ``prlimit --as`` (util-linux) when it exists,
    else resource.setrlimit in the child."""
    command = [sys.executable, "-c", code, *args]
    if shutil.which("prlimit"):
        return subprocess.run(["prlimit", f"--as={limit}", *command], capture_output=True, text=True, timeout=120)

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return subprocess.run(command, capture_output=True, text=True, timeout=120, preexec_fn=limited)


# -- the limits read -----------------------------------------------------------------------------------------
def test_cgroup_v2_every_level_counts_and_the_tightest_is_named(tmp_path):
    sources = {source.name: source for source in memory_sources(v2_tree(tmp_path))}
    job = sources["the cgroup v2 limit memory.max of /work/job"]
    parent = sources["the cgroup v2 limit memory.max of /work"]
    assert (job.limit, job.free) == (GB, 7 * GB // 10)  # 1 GB - (400 MB - 100 MB of cache)
    assert (parent.limit, parent.free) == (GB // 2, 2 * GB // 10)
    assert sources["MemAvailable"].free == 16_000_000 * 1024
    assert tightest(tmp_path) == parent


def test_cgroup_v2_without_a_limit_leaves_memavailable(tmp_path):
    root = fake_tree(
        tmp_path,
        "0::/job\n",
        {"sys/fs/cgroup/cgroup.controllers": "memory\n", "sys/fs/cgroup/job/memory.max": "max\n"},
        meminfo_kb=1000,
    )
    (root / "sys/fs/cgroup/job/memory.current").write_text("5000\n")
    assert [source.name for source in memory_sources(root)] == ["MemAvailable"]
    assert tightest(root).free == 1000 * 1024


@pytest.mark.parametrize("path", ["/docker/abc", "/"], ids=["host view", "namespaced"])
def test_cgroup_v1_limit_in_bytes(tmp_path, path):
    """v1 (hybrid: the v2 mount has no memory controller): 2 GB limit, 500 MB used of which 100 MB inactive
    cache -> 1.6 GB free; the hierarchy's root is unlimited (2^63 - 4096). In a cgroup namespace the
    process's path is not under the mount: the mount's own files are its cgroup's."""
    mount = "sys/fs/cgroup/memory"
    level = f"{mount}/docker/abc" if path != "/" else mount
    files = {
        "sys/fs/cgroup/unified/cgroup.controllers": "\n",
        f"{mount}/memory.limit_in_bytes": "9223372036854771712\n",
        f"{mount}/memory.usage_in_bytes": "9000000000\n",
        f"{level}/memory.limit_in_bytes": f"{2 * GB}\n",
        f"{level}/memory.usage_in_bytes": f"{GB // 2}\n",
        f"{level}/memory.stat": f"cache 1\ntotal_inactive_file {GB // 10}\n",
    }
    root = fake_tree(tmp_path, f"12:pids:/x\n4:memory:{path}\n0::/\n", files)
    limit = tightest(root)
    assert limit.name.startswith("the cgroup v1 limit memory.limit_in_bytes of /")
    assert (limit.limit, limit.free) == (2 * GB, 16 * GB // 10)


def test_a_run_under_a_cgroup_limit_is_refused_naming_it(tmp_path, monkeypatch):
    """The budget takes the tightest limit: a run of 192 MB of samples (test_memory) against 80 % of the fake
    cgroup's 200 MB free (160 MB)."""
    root = v2_tree(tmp_path)
    monkeypatch.setattr(pinstab.memory, "tightest", lambda: tightest(root))
    with pytest.raises(MemoryBudgetError) as refused:
        simulate("fourbar", dt=1e-3, duration=1000.0)
    assert refused.value.limit == 16 * GB // 100
    assert "limit of 160 MB (80% of the 200 MB left by the cgroup v2 limit memory.max of /work of 500 MB)" in str(
        refused.value
    )


def test_rlimit_as_is_read_less_the_virtual_size():
    done = python_under_address_limit(SOURCES, limit=3 * GB)
    name, limit, free, size = done.stdout.split()[-4:]
    assert "RLIMIT_AS" in done.stdout and int(limit) == 3 * GB
    assert abs(int(free) - (3 * GB - int(size))) < 50 * 2**20  # VmSize read twice, a few allocations apart


# -- the acceptance: a named memory error, no traceback -----------------------------------------------------
def test_nfourbar_1000_under_prlimit_is_refused_naming_rlimit_as():
    """N = 1000 (nv = 2001): three Pinocchio Data of 1.3 GB each, against 80 % of what 2 GB of address space leaves."""
    done = python_under_address_limit(CLI, "run", "nfourbar", "--param", "N=1000", "--quiet")
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert "pinstab run: error: a run of scene nfourbar" in done.stderr
    assert "needs about 3.96 GB" in done.stderr and "RLIMIT_AS (ulimit -v, prlimit --as) of 2 GB" in done.stderr


def test_a_real_memory_error_under_prlimit_is_named():
    """With the budget raised past the address space (--memory-limit), Pinocchio's allocation fails for real."""
    args = ("run", "nfourbar", "--param", "N=1000", "--quiet", "--memory-limit", "100GB")
    # 1.2 GB: the banded path holds one Data of about 1.3 GB (pinstab's, without the derivative tensors)
    done = python_under_address_limit(CLI, *args, limit=1_200_000_000)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert "ran out of memory" in done.stderr
    assert "the tightest limit on this process:" in done.stderr and "RLIMIT_AS" in done.stderr


# -- a MemoryError during a run keeps the samples ------------------------------------------------------------
@pytest.fixture
def out_of_memory_at_half_a_second(monkeypatch):
    """Keeping a step's state (one by one, or a compiled run's) raises MemoryError from t = 0.5 s on (as an allocation
    during the run would)."""
    keep = StepLoop.keep

    def failing(self, k, q, v, iterations=0):
        if self.grid.time(k) >= 0.5:
            raise MemoryError("Unable to allocate 8 GiB for an array")
        return keep(self, k, q, v, iterations)

    put_span = Records.put_span

    def failing_span(self, first, q, v, iterations=None):  # the compiled loop's samples
        if self.grid.time(first + len(q) - 1) >= 0.5:
            raise MemoryError("Unable to allocate 8 GiB for an array")
        return put_span(self, first, q, v, iterations)

    monkeypatch.setattr(StepLoop, "keep", failing)
    monkeypatch.setattr(Records, "put_span", failing_span)


def test_a_memory_error_during_a_run_keeps_the_samples_up_to_it(out_of_memory_at_half_a_second):
    """The kept samples are those of the same run without the failure (same times, same states to 1e-12)."""
    with pytest.raises(MemoryBudgetError, match="the run of scene fourbar ran out of memory") as stopped:
        simulate("fourbar", dt=1e-3, duration=1.0)
    error = stopped.value
    assert "Unable to allocate 8 GiB" in str(error) and tightest().name in str(error) and error.estimate is None
    kept = error.trajectory  # it ends at the last checked state: the start of the chunk of step 500
    assert kept.t[-1] == pytest.approx((500 - 1) // CHECK_STEPS * CHECK_STEPS * 1e-3, abs=1e-12)
    assert f"samples up to t = {kept.t[-1]:.6g} s are kept" in str(error)
    reference = simulate("fourbar", dt=1e-3, duration=kept.t[-1])
    assert np.array_equal(kept.t, reference.t)
    assert np.abs(kept.q - reference.q).max() < 1e-12


def test_the_command_line_saves_the_partial_run_and_exits_2(out_of_memory_at_half_a_second, tmp_path, capsys):
    saved = tmp_path / "partial.npz"
    code = main(["run", "fourbar", "--duration", "1", "--quiet", "--save", str(saved)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "pinstab run: error: the run of scene fourbar ran out of memory" in err
    assert f"the partial trajectory is saved to {saved}" in err
    assert Trajectory.load(saved).t[-1] == pytest.approx(0.4, abs=1e-12)  # as above


# -- values that overflow the dynamics ----------------------------------------------------------------------
def scene_file(tmp_path: Path, name: str, replace: tuple[str, str], urdf: str | None = None) -> Path:
    """A copy of the bundled scene ``name`` with one text replaced (and its robot file, when ``urdf`` names it,
    copied with a mass of 1e308)."""
    text = (ROBOTS / f"{name}.toml").read_text().replace(*replace)
    if urdf is not None:
        robot = (ROBOTS / urdf).read_text().replace('<mass value="1"/>', '<mass value="1e308"/>', 1)
        (tmp_path / "robot.urdf").write_text(robot)
        text = text.replace(f'"{urdf}"', '"robot.urdf"')
    else:
        text = text.replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("name", "replace", "urdf", "phrase"),
    [
        (
            "slider-crank",
            ("stiffness = 0.0", "stiffness = 1e308"),
            None,
            "force 'load'.stiffness = 1e+308 N/m is outside the allowed range [0, 1e+12] N/m",
        ),
        (
            "slider-crank",
            ('damping = "2.0 N*s/m"', "damping = 1e13"),
            None,
            "force 'load'.damping = 1e+13 N s/m is outside the allowed range [0, 1e+12] N s/m",
        ),
        ("fourbar", ("", ""), "urdf/fourbar.urdf", "robot link 'coupler': mass = 1e+308 kg is outside"),
        (
            "allegro-sphere",
            ('mass = "100 g"', "mass = 1e308"),
            None,
            "object 'ball'.mass = 1e+308 kg is outside the allowed range (0, 1e+12] kg",
        ),
    ],
    ids=["spring stiffness", "spring damping", "urdf link mass", "object mass"],
)
def test_values_that_overflow_are_refused_by_name(tmp_path, capsys, name, replace, urdf, phrase):
    code = main(["run", str(scene_file(tmp_path, name, replace, urdf)), "--duration", "0.01", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and "ProxQP" not in err
    assert phrase in err and "beyond 1e12 in SI units" in err


def test_the_ceiling_itself_is_accepted(tmp_path):
    """1e12 N/m is at the edge of the range: loaded (the run's step is another matter)."""
    scene = load_scene(scene_file(tmp_path, "slider-crank", ("stiffness = 0.0", "stiffness = 1e12")))
    assert scene.forces[1].stiffness == 1e12
    with pytest.raises(SceneError, match=r"stiffness = 1e\+12 N/m is outside"):
        load_scene(scene_file(tmp_path, "slider-crank", ("stiffness = 0.0", "stiffness = 1.0000001e12")))


def test_a_reading_of_the_real_limits_is_reused_for_half_a_second(monkeypatch):
    """Under the real root, tightest() reads the limits once per FRESH_FOR seconds (a run checks its budget several
    times at its start): the same reading within it, a new one after it."""
    clock = [1000.0]
    monkeypatch.setattr(limits.time, "monotonic", lambda: clock[0])
    monkeypatch.setattr(limits, "_recent", [])
    first = tightest()
    clock[0] += 0.4 * limits.FRESH_FOR
    assert tightest() is first
    clock[0] += limits.FRESH_FOR
    assert tightest() is not first

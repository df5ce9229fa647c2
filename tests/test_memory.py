"""The memory budget (issue 13, item 4): the estimates against measured resident sizes, refusals before
allocating (exit 2 with the estimate and the limit), ``--memory-limit``, and a long run kept small by thinning."""

from __future__ import annotations

import subprocess
import sys

import pytest

from pinstab import ConstrainedModel, MemoryBudgetError, PinstabError, load_scene, memory_limit, simulate
from pinstab.cli import main
from pinstab.memory import available_bytes, data_bytes, limit_bytes, parse_size

MEASURE_DATA = """
import ctypes
import sys
import pinocchio as pin
from pinstab.scene import load_scene
from pinstab.memory import data_bytes, new_data
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096
model = load_scene("nfourbar", N=int(sys.argv[1])).model
tensors = sys.argv[2] == "pin.Data"
build = pin.Data if tensors else new_data
ctypes.CDLL("libc.so.6").malloc_trim(0)  # freed heap given back: the datas' pages are new, not reused
before = rss()
datas = [build(model) for _ in range(4)]
print((rss() - before) / 4, data_bytes(model.nv, model.njoints, tensors))
"""

PEAK_OF_RUN = """
import resource, sys
from pinstab.cli import main
code = main(sys.argv[1:])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, code)
"""


@pytest.mark.parametrize("build", ["new_data", "pin.Data"])
@pytest.mark.parametrize("n", [20, 50, 75])
def test_the_data_estimate_is_an_upper_bound_within_a_factor_2_5(n, build):
    """nfourbar N = 20, 50, 75: nv = 41, 101, 151; pinstab's Data (measured 0.5 MB, 3 MB, 6 MB on Pinocchio 4.1) and
    Pinocchio's constructor's, with its nv^3 tensors (4 MB, 49 MB, 166 MB)."""
    argv = [sys.executable, "-c", MEASURE_DATA, str(n), build]
    done = subprocess.run(argv, capture_output=True, text=True, check=True)
    measured, estimate = map(float, done.stdout.split())
    assert measured <= estimate <= 2.5 * measured


@pytest.mark.parametrize(
    ("text", "size"), [("4 GB", 4e9), ("512MiB", 512 * 2**20), ("1e9", 1e9), ("2.5 gib", 2.5 * 2**30), ("100 kB", 1e5)]
)
def test_sizes(text, size):
    assert parse_size(text) == int(size)


@pytest.mark.parametrize(
    ("text", "phrase"),
    [("abc", "is not a size"), ("4 XB", "is not a size"), ("0", "positive, finite"), ("-1 GB", "positive, finite")],
)
def test_bad_sizes(text, phrase):
    with pytest.raises(PinstabError, match=phrase):
        parse_size(text)


def test_the_default_limit_is_80_percent_of_the_available_memory():
    assert limit_bytes() == pytest.approx(0.8 * available_bytes(), rel=0.05)
    with memory_limit("1 GB"):
        assert limit_bytes() == 10**9
    assert limit_bytes() != 10**9


def test_a_run_over_the_budget_is_refused_before_it_allocates():
    """1e6 samples of the four-bar (nq = nv = 3, 2 rows): 8 (3 + 3 + 2 + 16) 1e6 = 192 MB, plus 3 Data."""
    with memory_limit("100 MB"), pytest.raises(MemoryBudgetError, match="needs about 192 MB") as refused:
        simulate("fourbar", dt=1e-3, duration=1000.0)
    assert refused.value.limit == 10**8 and 192e6 <= refused.value.estimate <= 193e6
    assert "limit of 100 MB" in str(refused.value) and "record_every" in str(refused.value)
    with memory_limit("100 MB"):  # thinned, the same run fits
        assert simulate("fourbar", dt=1e-3, duration=10.0, record_every=1000).t[-1] == 10.0


def test_a_large_model_is_refused_before_its_data_is_built():
    """nfourbar N = 200: nv = 401, two Data of about 56 MB each."""
    scene = load_scene("nfourbar", N=200)
    with memory_limit("100 MB"), pytest.raises(MemoryBudgetError, match="401 velocities") as refused:
        ConstrainedModel(scene)
    assert refused.value.estimate == 2 * data_bytes(401, 402) and refused.value.limit == 10**8


def test_the_command_line_refuses_with_exit_2_and_names_the_estimate_and_the_limit(capsys):
    code = main(["run", "fourbar", "--duration", "1000", "--memory-limit", "50MB", "--quiet", "--json"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and "Traceback" not in err
    assert "needs about 192 MB" in err and "limit of 50 MB" in err and "--memory-limit 384MB" in err


def test_a_long_thinned_run_grows_the_peak_memory_by_less_than_20_mb(tmp_path):
    """2e5 steps of the four-bar with a sample every 100 steps, saved, against 10 steps (peak RSS of each)."""
    peaks = []
    for duration in ("0.01", "200"):
        argv = ["run", "fourbar", "--duration", duration, "--record-every", "100", "--quiet", "--json"]
        argv += ["--save", str(tmp_path / f"run-{duration}.npz")]
        done = subprocess.run([sys.executable, "-c", PEAK_OF_RUN, *argv], capture_output=True, text=True, check=True)
        peak, code = done.stdout.split()[-2:]
        assert code == "0"
        peaks.append(int(peak))
    assert peaks[1] - peaks[0] < 20 * 2**20

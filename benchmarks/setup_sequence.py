"""The README's set-up as a new user meets it, in a fresh clone of this checkout's HEAD (issue 33): the main-job
command, the test command, the main-job command again, then `touch cpp/stepping.cpp` and the documented
re-install (`.venv/bin/pip install --no-build-isolation -e .`). Each step's exit code and wall time, and the peak
memory of the heaviest process under it (a compile job, during the first build).

python benchmarks/setup_sequence.py           # about 12 min on 2 cores; writes benchmarks/results/setup.json
"""

from __future__ import annotations

import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pinstab.bench import save_results

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "setup.json"
REINSTALL = ".venv/bin/pip install --no-build-isolation -e ."


def readme_commands() -> tuple[str, str]:
    """The README's main-job and test commands: the command lines of its first two bash blocks."""
    blocks = re.findall(r"```bash\n(.*?)```", (ROOT / "README.md").read_text(), re.S)[:2]
    main_job, tests = (next(line for line in b.splitlines() if line and not line.startswith("#")) for b in blocks)
    return main_job, tests


def step(name: str, command: str, cwd: Path) -> dict:
    """Run ``command`` in bash in ``cwd``: its exit code, wall time [s] and the largest resident set [MiB] of any
    process it waited for (ru_maxrss of the children, which grows only: the first step's is the build's)."""
    began = time.perf_counter()
    done = subprocess.run(["bash", "-c", command], cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - began
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"{name:28s} exit {done.returncode:3d}  {wall:7.1f} s  peak process {peak:6.0f} MiB")
    record = {"step": name, "command": command, "exit": done.returncode, "wall_s": wall, "peak_rss_mib": peak}
    if done.returncode:  # what it said last, on either stream (pytest's summary, pip's error)
        record["stdout_tail"] = done.stdout.strip().splitlines()[-30:]
        record["stderr_tail"] = done.stderr.strip().splitlines()[-30:]
        print("\n".join(record["stdout_tail"] + record["stderr_tail"]))
    return record


def main() -> None:
    main_job, tests = readme_commands()
    with tempfile.TemporaryDirectory(prefix="pinstab-setup-") as folder:
        clone = Path(folder) / "pinstab"
        subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
        steps = [
            step("main job (first build)", main_job, clone),
            step("test command", tests, clone),
            step("main job again", main_job, clone),
            step("touch cpp/stepping.cpp", "touch cpp/stepping.cpp", clone),
            step("re-install (one file)", REINSTALL, clone),
        ]
    first, rebuild = steps[0]["wall_s"], steps[-1]["wall_s"]
    print(f"one-file rebuild / first build: {rebuild / first:.3f}")
    save_results(OUT, {"steps": steps, "rebuild_over_first_build": rebuild / first})
    sys.exit(max(s["exit"] for s in steps) != 0)


if __name__ == "__main__":
    main()

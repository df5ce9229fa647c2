"""Outputs checked before the work (issue 13, item 5): a folder in the target's place, a missing or
unwritable folder, names too long for the file system; temporary files removed, a killed writer's on the
next write."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from pinstab import PinstabError
from pinstab.cli import main
from pinstab.files import TEMP_MARK, atomic_output, check_output


def test_a_good_target_passes_and_leaves_nothing(tmp_path):
    assert check_output(tmp_path / "run.npz", ".npz", "trajectory") == tmp_path / "run.npz"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("name", "phrase"),
    [
        ("out.npz/", "is a folder; give a file name ending in .npz"),
        ("run.csv", "the output must be a .npz file"),
        ("missing/run.npz", "folder {tmp}/missing does not exist"),
        ("afile/run.npz", "folder {tmp}/afile is not a folder"),
        ("a" * 250 + ".npz", "its name is too long (254 bytes"),
    ],
)
def test_bad_targets_are_refused_with_their_cause(tmp_path, name, phrase):
    (tmp_path / "out.npz").mkdir()
    (tmp_path / "afile").write_text("x")
    with pytest.raises(PinstabError, match=phrase.format(tmp=tmp_path).replace("(", r"\(")):
        check_output(tmp_path / name, ".npz", "trajectory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "out.npz"]


def test_a_name_that_fits_only_without_the_temporary_suffix_is_refused_with_the_longest_that_fits(tmp_path):
    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    with pytest.raises(PinstabError, match="give a name of at most") as refused:
        check_output(tmp_path / ("b" * (name_max - 4) + ".npz"), ".npz", "trajectory")
    longest = int(str(refused.value).split("at most ")[1].split()[0])
    check_output(tmp_path / ("b" * (longest - 4) + ".npz"), ".npz", "trajectory")  # that one passes
    with pytest.raises(PinstabError):
        check_output(tmp_path / ("b" * (longest - 3) + ".npz"), ".npz", "trajectory")


def unwritable_folder(tmp_path):
    """A folder this process cannot create files in: read-only for a normal user, /sys for root."""
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o555)
    if not os.access(folder, os.W_OK):
        return folder
    if not os.access("/sys", os.W_OK) or subprocess.run(["touch", "/sys/x"], capture_output=True).returncode:
        return "/sys"
    pytest.skip("no folder is unwritable for this user")


def test_an_unwritable_folder_is_refused_before_the_run(tmp_path, capsys):
    folder = unwritable_folder(tmp_path)
    code = main(["run", "fourbar", "--duration", "100", "--quiet", "--save", f"{folder}/run.npz"])
    err = capsys.readouterr().err
    assert code == 2 and f"folder {folder} is not writable" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "argv",
    [
        "run fourbar --duration 100 --save {tmp}/out.npz",
        "run fourbar --duration 100 --plot {tmp}/out.npz",
        "record fourbar --duration 100 -o {tmp}/out.npz",
        "stability fourbar --grid 1000 -o {tmp}/out.npz",
        "plot {tmp}/run.npz -o {tmp}/out.npz",
    ],
)
def test_every_command_refuses_a_folder_target_before_its_work(tmp_path, capsys, argv):
    """A 100 s run or a 1000 x 1000 map would take minutes: refused at once."""
    (tmp_path / "out.npz").mkdir()
    words = argv.format(tmp=tmp_path).split()
    code = main(words if words[0] == "plot" else [*words, "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "out.npz is a folder" in err


def test_a_killed_writers_temporary_file_goes_with_the_next_write_and_a_live_ones_stays(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".run.npz{TEMP_MARK}{dead.stdout.strip()}-abcdefgh.npz"
    live = tmp_path / f".run.npz{TEMP_MARK}1-abcdefgh.npz"  # pid 1 runs
    other = tmp_path / f".other.npz{TEMP_MARK}{dead.stdout.strip()}-abcdefgh.npz"  # another target's
    for path in (stale, live, other):
        path.write_bytes(b"half")
    with atomic_output(tmp_path / "run.npz", ".npz", "trajectory") as temp:
        with open(temp, "wb") as handle:
            handle.write(b"whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, other.name, "run.npz"])
    assert (tmp_path / "run.npz").read_bytes() == b"whole"

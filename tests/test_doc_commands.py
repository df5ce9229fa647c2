"""Every shell command of README.md and docs/**/*.md is run, and exits with the code the page shows.

Which lines are commands:

- in a ```console block, each line starting with ``$ `` (its other lines are output, not compared: a run's wall
  time and the last digits of its figures move with the machine);
- in a ```bash or ```sh block, every line that is not empty and not a comment;
- a line ending with ``\\`` continues on the next one.

The exit code expected is 0, unless the command ends with a comment ``# exit code N``, or the block's next command
is ``echo $?`` followed by the line ``N`` (that ``echo`` is not run). A command whose shown output reads
``pinstab ...: error:`` must say which non-zero code it expects.

``<!-- not-run: REASON -->`` on the line before a block (blank lines allowed between) marks its commands as too long
for the tests (set-up commands, benchmarks of minutes): they are parsed, not run: a ``pinstab`` command by pinstab's
own argument parser, ``python SCRIPT.py`` by compiling the script, ``python -m pytest PATH`` and ``pip install -e
'.[EXTRA]'`` / ``--group NAME`` by checking that the path, extra or group exists; a command of any other kind in a
not-run block fails the test until a rule for it is added here.

Commands run with ``bash -c`` in a temporary folder that holds links to the repository's ``demos/``, ``benchmarks/``,
``robots/`` and ``tests/``, with ``.venv``'s ``bin`` first on ``PATH`` (``pinstab`` and ``python`` are the
project's) and ``MPLBACKEND=Agg``; the parent folders of relative output paths (``-o docs/x.png``) are created
there, so that nothing is written into the repository.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
LINKED = ("demos", "benchmarks", "robots", "tests")
NOT_RUN = re.compile(r"<!--\s*not-run:\s*(?P<reason>.+?)\s*-->")
EXIT_COMMENT = re.compile(r"#\s*exit code\s+(?P<code>\d+)\s*$")
FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>```+|~~~+)\s*(?P<lang>[\w-]*)")


@dataclass(frozen=True)
class DocCommand:
    page: str  # relative to the repository
    line: int  # 1-based line of the command's first line
    command: str
    exit_code: int
    not_run: str | None  # the reason, for commands only parsed
    shows_error: bool  # the page shows "pinstab ...: error:" after it

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _blocks(lines: list[str]):
    """(language, first content line index, content lines, not-run reason) of each fenced block."""
    index = 0
    while index < len(lines):
        opening = FENCE.match(lines[index])
        if not opening:
            index += 1
            continue
        fence, lang = opening["fence"], opening["lang"].lower()
        reason = None
        back = index - 1
        while back >= 0 and not lines[back].strip():
            back -= 1
        if back >= 0 and (marker := NOT_RUN.search(lines[back])):
            reason = marker["reason"]
        end = index + 1
        while end < len(lines) and not lines[end].strip().startswith(fence):
            end += 1
        yield lang, index + 1, lines[index + 1 : end], reason
        index = end + 1


def _strip_comment(command: str) -> str:
    """The command without a trailing ``# comment`` (a ``#`` after a blank, outside quotes)."""
    quote = ""
    for position, char in enumerate(command):
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (position == 0 or command[position - 1].isspace()):
            return command[:position].rstrip()
    return command.strip()


def extract(page: Path) -> list[DocCommand]:
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[DocCommand] = []
    for lang, first, content, reason in _blocks(lines):
        if lang not in ("console", "bash", "sh", "shell"):
            continue
        entries: list[tuple[int, str, list[str]]] = []  # (line, command, output lines)
        k = 0
        while k < len(content):
            text = content[k]
            stripped = text.strip()
            is_command = (
                stripped.startswith("$ ") if lang == "console" else bool(stripped) and not stripped.startswith("#")
            )
            if not is_command:
                if entries and lang == "console":
                    entries[-1][2].append(text)
                k += 1
                continue
            start = k
            command = stripped[2:] if lang == "console" else stripped
            while command.endswith("\\") and k + 1 < len(content):
                k += 1
                command = command[:-1].rstrip() + " " + content[k].strip()
            entries.append((first + start + 1, command, []))
            k += 1
        for position, (line, command, output) in enumerate(entries):
            if command.strip() == "echo $?":
                continue
            code = 0
            if match := EXIT_COMMENT.search(command):
                code = int(match["code"])
            following = entries[position + 1] if position + 1 < len(entries) else None
            if following and following[1].strip() == "echo $?" and following[2]:
                code = int(following[2][0].strip())
            shows_error = any(re.match(r"^pinstab[ \w-]*: error:", out.strip()) for out in output)
            rel = page.relative_to(ROOT).as_posix()
            found.append(DocCommand(rel, line, _strip_comment(command), code, reason, shows_error))
    return found


COMMANDS = [command for page in pages() for command in extract(page)]
# a command shown on several pages (the README's tour and a guide) is run once, under its first page and line
RUN = list({(c.command, c.exit_code): c for c in reversed([c for c in COMMANDS if c.not_run is None])}.values())[::-1]
PARSED = [c for c in COMMANDS if c.not_run is not None]


def test_the_pages_have_commands_and_the_marked_ones_give_reasons():
    """The extraction finds the README's two set-up commands and the fuzzers' long run (parsed) and the tour's
    commands (run)."""
    readme = [c for c in COMMANDS if c.page == "README.md"]
    assert sum(c.not_run is not None for c in readme) == 3
    assert sum(c.not_run is None for c in readme) >= 10
    assert all(c.not_run.strip() for c in PARSED)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("doc-commands")
    for name in LINKED:
        (folder / name).symlink_to(ROOT / name, target_is_directory=True)
    return folder


def _output_folders(command: str, workdir: Path) -> None:
    """Create, in the work folder, the parent folders of relative paths the command names (``docs/x.png``)."""
    try:
        tokens = shlex.split(command)
    except ValueError:
        return
    for token in tokens:
        value = token.split("=", 1)[-1] if token.startswith("--") else token
        if "/" not in value or value.startswith(("/", "-", ".")) or "://" in value:
            continue
        parent = (workdir / value).parent
        if parent.name and not parent.exists() and parent.parts[len(workdir.parts)] not in LINKED:
            parent.mkdir(parents=True, exist_ok=True)


@pytest.mark.parametrize("doc", RUN, ids=[c.id for c in RUN])
def test_doc_command_runs(doc: DocCommand, workdir: Path):
    assert not (doc.shows_error and doc.exit_code == 0), (
        f"{doc.id}: the page shows an error after `{doc.command}` but no exit code: add `# exit code N`"
    )
    _output_folders(doc.command, workdir)
    env = dict(os.environ, PATH=f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", MPLBACKEND="Agg")
    env.pop("PYTHONPATH", None)
    completed = subprocess.run(
        ["bash", "-c", doc.command], cwd=workdir, env=env, capture_output=True, text=True, timeout=300
    )
    assert completed.returncode == doc.exit_code, (
        f"{doc.id}: `{doc.command}` exited {completed.returncode}, the page shows {doc.exit_code}\n"
        f"stdout: {completed.stdout[-2000:]}\nstderr: {completed.stderr[-3000:]}"
    )


def _parse_pinstab(arguments: list[str]) -> None:
    from pinstab.cli.dispatch import build_parser

    try:
        build_parser().parse_args(arguments)
    except SystemExit as exc:  # --help exits 0; a bad command line exits 2
        assert exc.code == 0, f"pinstab {shlex.join(arguments)}: the parser refuses it (exit {exc.code})"


def _check_segment(tokens: list[str]) -> None:
    while tokens and re.match(r"^[A-Z_][A-Z0-9_]*=", tokens[0]):  # environment assignments
        tokens = tokens[1:]
    if tokens and tokens[0] == "prlimit":  # prlimit --as=N COMMAND
        tokens = tokens[1:]
        while tokens and tokens[0].startswith("--"):
            tokens = tokens[1:]
    assert tokens, "an empty command"
    program = Path(tokens[0]).name
    arguments = tokens[1:]
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    if program == "pinstab":
        _parse_pinstab(arguments)
    elif program in ("python", "python3") and arguments[:2] == ["-m", "venv"]:
        pass
    elif program in ("python", "python3") and arguments[:2] == ["-m", "pytest"]:
        for path in (a for a in arguments[2:] if not a.startswith("-")):
            assert (ROOT / path.split("::")[0]).exists(), f"pytest path {path} does not exist"
    elif program in ("python", "python3") and arguments and arguments[0].endswith(".py"):
        script = ROOT / arguments[0]
        compile(script.read_text(encoding="utf-8"), str(script), "exec")
    elif program == "pip" and arguments[:1] == ["install"]:
        options = arguments[1:]
        for k, option in enumerate(options):
            if option == "--group":
                assert options[k + 1] in pyproject["dependency-groups"], f"no dependency group {options[k + 1]}"
            if match := re.fullmatch(r"\.\[(?P<extras>[\w,-]+)\]", option):
                for extra in match["extras"].split(","):
                    assert extra in pyproject["project"]["optional-dependencies"], f"no extra {extra}"
    elif program == "sphinx-build":
        assert (ROOT / "docs" / "conf.py").is_file()
    else:
        raise AssertionError(f"no rule to parse a not-run `{shlex.join(tokens)}`: add one to {Path(__file__).name}")


@pytest.mark.parametrize("doc", PARSED, ids=[c.id for c in PARSED])
def test_not_run_doc_command_parses(doc: DocCommand):
    for segment in re.split(r"\s*(?:&&|\|\||;)\s*", doc.command):
        _check_segment(shlex.split(segment))

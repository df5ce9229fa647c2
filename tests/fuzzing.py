"""What the property-based fuzzers share (tests/test_fuzz*.py): TOML writing, the command line run in process, the
time bound of an example and the work bound of a run, outputs that must not be lost, and the physics a contact scene
guarantees (gaps, energy).

The invariant every fuzzer asserts: an input either runs with finite results, or ends in a
:class:`~pinstab.errors.PinstabError` (exit 2, 3, 4 or 5 on the command line) whose message says what is wrong;
never another exception or a traceback, never a hang, never a file lost, never a body through a plane it touches.
"""

from __future__ import annotations

import contextlib
import ctypes
import datetime
import faulthandler
import io
import json
import math
import os
import signal
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from hypothesis import event, note, settings
from hypothesis.control import currently_in_test_context

from conftest import HYPOTHESIS_PROFILE
from pinstab.cli import main
from pinstab.constraints.contacts import PointContact
from pinstab.errors import PinstabError
from pinstab.scene import Scene

FAILURE_CODES = (2, 3, 4, 5)  # bad input, divergence, stopped at a contact event, contacts without a solution
EXAMPLE_SECONDS = 30  # [s] wall time of one example before it counts as a hang (runs of a few steps take < 1 s)


def examples(ci: int) -> settings:
    """The examples of a property: ``ci`` under the default profile (CI: the fuzzers together within about two
    minutes), the profile's own number under the others (``long``: 10,000)."""
    return settings(max_examples=ci) if HYPOTHESIS_PROFILE == "default" else settings()


def report(message: str, label: str) -> None:
    """``message`` shown with a failing example and ``label`` counted in the statistics, inside a Hypothesis test
    (the checks also run outside one, in the reproducers' tests)."""
    if currently_in_test_context():
        note(message)
        event(label)


# -- TOML writing --------------------------------------------------------------------------------------
def toml_value(value: Any) -> str:
    """``value`` as a TOML value (tables inline, so one line)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, (datetime.date, datetime.time)):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_value(str(key))} = {toml_value(item)}" for key, item in value.items()) + "}"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def toml_document(data: dict[str, Any]) -> str:
    """A TOML document whose top-level table is ``data``."""
    return "".join(f"{toml_value(str(key))} = {toml_value(value)}\n" for key, value in data.items())


# -- outcomes ------------------------------------------------------------------------------------------
def assert_error(exc: PinstabError) -> None:
    """A PinstabError must say something."""
    assert str(exc).strip(), f"{type(exc).__name__} with an empty message"


@dataclass(frozen=True)
class Outcome:
    """A command's exit code, stdout and stderr."""

    code: int
    out: str
    err: str

    @property
    def message(self) -> str:
        """The text after ``error:`` on stderr ('' when there is none)."""
        return self.err.split("error:", 1)[1].strip() if "error:" in self.err else ""


def cli(argv: list[str]) -> Outcome:
    """``pinstab ARGV`` in process: its exit code, never an exception or a traceback; a failure (exit 2-5) says
    why after ``error:``; with ``--json``, stdout holds one JSON object (or nothing) and nothing reaches the
    process's standard output below Python (a C or Fortran library's complaint, e.g. LAPACK's)."""
    out, err = io.StringIO(), io.StringIO()
    with native_stdout() as native, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    outcome = Outcome(code, out.getvalue(), err.getvalue())
    assert "Traceback" not in outcome.err, outcome.err
    if code in FAILURE_CODES:
        assert outcome.message, f"exit {code} without a message: {outcome.err!r}"
    if "--json" in argv:
        assert not native.read(), f"written to stdout below Python: {native.read()!r}"
        if outcome.out.strip():
            json.loads(outcome.out)  # nothing but the JSON object on stdout
    return outcome


class Captured:
    """What was written to file descriptor 1 while it was captured."""

    def __init__(self) -> None:
        self.data = b""

    def read(self) -> bytes:
        return self.data


@contextlib.contextmanager
def native_stdout() -> Iterator[Captured]:
    """File descriptor 1 redirected to a temporary file (C's buffers flushed on both ends)."""
    libc = ctypes.CDLL(None)
    captured = Captured()
    with tempfile.TemporaryFile() as raw:
        libc.fflush(None)
        saved = os.dup(1)
        os.dup2(raw.fileno(), 1)
        try:
            yield captured
        finally:
            libc.fflush(None)
            os.dup2(saved, 1)
            os.close(saved)
            raw.seek(0)
            captured.data = raw.read()


def check_file(path: Path) -> Outcome:
    """``pinstab check FILE --json`` in process: exit 0 with finite figures, or 2/3 with a message."""
    outcome = cli(["check", str(path), "--json"])
    if outcome.code == 0:
        result = json.loads(outcome.out)
        figures = ("nq", "nv", "rows", "rank", "assembly_residual", "assembly_velocity_residual")
        assert all(result[key] is not None for key in figures), result  # None: the figure was not finite
    else:
        assert outcome.code in (2, 3), outcome
    return outcome


class Hang(AssertionError):
    """An example ran longer than :data:`EXAMPLE_SECONDS`."""


@contextlib.contextmanager
def time_limit(seconds: float = EXAMPLE_SECONDS) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` of wall time; a hang inside compiled code, which
    never returns to Python, ends the process with every thread's stack after three times that."""

    def expire(signum: int, frame: Any) -> None:
        raise Hang(f"the example ran longer than {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    faulthandler.dump_traceback_later(3 * seconds, exit=True)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGALRM, previous)


class Runaway(BaseException):
    """A run did more of some work than its bound (:func:`work_limit`). Not an :class:`Exception`: no handler of the
    code under test takes it for one of its own failures."""


def work_limit(
    monkeypatch: Any, owner: type, name: str, most: int, amount: Callable[[Any], int] | None = None
) -> list[int]:
    """Count the work of the calls of the method ``owner.name`` from now to the test's end (``monkeypatch``
    restores it): one per call, or ``amount(instance)`` read after each call (a solver's iterations); the call that
    takes the count past ``most`` raises :class:`Runaway`. A bound on a run's work that the machine's load does not
    move, as a wall-time bound is moved, and that ends a loop going round for ever. Returns the count so far (a
    one-item list)."""
    done = [0]
    method = getattr(owner, name)

    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        result = method(self, *args, **kwargs)
        done[0] += 1 if amount is None else amount(self)
        if done[0] > most:
            raise Runaway(f"{owner.__name__}.{name}: {done[0]} done, past the bound of {most}")
        return result

    monkeypatch.setattr(owner, name, counted)
    return done


# -- outputs that must not be lost ---------------------------------------------------------------------
PRECIOUS = "precious: not pinstab's to overwrite\n"
OUTPUT_STATES = ("absent", "file", "link")  # what an output path is before the command


def prepare_output(path: Path, state: str) -> Path | None:
    """Put ``path`` in ``state`` (absent, an existing file, a symbolic link to one); returns the file that
    holds :data:`PRECIOUS` (None when absent)."""
    path.unlink(missing_ok=True)
    if state == "absent":
        return None
    precious = path if state == "file" else path.with_name(path.name + ".target")
    precious.write_text(PRECIOUS)
    if state == "link":
        path.symlink_to(precious)
    return precious


def assert_not_lost(path: Path, precious: Path | None, state: str, load: Callable[[Path], Any]) -> None:
    """Whatever the command did, nothing is lost or half-written: a link's target keeps its content (the link left
    as it was or replaced by a file); the output path holds its old content or a complete output (``load`` reads
    it)."""
    if precious is not None and state == "link":
        assert precious.read_text() == PRECIOUS, f"the target of the link {path} was overwritten"
    if path.is_symlink() or not path.exists():
        return
    if path.read_bytes() != PRECIOUS.encode():
        load(path)


# -- what a contact scene guarantees ---------------------------------------------------------------------
def plane_contacts(scene: Scene) -> list[PointContact]:
    """The scene's plane contacts."""
    return [constraint for constraint in scene.constraints if isinstance(constraint, PointContact)]


def contact_geometry(scene: Scene, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each plane contact's signed distance from its plane (samples, contacts) [m], negative inside, and its point
    (samples, contacts, 3) [m, world], at the configurations ``q`` (samples, nq), by Pinocchio's frame placements:
    the point of a contact with a radius is its sphere's lowest, the centre less the radius along the normal."""
    data = scene.model.createData()
    contacts = plane_contacts(scene)
    gaps, points = np.zeros((len(q), len(contacts))), np.zeros((len(q), len(contacts), 3))
    for k, configuration in enumerate(q):
        pin.framesForwardKinematics(scene.model, data, configuration)
        for i, contact in enumerate(contacts):
            point = data.oMf[contact.frame_a].translation
            plane = pin.SE3.Identity() if contact.plane_frame is None else data.oMf[contact.plane_frame]
            normal = contact.selection[0]
            gaps[k, i] = normal @ (plane.actInv(point) - contact.plane_point) - contact.radius
            points[k, i] = point - contact.radius * (plane.rotation @ normal)
    return gaps, points


def contact_gaps(scene: Scene, q: np.ndarray) -> np.ndarray:
    """The signed distances of :func:`contact_geometry` (samples, contacts) [m]."""
    return contact_geometry(scene, q)[0]


def mechanical_energy(scene: Scene, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Kinetic plus gravitational energy [J] at each sample, by Pinocchio (gravity of the scene's model)."""
    data = scene.model.createData()
    energy = np.zeros(len(q))
    for k, (configuration, velocity) in enumerate(zip(q, v, strict=True)):
        energy[k] = pin.computeKineticEnergy(scene.model, data, configuration, velocity) + pin.computePotentialEnergy(
            scene.model, data, configuration
        )
    return energy

"""Dask for the sweeps (``bench``, ``sweep``): an embedded LocalCluster or a scheduler's address, the progress bar
over finished work, and SIGINT/SIGTERM deferred until the work in flight is done."""

from __future__ import annotations

import logging
import signal
import sys
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

from ..errors import PinstabError

LOCAL_WORKERS = 2  # processes of the embedded LocalCluster, one thread each


@contextmanager
def dask_client(scheduler: str | None, command: str, install: str) -> Iterator[Any]:
    """A ``distributed.Client`` on an embedded LocalCluster (:data:`LOCAL_WORKERS` processes on 127.0.0.1 ignoring
    SIGINT, its HTTP server on a free port, its workers' logs silenced) or on the scheduler at ``scheduler``
    (``tcp://host:port``); closed (the cluster too) on every exit path, Ctrl-C included; Dask's logs in this process
    silenced meanwhile (its errors are the caller's to name).

    Args:
        scheduler: the scheduler's address, or None for the embedded cluster.
        command: the command named in the errors (``bench``, ``sweep``).
        install: how to install Dask, for the error when it is missing.

    Raises:
        PinstabError: Dask is not installed (saying how to install it), or the scheduler cannot be reached.
    """
    try:
        from distributed import Client, LocalCluster
        from distributed.utils import silence_logging_cmgr
    except ImportError:
        raise PinstabError(f"{command} runs on Dask: {install}") from None
    # the client's own logs too: a scheduler lost logs its reconnection's traceback (the sweep names the loss)
    with silence_logging_cmgr(logging.CRITICAL):
        client, cluster = _connect(Client, LocalCluster, scheduler, command)
        try:
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def _connect(client_type: Any, cluster_type: Any, scheduler: str | None, command: str) -> tuple[Any, Any]:
    """(a client, the embedded LocalCluster or None) of :func:`dask_client`.

    Raises:
        PinstabError: the scheduler cannot be reached.
    """
    cluster = None
    try:
        if scheduler is None:
            with _interrupt_ignored():  # by the workers it starts
                cluster = cluster_type(
                    n_workers=LOCAL_WORKERS,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",  # None still serves HTTP on 8787: a second sweep warned it was taken
                    host="127.0.0.1",
                    silence_logs=logging.CRITICAL,  # a Ctrl-C or SIGTERM: no worker tracebacks on stderr
                )
            return client_type(cluster), cluster
        return client_type(scheduler, timeout=30), None
    except (OSError, ValueError) as exc:  # ValueError: an address Dask cannot parse
        if cluster is not None:
            cluster.close()
        raise PinstabError(
            f"{command}: cannot reach the Dask scheduler {scheduler!r}: {exc} (give tcp://host:port)"
        ) from None


@contextmanager
def _interrupt_ignored() -> Iterator[None]:
    """SIGINT ignored inside the block (main thread only; the handler restored after it). The processes started
    inside inherit the disposition: the local cluster's workers ignore the Ctrl-C that a terminal sends its whole
    foreground process group, so that the points in flight finish (:class:`StopAfterFlight`) and the cluster closes
    them. A Ctrl-C while the cluster starts (a second or two) is lost: press it again."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def progress(
    iterable: Iterable,
    enabled: bool,
    desc: str,
    total: int | None = None,
    initial: int = 0,
    unit: str = "run",
    delay: float = 0.0,
) -> Iterable:
    """``iterable`` behind a tqdm bar on stderr when ``enabled``: its items done (each a ``unit``) of ``total``, from
    ``initial``; shown once it has lasted ``delay`` [s]."""
    if not enabled:
        return iterable
    from tqdm import tqdm

    return tqdm(
        iterable, total=total, initial=initial, desc=desc, unit=unit, file=sys.stderr, mininterval=0.5, delay=delay
    )


class Stopped(KeyboardInterrupt):
    """Work stopped by SIGINT or SIGTERM once its pieces in flight were done (:class:`StopAfterFlight`).

    Attributes:
        kept: what was kept, in words (``12 rows in sweep.csv``), for the message of the exit.
    """

    def __init__(self, kept: str) -> None:
        super().__init__(kept)
        self.kept = kept


class StopAfterFlight:
    """A context manager in which the first SIGINT or SIGTERM asks the work to stop (:attr:`signum`) instead of
    ending it: the caller submits nothing more, lets the work in flight finish and keep its results, then calls
    :meth:`deliver`. A second signal is delivered at once (the work ends where it is). Signals the process ignores
    stay ignored; outside the main thread nothing changes.

    Attributes:
        signum: the signal received, or None.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopAfterFlight:
        if threading.current_thread() is threading.main_thread():
            for signum in self.SIGNALS:
                if signal.getsignal(signum) not in (signal.SIG_IGN, None):
                    self._previous[signum] = signal.signal(signum, self._received)
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self._restore()

    def _received(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is None:
            self.signum = signum
            return
        previous = self._previous.get(signum, signal.SIG_DFL)
        self._restore()
        _handle(signum, previous)

    def _restore(self) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)

    def deliver(self, kept: str) -> None:
        """After the ``with`` block: hand the signal received (if any) to the handler it replaced; the
        KeyboardInterrupt that raises becomes :class:`Stopped` saying what was ``kept``. Under the default action
        (SIGTERM outside the command line) the process ends by the signal."""
        if self.signum is None:
            return
        try:
            _handle(self.signum, self._previous.get(self.signum, signal.SIG_DFL))
        except KeyboardInterrupt as exc:
            raise Stopped(kept) from exc


def _handle(signum: int, handler: Any) -> None:
    """Run ``handler`` for ``signum``: a Python handler called, the default action taken (the handler restored)."""
    if callable(handler):
        handler(signum, None)
    else:
        signal.raise_signal(signum)

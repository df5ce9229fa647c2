"""Dask for the sweeps (``bench``, ``sweep``): an embedded LocalCluster or a scheduler's address, and the
progress bar over finished work."""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any

from ..errors import PinstabError

LOCAL_WORKERS = 2  # processes of the embedded LocalCluster, one thread each


@contextmanager
def dask_client(scheduler: str | None, command: str, install: str) -> Iterator[Any]:
    """A ``distributed.Client`` on an embedded LocalCluster (:data:`LOCAL_WORKERS` processes on 127.0.0.1, no
    dashboard, its workers' logs silenced) or on the scheduler at ``scheduler`` (``tcp://host:port``); closed
    (the cluster too) on every exit path, Ctrl-C included.

    Args:
        scheduler: the scheduler's address, or None for the embedded cluster.
        command: the command named in the errors (``bench``, ``sweep``).
        install: how to install Dask, for the error when it is missing.

    Raises:
        PinstabError: Dask is not installed (saying how to install it), or the scheduler cannot be reached.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise PinstabError(f"{command} runs on Dask: {install}") from None
    cluster = None
    try:
        if scheduler is None:
            cluster = LocalCluster(
                n_workers=LOCAL_WORKERS,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                host="127.0.0.1",
                silence_logs=logging.CRITICAL,  # a Ctrl-C or SIGTERM: no worker tracebacks on stderr
            )
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout=30)
    except (OSError, ValueError) as exc:  # ValueError: an address Dask cannot parse
        if cluster is not None:
            cluster.close()
        raise PinstabError(
            f"{command}: cannot reach the Dask scheduler {scheduler!r}: {exc} (give tcp://host:port)"
        ) from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def progress(iterable: Iterable, enabled: bool, desc: str, total: int | None = None, initial: int = 0) -> Iterable:
    """``iterable`` behind a tqdm bar on stderr (runs finished of ``total``, from ``initial``) when ``enabled``."""
    if not enabled:
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, total=total, initial=initial, desc=desc, unit="run", file=sys.stderr, mininterval=0.5)

"""One BLAS thread while a run computes.

pinstab's dense linear algebra is small (a Jacobian of 80 x 81 at most on the stepping paths, SVDs and
least squares at a singular passage, at the start of a run): OpenBLAS's worker threads do not speed it up, and
after each call they spin waiting for more work, on a core the run does not otherwise use, and their CPU time is
counted against the run. :func:`single_blas_thread` limits every loaded BLAS to one thread for the duration of a
call (``threadpoolctl``; the libraries are found once per process) and restores the user's setting after it.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache, wraps
from typing import ParamSpec, TypeVar

from threadpoolctl import ThreadpoolController

P = ParamSpec("P")
R = TypeVar("R")


@cache
def _controller() -> ThreadpoolController:
    """The BLAS and OpenMP libraries loaded in this process (found once)."""
    return ThreadpoolController()


def single_blas_thread(function: Callable[P, R]) -> Callable[P, R]:
    """``function`` run with every BLAS library limited to one thread."""

    @wraps(function)
    def limited(*args: P.args, **kwargs: P.kwargs) -> R:
        with _controller().limit(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return limited

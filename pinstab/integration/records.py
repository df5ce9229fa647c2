"""The samples a run keeps: all of them in memory (:class:`Records`), or a window of them written to a sink as
the run proceeds (:class:`StreamedRecords`: memory bounded whatever the run's length)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Protocol

import numpy as np


class Grid(Protocol):
    """The time grid of a run (:class:`~pinstab.integration.stepping.TimeGrid`)."""

    steps: int

    def time(self, k: int) -> float: ...

    def times(self, steps: np.ndarray) -> np.ndarray: ...


class SampleSink(Protocol):
    """Where streamed samples go (:class:`~pinstab.stream.StreamWriter`): a file at ``path``."""

    path: Path

    def close(self) -> None: ...

    def write(
        self, start: int, t: np.ndarray, steps: np.ndarray, q: np.ndarray, v: np.ndarray, corrections: np.ndarray
    ) -> None: ...


class Records:
    """The samples a run keeps: steps 0, K, 2K, ... and the last, each with t [s], q, v and the
    correction iterations of that step; one spare slot for a stopped run (see :meth:`end_with`).

    Args:
        grid: the run's time grid. every: K. nq, nv: state dimensions.

    Attributes:
        last: the index of the run's last step's sample. count: the samples kept (fewer when the run stopped
            early). ended: whether :meth:`end_with` ended them.
    """

    offset = 0  # the sample index of the arrays' first slot

    def __init__(self, grid: Grid, every: int, nq: int, nv: int, slots: int | None = None) -> None:
        self.every = every
        self.grid = grid
        self.last = grid.steps // every + (1 if grid.steps % every else 0)
        self.count = self.last + 1
        self.ended = False
        # every sample (zeros: no memory taken before a sample is put), or a window of ``slots``
        self.allocate(self.count + 1 if slots is None else slots, nq, nv)

    def allocate(self, slots: int, nq: int, nv: int) -> None:
        """The arrays of ``slots`` samples."""
        self.steps = np.zeros(slots, dtype=np.int64)
        self.t = np.zeros(slots)
        self.q = np.zeros((slots, nq))
        self.v = np.zeros((slots, nv))
        self.corrections = np.zeros(slots, dtype=int)

    def index(self, k: int) -> int:
        """The sample index of recorded grid step k."""
        return self.last if k == self.grid.steps else k // self.every

    def put(self, index: int, q: np.ndarray, v: np.ndarray, iterations: int = 0) -> None:
        """Keep the state of sample ``index`` (with its grid step and time)."""
        slot = index - self.offset
        step = self.grid.steps if index == self.last else index * self.every
        self.steps[slot], self.t[slot] = step, self.grid.time(step)
        self.q[slot], self.v[slot], self.corrections[slot] = q, v, iterations

    def put_span(self, first: int, q: np.ndarray, v: np.ndarray, iterations: np.ndarray | None = None) -> None:
        """Keep the recorded ones among the states (rows of q, v) of grid steps first, first + 1, ... (with their
        correction ``iterations``, none: 0)."""
        if len(q) == 1:  # one step at a time (a watched run near its singular passages): without the arrays
            if first % self.every == 0 or first == self.grid.steps:
                self.put(self.index(first), q[0], v[0], 0 if iterations is None else int(iterations[0]))
            return
        steps = np.arange(first, first + len(q))
        kept = (steps % self.every == 0) | (steps == self.grid.steps)
        if not kept.any():
            return
        steps = steps[kept]
        indices = np.where(steps == self.grid.steps, self.last, steps // self.every)
        slots = indices - self.offset
        self.steps[slots] = np.where(indices == self.last, self.grid.steps, indices * self.every)
        self.t[slots] = self.grid.times(self.steps[slots])
        self.q[slots], self.v[slots] = q[kept], v[kept]
        self.corrections[slots] = 0 if iterations is None else iterations[kept]

    def checked(self, k: int) -> None:
        """The samples up to grid step k passed the loop's check (they will not be replayed)."""

    def end_with(self, *samples: tuple[int, float, np.ndarray, np.ndarray]) -> None:
        """Keep the samples before the first of ``samples`` (step, t [s], q, v) and end with these (a run
        stopped there: its last good state, then at most one more, the failed step's)."""
        first = samples[0][0]
        index = min(-(-first // self.every), self.last)  # the first sample at or after that step
        for slot, (step, t, q, v) in enumerate(samples, start=self.slot(index)):
            self.steps[slot], self.t[slot], self.q[slot], self.v[slot] = step, t, q, v
        self.count = index + len(samples)
        self.ended = True

    def slot(self, index: int) -> int:
        """The array slot of sample ``index`` (for :meth:`end_with`)."""
        return index

    def kept(self, index: int) -> tuple[int, float]:
        """(grid step, t [s]) of the kept sample ``index``."""
        return int(self.steps[index - self.offset]), float(self.t[index - self.offset])


class StreamedRecords(Records):
    """Records that hold a window of samples and write them to ``sink`` once checked: a block at a time (up to the
    next multiple of ``block``: the file's chunks), or those checked so far once ``period`` of wall time passed since
    the last write.

    Args:
        grid, every, nq, nv: as :class:`Records`. sink: where the samples go. block: samples per write.
        spare: samples a chunk of the loop keeps at most beyond a block. period: the longest wall time between two
            writes [s] (:data:`pinstab.stream.FLUSH_PERIOD`).
    """

    def __init__(
        self, grid: Grid, every: int, nq: int, nv: int, sink: SampleSink, block: int, spare: int, period: float
    ) -> None:
        super().__init__(grid, every, nq, nv, block + spare)
        self.sink, self.block, self.period = sink, block, period
        self.written = time.monotonic()  # when samples were last written [s]
        self.last_written = (0, 0.0)  # (grid step, t [s]) of the last sample written, before the window

    def checked(self, k: int) -> None:
        """Write the checked samples up to the block's end when there is one, or all of them when the last write
        is ``period`` old."""
        final = self.count if k == self.grid.steps else k // self.every + 1
        end = (self.offset // self.block + 1) * self.block
        if final >= end:
            self.write(end)
        elif final > self.offset and time.monotonic() - self.written >= self.period:
            self.write(final)

    def write(self, stop: int) -> None:
        """Write samples offset .. stop - 1 and make room for those after."""
        n = stop - self.offset
        self.sink.write(self.offset, self.t[:n], self.steps[:n], self.q[:n], self.v[:n], self.corrections[:n])
        if n:
            self.last_written = (int(self.steps[n - 1]), float(self.t[n - 1]))
        for array in (self.t, self.steps, self.q, self.v, self.corrections):
            array[: len(array) - n] = array[n:].copy()
        self.offset = stop
        self.written = time.monotonic()

    def slot(self, index: int) -> int:
        """A sample before the window (already written) moves the window back to it: its rows are rewritten."""
        self.offset = min(self.offset, index)
        return index - self.offset

    def kept(self, index: int) -> tuple[int, float]:
        """(grid step, t [s]) of the kept sample ``index``: in the window, or the last one written (the samples
        before it are in the file only). Reading it leaves the window where it is (:meth:`slot` would move it back
        over rows the window no longer holds, and :meth:`finish` would write them again from stale slots: the last
        row of a run whose final write came before its end read t = 0)."""
        return self.last_written if index == self.offset - 1 else super().kept(index)

    def finish(self) -> None:
        """Write the samples kept and not yet written (up to :attr:`count`)."""
        self.write(self.count)

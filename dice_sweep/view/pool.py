"""Worker processes that roll the bands of rows of a zoomed map for ``dice-sweep view``.

The HTTP server answers in threads; ``roll_batch`` holds the GIL while it runs, so rolls go
to a pool of processes and the server stays responsive (a click's roll, a second request).

Not the forked pool of :mod:`dice_sweep.executor`, which every batch command shares: a fork
of the running server would copy its open connections (a client reading a streamed map to
its end would wait for the workers to exit too) and any lock another thread holds at that
moment (a deadlock in the child; Python 3.12 warns about it). These workers are spawned, once:
they live as long as the server, so their start (imports, loading the kernel from numba's
cache) is paid once, not per zoom.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import signal
import sys
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

import numpy as np

_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>
BAND_ROLLS = 4096  # rolls per task at most: progress steps and how soon a cancel acts


class Cancelled(Exception):
    """The map is not wanted any more (the page moved on, or the server is stopping)."""


def _init_worker(mapper, start) -> None:
    # Ctrl-C reaches the whole process group; the server stops the workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):  # a server killed by SIGKILL takes its workers along
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        except (OSError, AttributeError):
            pass
    # load (or, on a cold cache, build) the kernel now rather than at the first zoom
    mapper.with_engine_for(start[np.newaxis, :].copy(), 1, 1).warm_up(start)


def _roll_band(mapper, states: np.ndarray, pixels, draws: int) -> np.ndarray:
    if pixels is None:
        return mapper.roll(states).outcome
    return mapper.roll_draws(states, pixels, draws).outcome


def _nothing() -> None:
    return None


def bands(ny: int, nx: int, workers: int) -> list[tuple[int, int]]:
    """(first row, end row) of the tasks of an (ny, nx) map: whole rows, at most BAND_ROLLS
    rolls each, and at least four per worker, so that progress moves and both cores work."""
    rows = max(1, min(BAND_ROLLS // max(nx, 1), -(-ny // (4 * workers))))
    return [(start, min(start + rows, ny)) for start in range(0, ny, rows)]


class RollPool:
    """``workers`` spawned processes rolling bands of a map's starts with the mapper.

    Parameters
    ----------
    mapper : dice_sweep.mapper.Mapper
        The file's model: every zoom's (a grid changes only starts).
    start : numpy.ndarray
        float64 (6,): a start each worker rolls once to load the kernel (the file's [initial] state).
    workers : int
        Processes, at least 1.
    """

    def __init__(self, mapper, start, workers: int):
        self.workers = max(1, int(workers))
        self._executor = ProcessPoolExecutor(
            self.workers, mp_context=multiprocessing.get_context("spawn"), initializer=_init_worker,
            initargs=(mapper, np.asarray(start, dtype=np.float64))
        )
        self._closed = False

    def start(self) -> None:
        """Start every worker now (a spawned pool starts one per task submitted while none is idle)."""
        for _ in range(self.workers):
            self._executor.submit(_nothing)

    def roll_map(self, mapper, states: np.ndarray, shape: tuple[int, int], on_band=None, cancelled=None,
                 pixels=None, draws: int = 1) -> np.ndarray:
        """Outcomes of the mapper on ``states`` (row-major over ``shape`` = (ny, nx)) as an int8 (ny, nx) map.

        With ``pixels`` (each start's stream number, :func:`dice_sweep.mapper.start_pixels`):
        ``draws`` rolls of each start on its streams (:meth:`Mapper.roll_draws`), an int8
        (ny, nx, draws) map. ``on_band(first_row, end_row, outcome_rows, rolls_done)`` is called
        as each band arrives (in any order); it may raise to stop. ``cancelled()`` is asked
        between bands; True stops with :class:`Cancelled`. Bands not started are dropped either way.
        """
        ny, nx = shape
        draws = 1 if pixels is None else draws
        outcome = np.empty(shape if pixels is None else (*shape, draws), np.int8)
        todo = iter(bands(ny, nx * draws, self.workers))
        pending = {}
        done_rolls = 0

        def submit_next():
            band = next(todo, None)
            if band is not None:
                first, end = band
                cells = slice(first * nx, end * nx)
                band_pixels = None if pixels is None else pixels[cells]
                pending[self._executor.submit(_roll_band, mapper, states[cells], band_pixels, draws)] = band

        try:
            for _ in range(2 * self.workers):  # one running and one queued per worker
                submit_next()
            while pending:
                finished, _ = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                if self._closed or (cancelled is not None and cancelled()):
                    raise Cancelled()
                for future in finished:
                    first, end = pending.pop(future)
                    outcome[first:end] = future.result().reshape(outcome[first:end].shape)
                    done_rolls += (end - first) * nx * draws
                    if on_band is not None:
                        on_band(first, end, outcome[first:end], done_rolls)
                    submit_next()
        finally:
            for future in pending:
                future.cancel()
        return outcome

    def close(self) -> None:
        """Drop queued bands and stop the workers (waits for the bands being rolled)."""
        self._closed = True
        self._executor.shutdown(wait=True, cancel_futures=True)


"""The one worker pool: every way of covering initial conditions runs its rolls here.

The mapper (:mod:`dice_sweep.mapper`) turns starts into sides; the ways of covering a plane
are strategies that hand the pool work (the shape of Attractors.jl's mappers):

- the full grid (dice_sweep.sweep) hands it a :class:`TileTask`, whose tiles' results arrive
  in any order and are written as they come (:func:`tile_results`, local or on a dask cluster);
- quadtree refinement, Monte Carlo control maps and forecast ensembles hand it chunks of
  arbitrary starts (:func:`dice_sweep.mapper.roll_states`, over :func:`ordered_map`);
- the measured-data loop maps its candidate fits over the same workers (:func:`ordered_map`).

Locally, one worker computes in this process; more are forked processes (which share what
the parent loaded or compiled) taking items from a shared counter and sending their results
on a pipe of their own, gathered into one message per SEND_SECONDS (the parent wakes once
per message, not once per item: docs/dev/sweep_time.md). A worker that raises sends its
error and traceback; one that dies ends the run with a one-line error; Ctrl-C stops them all
(:class:`StopRequest`).
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence

from dice_sweep.errors import DiceSweepError

MAX_WORKERS = 1024  # worker processes; more would fork one per tile of a large grid
EXECUTORS = ("local", "dask")
_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>
_STOP_POLL_SECONDS = 0.2  # how often the parent looks for Ctrl-C while workers compute
# A worker's results go to the parent together, one message per this long: each message wakes the
# parent, a third process on the workers' cores, and a tile written right after another costs it
# less (fig08, 2 ms tiles: 0.18-0.25 ms a write instead of 0.31-0.34; docs/dev/sweep_time.md).
# An item slower than this goes alone.
SEND_SECONDS = 0.05


def default_workers() -> int:
    """Default worker count: the cores this process may use.

    The CPU affinity mask, where the OS has one, rather than ``os.cpu_count()``: under SLURM,
    taskset or a container limit it is what the job was given.

    Returns
    -------
    int
    """
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def workers_or_default(workers: int | None) -> int:
    """``workers`` (a count :func:`worker_count` checked), or :func:`default_workers` for None."""
    return default_workers() if workers is None else int(workers)


def worker_count(workers: int | None) -> int:
    """``workers``, or :func:`default_workers` for None; a one-line error outside [1, MAX_WORKERS]."""
    workers = workers_or_default(workers)
    if not 1 <= workers <= MAX_WORKERS:
        raise DiceSweepError(f"--workers: {workers} is outside the allowed range [1, {MAX_WORKERS}]")
    return workers


def parse_shard(text: str) -> tuple[int, int]:
    """``"I/N"`` -> (I, N), with 0 <= I < N.

    Parameters
    ----------
    text : str
        The ``--shard`` argument (which part of a sweep's tiles this process computes; here, not in
        dice_sweep.sweep, so that checking it imports no kernel: docs/dev/speed_issue33.md).

    Returns
    -------
    tuple of int
        (I, N).

    Raises
    ------
    DiceSweepError
        If the text is not of that form.
    """
    try:
        shard_index, shard_count = (int(part) for part in text.split("/"))
    except ValueError:
        raise DiceSweepError(f"--shard {text!r}: expected I/N, e.g. 0/4") from None
    if shard_count < 1 or not 0 <= shard_index < shard_count:
        raise DiceSweepError(f"--shard {shard_index}/{shard_count}: need 0 <= I < N")
    return shard_index, shard_count


def check_executor(executor: str, scheduler: str | None, workers: int | None) -> None:
    """Refuse an executor this pool does not have, and options it does not combine with
    (one line each, naming the option)."""
    if executor not in EXECUTORS:
        raise DiceSweepError(f"--executor {executor!r}: allowed values are {', '.join(EXECUTORS)}")
    if scheduler is not None and executor != "dask":
        raise DiceSweepError("--scheduler: only with --executor dask")
    if scheduler is not None and workers is not None:
        raise DiceSweepError("--workers: not with --scheduler (the dask cluster has its own workers)")


def _die_with_parent(parent_pid: int) -> None:
    # A parent killed by SIGKILL cannot stop its workers, which would compute for nobody;
    # on Linux the kernel can kill them when the parent goes.
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)


def process_context():
    """fork where it exists (the workers share the kernel compiled in the parent); elsewhere
    (macOS, Windows) spawn, which is safe there."""
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    return multiprocessing.get_context(method)


class StopRequest:
    """Ctrl-C as a flag, checked between items, while work runs in the main thread.

    A KeyboardInterrupt raised at an arbitrary point can land in a weakref callback, where
    Python ignores it, or in the middle of an HDF5 write; a flag acts only where we look at
    it. A second Ctrl-C goes to the previous handler and so acts at once.
    """

    def __init__(self):
        self.requested = False
        self._installed = False
        self._previous = signal.SIG_DFL

    def __enter__(self) -> "StopRequest":
        if threading.current_thread() is threading.main_thread():
            previous = signal.signal(signal.SIGINT, self._handle)
            self._previous = signal.SIG_DFL if previous is None else previous
            self._installed = True
        return self

    def _handle(self, signum, frame) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._previous)

    def __exit__(self, *exc_info) -> None:
        if self._installed:
            signal.signal(signal.SIGINT, self._previous)


class _WorkerFailed:
    """What a worker sends instead of a result when computing it raised."""

    def __init__(self, error: BaseException):
        self.traceback = traceback.format_exc()
        try:
            pickle.dumps(error)
            self.error = error
        except Exception:  # an error that cannot cross the pipe is sent as its text
            self.error = RuntimeError(f"{type(error).__name__}: {error}")


class _RemoteTraceback(Exception):
    """The traceback of an error raised in a worker process, as its text."""

    def __str__(self) -> str:
        return "\n" + self.args[0]


def _worker_main(task: Callable, count: int, next_slot, results, parent_pid: int) -> None:
    """A worker process: take the next item number until ``count`` are taken, send the
    [(number, task(number)), ...] computed to the parent on ``results`` once SEND_SECONDS
    have passed since the last message, and when there is nothing left to take."""
    # Ctrl-C reaches the whole process group; only the parent handles it (by stopping us).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent_pid)
    computed, sent = [], time.perf_counter()
    try:
        while True:
            with next_slot.get_lock():
                slot = next_slot.value
                next_slot.value = slot + 1
            if slot >= count:
                break
            computed.append((slot, task(slot)))
            if time.perf_counter() - sent >= SEND_SECONDS:
                results.send(computed)
                computed, sent = [], time.perf_counter()
        if computed:
            results.send(computed)
    except BaseException as error:  # noqa: BLE001 - every failure is reported to the parent
        if computed:  # what was computed before the failure is kept
            results.send(computed)
        results.send(_WorkerFailed(error))
    finally:
        results.close()


@contextlib.contextmanager
def unordered_results(task: Callable, count: int, workers: int, stop: StopRequest, *, after_death: str):
    """Yield an iterator of (k, task(k)) for k in range(count), in completion order.

    One worker computes in this process. More are forked processes that take item numbers
    from a shared counter and each send their results on a pipe of their own: the parent has
    no thread of its own to feed, and spends its CPU (which it shares with the workers) only
    on receiving (concurrent.futures.ProcessPoolExecutor, used before, spent more of it in
    its threads and queues than a sweep's writes took; scripts/bench.py reports the parent's
    CPU). The iterator ends early once ``stop`` is requested. On any exception in the
    ``with`` body the workers are terminated at once. ``task`` must be picklable where
    processes are spawned. ``after_death`` ends the error of a worker that died.
    """
    if workers == 1 or count <= 1:
        yield ((k, task(k)) for k in range(count) if not stop.requested)
        return
    context = process_context()
    next_slot = context.Value("q", 0)
    processes, pipes = [], []
    try:
        for _ in range(min(workers, count)):
            receiving, sending = context.Pipe(duplex=False)
            process = context.Process(target=_worker_main, args=(task, count, next_slot, sending, os.getpid()), daemon=True)
            process.start()
            sending.close()  # the worker's end: once every holder closes it, recv() sees EOF
            processes.append(process)
            pipes.append(receiving)
        yield _received(dict(zip(pipes, processes)), stop, after_death)
    except BaseException:
        for process in processes:
            process.terminate()
        raise
    finally:
        for process in processes:
            process.join()
        for pipe in pipes:
            pipe.close()


def _received(workers: dict, stop: StopRequest, after_death: str) -> Iterator:
    """Results from the workers' pipes ({pipe: process}) as they arrive, until every worker
    has closed its pipe or ``stop`` is requested."""
    while workers and not stop.requested:
        for pipe in multiprocessing.connection.wait(list(workers), timeout=_STOP_POLL_SECONDS):
            if stop.requested:  # stop at once: results computed but not yet received are lost
                return
            try:
                message = pipe.recv()
            except EOFError:  # the worker ran out of items, or died
                process = workers.pop(pipe)
                process.join()
                if process.exitcode != 0:
                    raise DiceSweepError(f"a worker process ended with exit code {process.exitcode} (killed?); {after_death}") from None
                continue
            if isinstance(message, _WorkerFailed):
                raise message.error from _RemoteTraceback(message.traceback)
            for result in message:  # a worker's results since its last message
                if stop.requested:
                    return
                yield result


def ordered_map(task: Callable, count: int, workers: int, on_result: Callable[[int], None] | None = None) -> list:
    """[task(0), ..., task(count - 1)] computed by ``workers`` (1: in this process).

    ``on_result(k)`` is called as each result arrives. Ctrl-C stops the workers and raises
    KeyboardInterrupt here.
    """
    results = [None] * count
    with StopRequest() as stop, unordered_results(task, count, workers, stop, after_death="nothing was kept") as arriving:
        for k, value in arriving:
            results[k] = value
            if on_result is not None:
                on_result(k)
    if stop.requested:
        raise KeyboardInterrupt
    return results


@dataclasses.dataclass(frozen=True)
class TileTask:
    """The work a sweep hands the pool: ``run(index)`` computes tile ``index`` and returns
    what the writer takes, as it is. The pool knows nothing else of a sweep (not its grid,
    kernel or file format), and calls nothing else.

    Attributes
    ----------
    run : callable
        int -> a tile's result. Picklable (a module-level function, or a bound method of a
        picklable object): dask sends it to its workers.
    """

    run: Callable[[int], object]


class _TodoItems:
    """Picklable item function of the local pool: item k is tile ``todo[k]`` of ``task``."""

    def __init__(self, task: TileTask, todo: Sequence[int]):
        self.run = task.run
        self.todo = list(todo)

    def __call__(self, k: int):
        return self.run(self.todo[k])


@contextlib.contextmanager
def tile_results(task: TileTask, todo: Sequence[int], workers: int | None, stop: StopRequest, *, executor: str = "local",
                 scheduler: str | None = None):
    """Yield an iterator of (tile index, ``task.run(index)``) of tiles ``todo``, in
    completion order: forked local workers, or tasks on a dask cluster
    (:mod:`dice_sweep.distributed`)."""
    if executor == "dask" and todo:
        from dice_sweep.distributed import dask_tile_results

        with dask_tile_results(task, todo, stop, scheduler=scheduler, workers=workers) as results:
            yield results
        return
    todo = list(todo)
    after_death = "the tiles written are kept: run the same command with --resume to finish"
    with unordered_results(_TodoItems(task, todo), len(todo), workers, stop, after_death=after_death) as results:
        yield ((todo[k], value) for k, value in results)

"""Adaptive quadtree refinement of a sweep: full resolution only where the outcome changes.

A sweep with ``levels`` L computes its grid of ny x nx cells in L + 1 levels. Level 0 is
the grid coarsened 2^L times on each axis, every cell rolled at its own centre. From level
l - 1 to level l every cell splits into 2 x 2 children. The children of a cell whose outcome
differs from that of any of its 8 neighbours are rolled at their own centres. The children
of any other cell take its value, all its maps included (status, impacts, counters, time),
without a roll. A boundary found at level l can run on into a block that was not refined;
every cell of level l whose outcome then differs from a neighbour's is rolled as well, until
every cell on a boundary at level l was rolled at level l. After level L the map has the config's resolution. ``/simulated`` marks the
pixels rolled at their own centre and ``/refine_level`` says at which level each pixel's value
was rolled (docs/hdf5.md).

What it can miss: a structure that lies wholly inside a cell of some level whose 8
neighbours all agree with it at that level, and that touches no boundary seen at a finer
level (an island smaller than about two cells of that level). docs/chaos.md measures the share of
pixels that differ from a full sweep.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from tqdm import tqdm

from dice_sweep.config import PARAM_UNITS, config_to_toml
from dice_sweep.errors import DiceSweepError
from dice_sweep.physics import COUNT_COLUMNS, STATUS_NAMES
from dice_sweep.storage import SweepAxis, SweepFile, SweepHeader, rolls_to_maps, write_refinement_maps
from dice_sweep.sweep import (
    DEFAULT_TILE_SHAPE,
    SweepInterrupted,
    SweepJob,
    TileGrid,
    _process_context,
    default_workers,
)

CHUNK_ROLLS = 4096  # rolls per batch handed to a worker (and per progress-bar step)
MAX_LEVELS = 12  # 2^12 = 4096 times coarser: more would leave almost no coarse grid


# --- rolling arbitrary states, in parallel ------------------------------------------------

_worker_job: SweepJob | None = None


def _init_worker(job: SweepJob) -> None:
    # Ctrl-C reaches the whole process group; only the parent handles it (as in sweep.py)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _worker_job
    _worker_job = job


def _roll_in_worker(states: np.ndarray) -> tuple[np.ndarray, ...]:
    return _worker_job.roll(states)


def roll_states(job: SweepJob, states, workers: int = 1, on_chunk=None) -> tuple[np.ndarray, ...]:
    """``roll_batch`` on any starts, cut into chunks of ``CHUNK_ROLLS`` over ``workers`` processes.

    Parameters
    ----------
    job : dice_sweep.sweep.SweepJob
        Gives the kernel parameters.
    states : numpy.ndarray
        float (N, 6): starts, columns ``STATE_COLUMNS``.
    workers : int
        Processes; 1 rolls in this one. A roll depends only on its start, so the result does
        not depend on ``workers``.
    on_chunk : callable, optional
        Called with the number of rolls of each finished chunk.

    Returns
    -------
    tuple of numpy.ndarray
        (outcome, status, counts, t_decided) as ``SweepJob.roll`` gives them, in the order
        of ``states``.
    """
    states = np.ascontiguousarray(states, dtype=np.float64)
    chunks = [states[start : start + CHUNK_ROLLS] for start in range(0, len(states), CHUNK_ROLLS)]
    if not chunks:
        return job.roll(states)
    results = []
    for chunk, result in zip(chunks, _rolled_chunks(job, chunks, workers)):
        results.append(result)
        if on_chunk is not None:
            on_chunk(len(chunk))
    return tuple(np.concatenate(parts) for parts in zip(*results))


def _rolled_chunks(job: SweepJob, chunks, workers: int):
    """Yield ``job.roll(chunk)`` for each chunk, in order, computed by ``workers`` processes."""
    if workers == 1 or len(chunks) == 1:
        yield from map(job.roll, chunks)
        return
    job.warm_up()  # compile before forking, so that every worker inherits the kernel
    executor = ProcessPoolExecutor(
        min(workers, len(chunks)), mp_context=_process_context(), initializer=_init_worker, initargs=(job,)
    )
    try:
        yield from executor.map(_roll_in_worker, chunks)
    finally:
        # on Ctrl-C or an error, drop the chunks not started rather than roll them all first
        executor.shutdown(wait=True, cancel_futures=True)


# --- the quadtree -------------------------------------------------------------------------


def boundary_cells(outcome) -> np.ndarray:
    """bool map of the cells whose outcome differs from that of any of their 8 neighbours.

    Parameters
    ----------
    outcome : numpy.ndarray, shape (ny, nx)

    Returns
    -------
    numpy.ndarray
        bool (ny, nx).
    """
    ny, nx = outcome.shape
    flagged = np.zeros((ny, nx), dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == dx == 0:
                continue
            # cell [j, i] against its neighbour [j + dy, i + dx], where that exists
            rows_a, rows_b = slice(max(0, -dy), ny - max(0, dy)), slice(max(0, dy), ny - max(0, -dy))
            cols_a, cols_b = slice(max(0, -dx), nx - max(0, dx)), slice(max(0, dx), nx - max(0, -dx))
            flagged[rows_a, cols_a] |= outcome[rows_a, cols_a] != outcome[rows_b, cols_b]
    return flagged


def level_values(lo: float, hi: float, cells: int) -> np.ndarray:
    """Cell centres ``lo + (i + 0.5) (hi - lo) / cells`` of one level of an axis."""
    return lo + (np.arange(cells) + 0.5) * (hi - lo) / cells


def check_levels(cfg, levels: int) -> tuple[int, int]:
    """(rows, columns) of the coarsest level; refuse levels the grid cannot be halved into.

    Raises
    ------
    DiceSweepError
        If ``levels`` is outside 0 .. ``MAX_LEVELS`` or a grid axis is not divisible by 2^levels.
    """
    if cfg.grid is None:
        raise DiceSweepError(f"{cfg.source}: grid: the config has no [grid] section to sweep")
    if not 0 <= levels <= MAX_LEVELS:
        raise DiceSweepError(f"--refine {levels}: outside the allowed range [0, {MAX_LEVELS}]")
    factor = 2**levels
    for name in ("y", "x"):
        num = getattr(cfg.grid, name).num
        if num % factor:
            raise DiceSweepError(
                f"--refine {levels}: grid.{name}.num = {num} is not divisible by 2^{levels} = {factor} "
                f"(e.g. use {max(factor, num // factor * factor)})"
            )
    return cfg.grid.y.num // factor, cfg.grid.x.num // factor


@dataclasses.dataclass(frozen=True)
class RefinedMaps:
    """The result of :func:`refine_maps`.

    Attributes
    ----------
    maps : dict of str to numpy.ndarray
        The stored (ny, nx) maps by dataset path (as :func:`dice_sweep.storage.rolls_to_maps`).
    refine_level : numpy.ndarray
        uint8 (ny, nx): level whose roll gave each pixel its value (``levels`` = rolled at
        the pixel's own centre).
    levels : int
    rolls : int
        Rolls made, all levels together.
    rolls_per_level : tuple of int
    """

    maps: dict[str, np.ndarray]
    refine_level: np.ndarray
    levels: int
    rolls: int
    rolls_per_level: tuple[int, ...]

    @property
    def simulated(self) -> np.ndarray:
        """bool (ny, nx): pixels rolled at their own centre."""
        return self.refine_level == self.levels

    @property
    def rolls_saved(self) -> float:
        """Share of the rolls of a full sweep that were not made (negative if more were)."""
        return 1.0 - self.rolls / self.refine_level.size


def _roll_cells(job: SweepJob, xs, ys, rows, cols, workers, on_chunk) -> dict[str, np.ndarray]:
    """Roll cells (rows[k], cols[k]) of a level with centres xs, ys; 1-D maps by dataset."""
    states = np.empty((len(rows), len(job.base_state)))
    states[:] = job.base_state
    states[:, job.x_column] = xs[cols]
    states[:, job.y_column] = ys[rows]
    return rolls_to_maps(COUNT_COLUMNS, (len(rows),), *roll_states(job, states, workers, on_chunk))


def refine_maps(cfg, levels: int, *, workers: int = 1, on_chunk=None) -> RefinedMaps:
    """Compute the maps of ``cfg.grid`` by quadtree refinement over ``levels`` levels.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Config whose grid (``num`` divisible by 2^levels on both axes) is the finest level.
    levels : int
        Number of halvings; 0 is a full sweep.
    workers : int
        Worker processes for the rolls.
    on_chunk : callable, optional
        Called with the number of rolls of each finished chunk (progress).

    Returns
    -------
    RefinedMaps
    """
    ny0, nx0 = check_levels(cfg, levels)
    grid = cfg.grid
    job = SweepJob.from_config(cfg)
    rows, cols = np.indices((ny0, nx0)).reshape(2, -1)
    maps = _roll_cells(
        job, level_values(grid.x.min, grid.x.max, nx0), level_values(grid.y.min, grid.y.max, ny0),
        rows, cols, workers, on_chunk,
    )
    maps = {name: values.reshape(ny0, nx0) for name, values in maps.items()}
    refine_level = np.zeros((ny0, nx0), dtype=np.uint8)
    rolls_per_level = [ny0 * nx0]
    for level in range(1, levels + 1):
        refine = np.repeat(np.repeat(boundary_cells(maps["outcome"]), 2, axis=0), 2, axis=1)
        maps = {name: np.repeat(np.repeat(values, 2, axis=0), 2, axis=1) for name, values in maps.items()}
        refine_level = np.repeat(np.repeat(refine_level, 2, axis=0), 2, axis=1)
        xs = level_values(grid.x.min, grid.x.max, refine.shape[1])
        ys = level_values(grid.y.min, grid.y.max, refine.shape[0])
        rolls = 0
        while refine.any():
            # a boundary found at this level can run on into a block that was not refined:
            # follow it there, until every cell on a boundary was rolled at this level
            rows, cols = np.nonzero(refine)
            for name, values in _roll_cells(job, xs, ys, rows, cols, workers, on_chunk).items():
                maps[name][rows, cols] = values
            refine_level[rows, cols] = level
            rolls += len(rows)
            refine = boundary_cells(maps["outcome"]) & (refine_level < level)
        rolls_per_level.append(rolls)
    return RefinedMaps(maps, refine_level, levels, sum(rolls_per_level), tuple(rolls_per_level))


@dataclasses.dataclass(frozen=True)
class RefineSummary:
    """What :func:`run_refined_sweep` did.

    Attributes
    ----------
    path : str
    shape : tuple of int
        (ny, nx) of the finest level.
    levels : int
    rolls : int
        Rolls made.
    simulated : int
        Pixels rolled at their own centre.
    seconds : float
        Wall time.
    """

    path: str
    shape: tuple[int, int]
    levels: int
    rolls: int
    simulated: int
    seconds: float

    def describe(self) -> str:
        """One line for the user."""
        ny, nx = self.shape
        full = ny * nx
        return (
            f"{self.path} ({ny} x {nx}, refined over {self.levels} levels): {self.rolls} rolls "
            f"({100 * self.rolls / full:.1f} % of a full sweep) in {self.seconds:.1f} s, "
            f"{self.simulated} pixels ({100 * self.simulated / full:.1f} %) rolled at their own centre, complete"
        )


def _header(cfg) -> SweepHeader:
    grid = cfg.grid
    axes = {
        name: SweepAxis(axis.param, PARAM_UNITS[axis.param], np.asarray(axis.values(), dtype=np.float64), float(axis.min), float(axis.max))
        for name, axis in (("x", grid.x), ("y", grid.y))
    }
    return SweepHeader(
        config_toml=config_to_toml(cfg),
        sides=cfg.die.sides,
        x=axes["x"],
        y=axes["y"],
        tile_shape=DEFAULT_TILE_SHAPE,
        shard=(0, 1),
        count_columns=COUNT_COLUMNS,
        status_names=STATUS_NAMES,
    )


def write_refined(path, cfg, refined: RefinedMaps) -> None:
    """Write refined maps as a complete sweep file (docs/hdf5.md) plus the refinement maps."""
    header = _header(cfg)
    tiles = TileGrid(header.shape, header.tile_shape)
    with SweepFile.create(path, header, tiles.count) as sweep_file:
        for index in range(tiles.count):
            rows, cols = tiles.bounds(index)
            sweep_file.write_tile(index, rows, cols, {name: values[rows, cols] for name, values in refined.maps.items()})
        write_refinement_maps(sweep_file, refined.refine_level, refined.levels)
        sweep_file.mark_complete()


def run_refined_sweep(cfg, out_path, levels: int, *, workers: int | None = None, progress: bool = True) -> RefineSummary:
    """Sweep ``cfg.grid`` by quadtree refinement and write it to a new HDF5 file.

    The file has the layout of a full sweep (docs/hdf5.md) plus ``/simulated`` and
    ``/refine_level``. It is written only at the end: an interrupted refinement leaves no
    file (and there is no ``--resume``).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
    out_path : str or os.PathLike
        File to create; must not exist.
    levels : int
        Number of halvings of the grid (0 = every pixel rolled).
    workers : int, optional
        Worker processes; default all cores this process may use.
    progress : bool
        Show a tqdm bar on stderr (only when stderr is a terminal).

    Returns
    -------
    RefineSummary

    Raises
    ------
    DiceSweepError
        If the output exists, its folder does not, or the grid cannot be halved ``levels`` times.
    dice_sweep.sweep.SweepInterrupted
        On Ctrl-C (the CLI exits with 130); no file is written.
    """
    started = time.perf_counter()
    check_levels(cfg, levels)
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise DiceSweepError(f"--workers {workers}: need at least 1")
    if os.path.exists(out_path):
        raise DiceSweepError(f"{out_path}: exists; remove it or choose another output file (--refine has no --resume)")
    folder = os.path.dirname(os.path.abspath(out_path))
    if not os.path.isdir(folder):
        raise DiceSweepError(f"{out_path}: folder {folder} does not exist")
    try:
        with tqdm(unit=" rolls", unit_scale=True, desc=os.path.basename(str(out_path)), file=sys.stderr,
                  disable=not (progress and sys.stderr.isatty())) as bar:
            refined = refine_maps(cfg, levels, workers=workers, on_chunk=bar.update)
    except KeyboardInterrupt:
        raise SweepInterrupted(
            f"{out_path}: interrupted; a refined sweep is written only at its end, so nothing was written"
        ) from None
    write_refined(out_path, cfg, refined)
    return RefineSummary(
        str(out_path), refined.refine_level.shape, levels, refined.rolls, int(refined.simulated.sum()),
        time.perf_counter() - started,
    )


def compare_with_full(refined_outcome, full_outcome) -> float:
    """Share of pixels whose outcome differs between a refined and a full map of one grid."""
    refined_outcome, full_outcome = np.asarray(refined_outcome), np.asarray(full_outcome)
    if refined_outcome.shape != full_outcome.shape:
        raise DiceSweepError(f"maps {refined_outcome.shape} and {full_outcome.shape}: not of the same grid")
    return float(np.mean(refined_outcome != full_outcome))


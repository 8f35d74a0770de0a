"""The full grid of initial conditions over the mapper: tiles, shards, the file, resume and merge.

The (ny, nx) grid is cut into tiles of ``tile_shape`` cells (clipped at the edges), numbered
row-major. Shard I of N holds the tiles with ``tile_index % N == I``: interleaved rather than
contiguous so that every shard gets its share of the expensive (chaotic) regions. A tile's
starts go to the mapper (:mod:`dice_sweep.mapper`) as one batch, on the worker pool through
its :class:`~dice_sweep.executor.TileTask`; a roll's result depends only on its own start, so
the maps are bitwise identical for any worker count, shard split and tile order. The grid's
inputs (config, shard, executor options) are checked before they get here (dice_sweep.app).
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from dice_sweep.config import PARAM_UNITS, config_to_toml
from dice_sweep.engine import ENGINE_NUMBA, ENGINE_PLAIN, PROBE_ROLLS
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import StopRequest, TileTask, tile_results, workers_or_default
from dice_sweep.mapper import Mapper, Plane, Rolls
from dice_sweep.physics.layout import COUNT_COLUMNS, STATE_COLUMNS, STATUS_NAMES
from dice_sweep.storage import (
    EncodedTile,
    SweepAxis,
    SweepFile,
    SweepHeader,
    chunk_shape,
    create_whole,
    draws_to_maps,
    encode_rolls,
    encode_tile,
    exists_error,
)

DEFAULT_TILE_SHAPE = (64, 64)
# Grids of at least LARGE_GRID_CELLS cells (1024 x 1024) are cut into tiles of LARGE_TILE_SHAPE:
# a tile costs about 0.8 ms beyond its rolls and encoding (sending, the parent's receiving and
# writing), 10 % of fig08's 64 x 64 tile; a 128 x 128 tile shares it over 4 times the rolls,
# and such a grid still has 64 tiles or more, so the last tile a worker takes is a short tail
# (docs/dev/sweep_time.md).
LARGE_TILE_SHAPE = (128, 128)
LARGE_GRID_CELLS = 64 * LARGE_TILE_SHAPE[0] * LARGE_TILE_SHAPE[1]


class SweepInterrupted(DiceSweepError):
    """The user stopped a sweep (Ctrl-C); what was written is kept and can be resumed.

    The CLI exits with code 130 (the shell's code for SIGINT) instead of 2.
    """


@dataclasses.dataclass(frozen=True)
class SweepSummary:
    """What a call to :func:`run_sweep` or :func:`merge_parts` did.

    Attributes
    ----------
    path : str
        The HDF5 file written.
    shape : tuple of int
        (ny, nx) of the whole grid.
    shard : tuple of int
        (I, N) of the file.
    rolls_computed : int
        Rolls simulated by this call (0 for a merge or an already complete file).
    rolls_in_shard : int
        Rolls the file holds when complete.
    seconds : float
        Wall time of the call, s.
    complete : bool
        True if every tile of the shard is in the file.
    already_complete : bool
        True if the call found the file complete and did nothing.
    merged_parts : int
        Number of shard files a merge joined (0 for a sweep).
    kernel_seconds : float
        Of ``seconds``, the time spent loading or compiling the kernel (a cold start compiles
        for tens of seconds; the rate leaves it out).
    engine : str
        ``numba`` (compiled) or ``plain`` (the kernel's source uncompiled: numba's cache was
        cold and the work smaller than a compile; :mod:`dice_sweep.engine`).
    """

    path: str
    shape: tuple[int, int]
    shard: tuple[int, int]
    rolls_computed: int
    rolls_in_shard: int
    seconds: float
    complete: bool
    already_complete: bool = False
    merged_parts: int = 0
    kernel_seconds: float = 0.0
    engine: str = ENGINE_NUMBA

    def describe(self) -> str:
        """One line for the user."""
        ny, nx = self.shape
        where = f"{self.path} ({ny} x {nx}, shard {self.shard[0]}/{self.shard[1]})"
        if self.already_complete:
            return f"{where} is already complete; nothing to do"
        if self.merged_parts:
            return f"{where}: merged {self.merged_parts} parts in {self.seconds:.1f} s, complete"
        rolling = self.seconds - self.kernel_seconds
        rate = self.rolls_computed / rolling if rolling > 0 else 0.0
        state = "complete" if self.complete else "NOT complete"
        # a compile is not the kernel's speed (make demo on a cold cache said 757 rolls/s)
        if self.engine == ENGINE_PLAIN:
            compiled = ", uncompiled: a compile would take longer than this run"
        elif self.kernel_seconds >= COMPILE_SHOWN:
            compiled = f" after {self.kernel_seconds:.1f} s compiling the kernel"
        else:
            compiled = ""
        return (
            f"{where}: {self.rolls_computed} rolls in {self.seconds:.1f} s "
            f"({rate:.0f} rolls/s{compiled}), {state}"
        )


COMPILE_SHOWN = 1.0  # s: a kernel load this long was a compile (a cached load takes ~0.3 s)


# --- grid --------------------------------------------------------------------------------


def axis_values(axis) -> np.ndarray:
    """Cell centres ``min + (i + 0.5) (max - min) / num`` of a grid axis.

    The one formula is ``dice_sweep.config.Axis.values``; every module that needs the grid's
    values goes through it, so that all agree bitwise.

    Parameters
    ----------
    axis : dice_sweep.config.Axis
        ``param``, ``min``, ``max`` (in the parameter's SI unit) and ``num`` cells.

    Returns
    -------
    numpy.ndarray
        float64 (num,).
    """
    return np.asarray(axis.values(), dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class TileGrid:
    """A (ny, nx) grid cut into tiles of ``tile_shape`` (clipped at the edges), row-major."""

    shape: tuple[int, int]
    tile_shape: tuple[int, int]

    def __post_init__(self):
        if min(self.tile_shape) < 1:
            raise DiceSweepError(f"tile shape {self.tile_shape}: need at least 1 x 1 cells")

    @property
    def tiles_per_row(self) -> int:
        """Number of tile columns."""
        return -(-self.shape[1] // self.tile_shape[1])

    @property
    def count(self) -> int:
        """Number of tiles."""
        return -(-self.shape[0] // self.tile_shape[0]) * self.tiles_per_row

    def bounds(self, index: int) -> tuple[slice, slice]:
        """(rows, cols) slices of tile ``index``."""
        tile_row, tile_col = divmod(index, self.tiles_per_row)
        rows = slice(tile_row * self.tile_shape[0], min((tile_row + 1) * self.tile_shape[0], self.shape[0]))
        cols = slice(tile_col * self.tile_shape[1], min((tile_col + 1) * self.tile_shape[1], self.shape[1]))
        return rows, cols

    def size(self, index: int) -> int:
        """Number of cells of tile ``index``."""
        rows, cols = self.bounds(index)
        return (rows.stop - rows.start) * (cols.stop - cols.start)

    def shard_tiles(self, shard: tuple[int, int]) -> list[int]:
        """Indices of the tiles of shard (I, N): those with ``index % N == I``."""
        shard_index, shard_count = shard
        return list(range(shard_index, self.count, shard_count))


@dataclasses.dataclass(frozen=True, eq=False)
class SweepJob:
    """A grid cut into tiles and the mapper that rolls its cells (picklable and config-free:
    its :meth:`task` carries it to the workers). Build it with :meth:`from_config`.

    With the stochastic impact law (``stochastic``, [scatter] spreads above 0) or ``draws``
    > 1, every cell is rolled ``draws`` times, draw m of cell (row j, column i) on the random
    stream (pixel j nx + i, draw m): a cell's rolls depend on the cell alone, never on the
    tile, shard or worker. ``sides``: the die's n (for the shares of the draws)."""

    mapper: Mapper
    plane: Plane
    xs: np.ndarray
    ys: np.ndarray
    tiles: TileGrid
    draws: int = 1
    stochastic: bool = False
    sides: int = 0

    @classmethod
    def from_config(cls, cfg, tile_shape=None) -> "SweepJob":
        """The job of a config's grid (which the caller has checked it has) cut into tiles of
        ``tile_shape`` (None: :func:`grid_tile_shape`)."""
        tile_shape = grid_tile_shape(cfg) if tile_shape is None else tile_shape
        xs, ys = axis_values(cfg.grid.x), axis_values(cfg.grid.y)
        return cls(Mapper.from_config(cfg), Plane.from_config(cfg), xs, ys, TileGrid((len(ys), len(xs)), tuple(tile_shape)),
                   cfg.scatter.draws, cfg.scatter.on or cfg.scatter.draws > 1, cfg.die.sides)

    def tile_states(self, index: int) -> np.ndarray:
        """Starts of the cells of tile ``index``, row-major."""
        rows, cols = self.tiles.bounds(index)
        return self.plane.grid(self.xs[cols], self.ys[rows])

    def tile_pixels(self, index: int) -> np.ndarray:
        """Pixel numbers (row j, column i -> j nx + i, over the whole grid) of the cells of tile
        ``index``, row-major: their random streams."""
        rows, cols = self.tiles.bounds(index)
        return (np.arange(rows.start, rows.stop)[:, None] * self.tiles.shape[1] + np.arange(cols.start, cols.stop)).ravel()

    def tile_rolls(self, index: int) -> Rolls:
        """The mapper on the cells of tile ``index`` (one batch, in this process); with the
        stochastic law, the ``draws`` rolls of each cell, a cell's draws consecutive."""
        if not self.stochastic:
            return self.mapper.roll(self.tile_states(index))
        return self.mapper.roll_draws(self.tile_states(index), self.tile_pixels(index), self.draws)

    def stored_tile(self, index: int) -> EncodedTile:
        """Tile ``index`` rolled and encoded as the file stores it (:func:`storage.encode_rolls`;
        with ``draws`` > 1, :func:`storage.draws_to_maps`: draw 0 and the shares of the draws)."""
        rows, cols = self.tiles.bounds(index)
        shape = (rows.stop - rows.start, cols.stop - cols.start)
        chunk = chunk_shape(self.tiles.tile_shape, self.tiles.shape)
        if self.draws == 1:
            return encode_rolls(self.tile_rolls(index), shape, chunk, COUNT_COLUMNS)
        maps = draws_to_maps(COUNT_COLUMNS, shape, self.sides, self.draws, *self.tile_rolls(index))
        return encode_tile(maps, chunk, COUNT_COLUMNS, self.sides)

    def task(self) -> TileTask:
        """What the worker pool computes for this job: each tile, stored as the file takes it.

        The workers encode, not the process writing the file: it then only copies bytes
        (storage.EncodedTile: 0.4 instead of 3.1 ms of the writer's CPU per 64 x 64 tile)."""
        return TileTask(self.stored_tile)

    def warm_up(self) -> None:
        """Compile (or load) the kernel in this process (:meth:`Mapper.warm_up` on the
        grid's unswept start), so that forked workers inherit it."""
        self.mapper.warm_up(self.plane.base_state)
        if self.stochastic:  # the kernel with streams is another compile
            self.mapper.roll_draws(self.plane.base_state[None], np.zeros(1, dtype=np.int64), 1)

    def with_engine_for(self, todo: Sequence[int], workers: int) -> "SweepJob":
        """This job on the engine that rolls tiles ``todo`` soonest (:meth:`Mapper.with_engine_for`,
        probed on starts spread over them)."""
        rolls = sum(self.tiles.size(index) for index in todo) * self.draws
        mapper = self.mapper.with_engine_for(lambda: _probe_states(self, todo), rolls, min(workers, max(1, len(todo))))
        return dataclasses.replace(self, mapper=mapper)


def _probe_states(job: SweepJob, todo: Sequence[int], count: int = PROBE_ROLLS) -> np.ndarray:
    """Starts of ``count`` cells spread evenly over the cells of tiles ``todo`` (row-major
    within each tile): what the engine choice times."""
    sizes = np.array([job.tiles.size(index) for index in todo], dtype=np.int64)
    if sizes.sum() == 0:
        return np.empty((0, len(STATE_COLUMNS)))
    offsets = np.linspace(0, sizes.sum() - 1, min(count, int(sizes.sum()))).astype(np.int64)
    ends = np.cumsum(sizes)
    rows, cols = [], []
    for offset in offsets:
        k = int(np.searchsorted(ends, offset, side="right"))
        tile_rows, tile_cols = job.tiles.bounds(todo[k])
        row, col = divmod(int(offset - (ends[k] - sizes[k])), tile_cols.stop - tile_cols.start)
        rows.append(tile_rows.start + row)
        cols.append(tile_cols.start + col)
    return job.plane.cells(job.xs[cols], job.ys[rows])


def default_tile_shape(shape: tuple[int, int]) -> tuple[int, int]:
    """The tiles a (ny, nx) grid is cut into when none are asked for: LARGE_TILE_SHAPE from
    LARGE_GRID_CELLS cells on, else DEFAULT_TILE_SHAPE."""
    return LARGE_TILE_SHAPE if shape[0] * shape[1] >= LARGE_GRID_CELLS else DEFAULT_TILE_SHAPE


def grid_tile_shape(cfg) -> tuple[int, int]:
    """:func:`default_tile_shape` of ``cfg``'s grid."""
    return default_tile_shape((cfg.grid.y.num, cfg.grid.x.num))


# --- sweep -------------------------------------------------------------------------------


def _sweep_axis(axis) -> SweepAxis:
    return SweepAxis(axis.param, PARAM_UNITS[axis.param], axis_values(axis), float(axis.min), float(axis.max))


def sweep_header(cfg, tile_shape=None, shard=(0, 1)) -> SweepHeader:
    """The header of a sweep file of ``cfg`` (its grid, config text, kernel layout), in tiles
    of ``tile_shape`` (None: :func:`grid_tile_shape`)."""
    grid = cfg.grid
    tile_shape = grid_tile_shape(cfg) if tile_shape is None else tile_shape
    return SweepHeader(
        config_toml=config_to_toml(cfg),
        sides=cfg.die.sides,
        x=_sweep_axis(grid.x),
        y=_sweep_axis(grid.y),
        tile_shape=tuple(tile_shape),
        shard=shard,
        count_columns=COUNT_COLUMNS,
        status_names=STATUS_NAMES,
        draws=cfg.scatter.draws,
    )


def _first_difference(text_a: str, text_b: str) -> str:
    """'A-line' vs 'B-line' of the first line where two texts differ."""
    lines_a, lines_b = text_a.splitlines(), text_b.splitlines()
    for line_a, line_b in zip(lines_a + [""] * len(lines_b), lines_b + [""] * len(lines_a)):
        if line_a != line_b:
            return f"{line_a.strip() or '(nothing)'!r} vs {line_b.strip() or '(nothing)'!r}"
    return "no line differs"


def _run_mismatch(mine: SweepHeader, theirs: SweepHeader) -> str | None:
    """Why two headers are not of the same run (None if they are)."""
    if mine.config_toml != theirs.config_toml:
        return f"another config ({_first_difference(mine.config_toml, theirs.config_toml)})"
    if mine.dice_sweep_version != theirs.dice_sweep_version:
        return f"dice_sweep {mine.dice_sweep_version} vs {theirs.dice_sweep_version}"
    if tuple(mine.tile_shape) != tuple(theirs.tile_shape):
        return f"tile shape {mine.tile_shape} vs {theirs.tile_shape}"
    if set(mine.count_columns) != set(theirs.count_columns):
        return f"kernel counters {mine.count_columns} vs {theirs.count_columns}"
    return None


def _check_resumable(path, in_file: SweepHeader, wanted: SweepHeader) -> None:
    reason = _run_mismatch(in_file, wanted)
    if reason is None and in_file.shard != wanted.shard:
        reason = f"shard {in_file.shard[0]}/{in_file.shard[1]} vs {wanted.shard[0]}/{wanted.shard[1]}"
    if reason is not None:
        raise DiceSweepError(
            f"{path}: cannot resume, the file is of a different run (file vs now: {reason}); "
            "use another output file or remove it"
        )


def run_sweep(
    cfg,
    out_path,
    *,
    workers: int | None = None,
    shard: tuple[int, int] = (0, 1),
    resume: bool = False,
    progress: bool = True,
    tile_shape: tuple[int, int] | None = None,
    on_tile: Callable[[int, int], None] | None = None,
    executor: str = "local",
    scheduler: str | None = None,
) -> SweepSummary:
    """Roll every cell of ``cfg.grid`` (or of one shard of it) and write the maps to HDF5.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Validated config with a ``grid`` (:func:`dice_sweep.app.sweep.sweep` checks the
        command's inputs once; this function takes them as checked).
    out_path : str or os.PathLike
        HDF5 file to write (layout: docs/hdf5.md), on a path checked before
        (:func:`dice_sweep.outputs.check_outputs`). Must not exist unless ``resume``.
    workers : int, optional
        Worker processes; default all cores this process may use. 1 computes in-process.
        With ``executor="dask"``: the processes of the local cluster started when no
        ``scheduler`` is given; not allowed with a ``scheduler`` (the cluster has its own).
    shard : tuple of int
        (I, N), 0 <= I < N (:func:`dice_sweep.executor.parse_shard`): compute only the tiles with
        ``tile_index % N == I``.
    resume : bool
        Continue the file ``out_path`` of the same config and shard, computing only the tiles
        it lacks (a missing file is started afresh; a complete one is left alone).
    progress : bool
        Show a tqdm bar on stderr (only when stderr is a terminal).
    tile_shape : tuple of int, optional
        (rows, cols) of a tile: the unit of work, of HDF5 chunking and of resume. None: the
        tiles of the file resumed, else :func:`default_tile_shape` of the grid.
    on_tile : callable, optional
        Called as ``on_tile(tile_index, rolls_computed)`` after each tile is written and
        flushed (``rolls_computed`` counts this call's rolls so far).
    executor : {"local", "dask"}
        "local": forked worker processes on this machine. "dask": tiles are tasks on a
        dask.distributed cluster and this process writes the file as results arrive
        (:mod:`dice_sweep.distributed`; optional dependency, docs/scaling.md).
    scheduler : str, optional
        With ``executor="dask"``: the scheduler's address (``tcp://host:8786``); None starts
        a local cluster.

    Returns
    -------
    SweepSummary

    Raises
    ------
    DiceSweepError
        On an existing file without ``resume``, a file of another run, or a dask cluster
        that cannot be reached or runs another kernel.
    SweepInterrupted
        On Ctrl-C, after stopping the workers; the written tiles are kept.
    """
    started = time.perf_counter()
    workers = workers_or_default(workers)
    path = Path(out_path)
    resuming = path.exists()
    if resuming and not resume:
        raise exists_error(path, "use --resume or remove it")
    if tile_shape is None and resuming:  # a file started with other tiles (an older default) goes on in its own
        with SweepFile.open(path) as existing:
            tile_shape = existing.header.tile_shape
    job = SweepJob.from_config(cfg, tile_shape)
    header = sweep_header(cfg, job.tiles.tile_shape, shard)
    tiles = job.tiles
    shard_tiles = tiles.shard_tiles(shard)

    def tile_rolls(index):  # rolls of a tile: its cells times their draws
        return tiles.size(index) * job.draws

    rolls_in_shard = sum(tile_rolls(index) for index in shard_tiles)

    kernel_seconds = 0.0  # set by the warm-up below; summary reads it when called

    def summary(rolls_computed, complete, already_complete=False):
        return SweepSummary(
            str(path), tiles.shape, shard, rolls_computed, rolls_in_shard,
            time.perf_counter() - started, complete, already_complete, kernel_seconds=kernel_seconds,
            engine=job.mapper.engine,
        )

    done = np.zeros(tiles.count, dtype=bool)
    if resuming:
        with SweepFile.open(path) as existing:
            existing.check_values()  # its tiles are kept as they are: no side the die does not have
            _check_resumable(path, existing.header, header)
            if existing.complete:
                return summary(0, True, already_complete=True)
            done = _tiles_written(existing, tiles)
    todo = [index for index in shard_tiles if not done[index]]
    rolls_todo = sum(tile_rolls(index) for index in todo)

    rolls_computed = 0
    try:
        if executor == "local":
            loading = time.perf_counter()
            job = job.with_engine_for(todo, workers)
            job.warm_up()  # before forking, so that every worker inherits the compiled kernel
            kernel_seconds = time.perf_counter() - loading
        with (
            StopRequest() as stop,  # before forking: workers never see the default handler
            tile_results(job.task(), todo, workers, stop, executor=executor, scheduler=scheduler) as results,
            _open_output(path, header, tiles.count, resuming) as sweep_file,
            _progress_bar(progress, total=rolls_in_shard, initial=rolls_in_shard - rolls_todo, unit=" rolls",
                          unit_scale=True, desc=path.name) as bar,
        ):
            for index, maps in results:
                sweep_file.write_tile(index, *tiles.bounds(index), maps)
                rolls_computed += tile_rolls(index)
                bar.update(tile_rolls(index))
                if on_tile is not None:
                    on_tile(index, rolls_computed)
            complete = bool(sweep_file.done_tiles()[shard_tiles].all())
            if complete:
                sweep_file.mark_complete()
            elif stop.requested:
                raise KeyboardInterrupt  # inside the with: the workers are terminated
    except KeyboardInterrupt:
        raise SweepInterrupted(
            f"{path}: interrupted after {rolls_computed} of {rolls_todo} rolls (what is written "
            "is kept); run the same command with --resume to finish it"
        ) from None
    return summary(rolls_computed, complete)


class _NoBar:
    """What the sweep's loop updates when no bar is shown."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        return None

    def update(self, n=1):
        return None


def _progress_bar(progress: bool, **options):
    """A tqdm bar on stderr when ``progress`` and stderr is a terminal, else one that shows
    nothing. tqdm is imported only for a bar: its import (and its look-up of its own version
    in the installed packages' metadata) is about 20 ms of CPU of every command's fixed start."""
    if not (progress and sys.stderr.isatty()):
        return _NoBar()
    from tqdm import tqdm

    return tqdm(file=sys.stderr, **options)


def _tiles_written(sweep_file: SweepFile, tiles: TileGrid) -> np.ndarray:
    """Tiles recorded as done whose cells all hold data.

    HDF5 does not promise in which order buffered writes reach the disk, so after a kill a
    tile could be recorded without its data; such a tile is computed again.
    """
    recorded, computed = sweep_file.done_tiles(), sweep_file.computed()
    return np.array([recorded[i] and computed[tiles.bounds(i)].all() for i in range(tiles.count)], dtype=bool)


def _open_output(path, header: SweepHeader, n_tiles: int, resuming: bool) -> SweepFile:
    if resuming:
        return SweepFile.open(path, writable=True)
    return SweepFile.create(path, header, n_tiles)


# --- merge -------------------------------------------------------------------------------


def _check_parts(parts: Sequence[SweepFile]) -> None:
    """Refuse parts of different runs, incomplete parts, and overlapping or missing shards."""
    first = parts[0]
    shard_count = first.header.shard[1]
    owners: dict[int, str] = {}
    for part in parts:
        reason = _run_mismatch(first.header, part.header)
        if reason is not None:
            raise DiceSweepError(f"{part.path}: not a part of the same sweep as {first.path} ({reason})")
        shard_index, count = part.header.shard
        if count != shard_count:
            raise DiceSweepError(
                f"{part.path}: shard {shard_index}/{count}, but {first.path} is one of {shard_count} shards"
            )
        if not part.complete:
            raise DiceSweepError(f"{part.path}: not complete; finish it with --resume first")
        if shard_index in owners:
            raise DiceSweepError(
                f"{owners[shard_index]} and {part.path} are both shard {shard_index}/{shard_count}"
            )
        owners[shard_index] = str(part.path)
    missing = [f"{index}/{shard_count}" for index in range(shard_count) if index not in owners]
    if missing:
        raise DiceSweepError(f"merge: shards missing: {', '.join(missing)}")


def merge_parts(part_paths: Sequence, out_path) -> SweepSummary:
    """Join the complete shard files of one sweep into one complete file.

    Parameters
    ----------
    part_paths : sequence of str or os.PathLike
        One file per shard I/N, I = 0..N-1, all of the same config.
    out_path : str or os.PathLike
        The merged file to create; its maps equal those of an unsharded run, bitwise.

    Returns
    -------
    SweepSummary

    Raises
    ------
    DiceSweepError
        If ``out_path`` (a path checked before, :func:`dice_sweep.outputs.check_outputs`)
        exists, or the parts are of different runs, incomplete, overlapping or leave shards
        missing.
    """
    started = time.perf_counter()
    if not part_paths:
        raise DiceSweepError("merge: no part files given")
    path = Path(out_path)
    if path.exists():
        raise exists_error(path, "remove it or choose another output file")
    with contextlib.ExitStack() as stack:
        parts = [stack.enter_context(SweepFile.open(part_path)) for part_path in part_paths]
        _check_parts(parts)
        for part in parts:
            part.check_values()
        header = dataclasses.replace(parts[0].header, shard=(0, 1))
        tiles = TileGrid(header.shape, header.tile_shape)
        with create_whole(path, header, tiles.count) as merged:
            for part in parts:
                for index in tiles.shard_tiles(part.header.shard):
                    bounds = tiles.bounds(index)
                    merged.write_tile(index, *bounds, part.read_tile(*bounds))  # chunks copied as they are
            merged.mark_complete()
    n_rolls = tiles.shape[0] * tiles.shape[1]
    seconds = time.perf_counter() - started
    return SweepSummary(str(path), tiles.shape, (0, 1), 0, n_rolls, seconds, True, merged_parts=len(parts))

"""The mapper: initial conditions and a model in, the side each start lands on out.

Its one job (Attractors.jl's ``AttractorMapper``): any array of starts, plus the kernel's
parameters of a config, gives each start's side (-1: no answer) and the kernel's status,
counters and decision time, in this process (:meth:`Mapper.roll`) or on the one worker pool
(:func:`roll_states`). Every way of covering initial conditions hands it its starts: the
full grid (dice_sweep.sweep), quadtree refinement (dice_sweep.refine), Monte Carlo control
maps (dice_sweep.chaos.control), forecast ensembles (dice_sweep.measured.forecast), the
explorer (dice_sweep.view) and the reference comparisons (dice_sweep.reference).

Each batch of starts is one ``roll_batch`` call on whole arrays: no Python per roll. A roll
depends only on its own start, so the result does not depend on the batch it came in, the
chunking or the worker count.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from dice_sweep.engine import ENGINE_NUMBA, ENGINE_PLAIN, sweep_engine
from dice_sweep.engine import run as engine_run
from dice_sweep.executor import ordered_map
from dice_sweep.physics import pack_params, roll_batch
from dice_sweep.physics.kernel import roll_batch_streams
from dice_sweep.physics.layout import COUNT_COLUMNS, STATE_COLUMNS
from dice_sweep.physics.scatter import off_grid_streams
from dice_sweep.roll import initial_state

CHUNK_ROLLS = 4096  # rolls per batch handed to a worker (and per progress step)


class Rolls(NamedTuple):
    """What the kernel says about N starts, in their order.

    Attributes
    ----------
    outcome : numpy.ndarray
        int8 (N,): side 0..n-1, -1 = no answer.
    status : numpy.ndarray
        uint8 (N,): 0 decided, other codes in ``STATUS_NAMES``.
    counts : numpy.ndarray
        int32 (N, len(COUNT_COLUMNS)): the kernel's counters.
    t_decided : numpy.ndarray
        float64 (N,): simulated time of the decision, s (NaN if none).
    """

    outcome: np.ndarray
    status: np.ndarray
    counts: np.ndarray
    t_decided: np.ndarray


def _empty_rolls(n_rolls: int) -> Rolls:
    """Output arrays of ``n_rolls`` rolls, for ``roll_batch`` to fill."""
    return Rolls(np.empty(n_rolls, np.int8), np.empty(n_rolls, np.uint8),
                 np.empty((n_rolls, len(COUNT_COLUMNS)), np.int32), np.empty(n_rolls))


@dataclasses.dataclass(frozen=True, eq=False)
class Mapper:
    """A model (the kernel's parameter vectors) and the engine that runs it; picklable and
    config-free, so workers get it whole. Build it with :meth:`from_config`."""

    fpar: np.ndarray
    ipar: np.ndarray
    engine: str = ENGINE_NUMBA  # dice_sweep.engine: "plain" runs the kernel's source uncompiled

    @classmethod
    def from_config(cls, cfg) -> "Mapper":
        """The mapper of a validated config's die, contact law, effects and integrator."""
        fpar, ipar = pack_params(cfg)
        return cls(fpar, ipar)

    def roll(self, states, engine: str | None = None, streams=None) -> Rolls:
        """One ``roll_batch`` call on every start, in this process.

        Parameters
        ----------
        states : numpy.ndarray
            float64 (N, 6), columns ``STATE_COLUMNS``, SI.
        engine : str, optional
            Overrides the mapper's engine for this call.
        streams : numpy.ndarray, optional
            float64 (N, 2): each start's random stream (pixel, draw) for the stochastic impact
            law (``roll_batch_streams``); None: ``roll_batch``, every roll on stream (0, 0).

        Returns
        -------
        Rolls
        """
        rolls = _empty_rolls(len(states))
        if streams is None:
            engine_run(roll_batch, engine or self.engine, self.fpar, self.ipar, states, *rolls)
        else:
            engine_run(roll_batch_streams, engine or self.engine, self.fpar, self.ipar, states,
                       np.ascontiguousarray(streams, dtype=np.float64), *rolls)
        return rolls

    def roll_draws(self, states, pixels, draws: int, engine: str | None = None) -> Rolls:
        """``draws`` rolls of each start under the stochastic impact law, start k's draw m on
        the random stream (``pixels[k]``, m), in this process.

        Parameters
        ----------
        states : numpy.ndarray
            float64 (N, 6), columns ``STATE_COLUMNS``, SI.
        pixels : array_like of int
            (N,): each start's stream number, 0 <= pixel < 2^53 (a sweep: its pixel j nx + i).
        draws : int
            Rolls per start.

        Returns
        -------
        Rolls
            N * draws rolls, start-major: rows k draws .. (k + 1) draws - 1 are start k's.
        """
        return self.roll(np.repeat(np.asarray(states, dtype=np.float64), draws, axis=0), engine,
                         streams=draw_streams(pixels, draws))

    def with_engine_for(self, states, rolls: int, workers: int) -> "Mapper":
        """This mapper on the engine that finishes ``rolls`` rolls like ``states`` (an array,
        or a callable giving one when a probe needs them) soonest
        (:func:`dice_sweep.engine.sweep_engine`): compiled when numba has the kernel, plain
        when the work is smaller than a compile."""
        # numba looks the compiled kernel up by the arguments' types only
        probe_args = (self.fpar, self.ipar, np.zeros((1, len(STATE_COLUMNS))), *_empty_rolls(1))
        engine = sweep_engine(roll_batch, probe_args, lambda batch: self.roll(batch, ENGINE_PLAIN), states, rolls, workers)
        return dataclasses.replace(self, engine=engine)

    def warm_up(self, start) -> None:
        """Compile (or load) the kernel in this process by rolling ``start`` (float64 (6,))
        once (with the plain engine: build its functions), so that forked workers inherit it."""
        self.roll(np.array(start, dtype=np.float64).reshape(1, len(STATE_COLUMNS)))


def draw_streams(pixels, draws: int) -> np.ndarray:
    """float64 (N * draws, 2): the streams (pixel, draw) of ``draws`` draws of each of the
    ``pixels``, pixel-major (:meth:`Mapper.roll_draws`)."""
    pixels = np.asarray(pixels, dtype=np.int64)
    return np.column_stack([np.repeat(pixels, draws), np.tile(np.arange(draws), len(pixels))]).astype(np.float64)


def _index_on(grid, values) -> np.ndarray:
    """Index of each value in the ascending ``grid`` where it is one of its values bit for bit, else -1."""
    index = np.clip(np.searchsorted(grid, values), 0, len(grid) - 1)
    return np.where(grid[index] == values, index, -1)


def start_pixels(grid_xs, grid_ys, xs, ys) -> np.ndarray:
    """int64 (N,): the stream numbers of starts (xs[k], ys[k]) rolled for a sweep whose grid
    has cell centres ``grid_xs`` (columns) and ``grid_ys`` (rows), both ascending: a start on a
    cell's centre (both values equal to the grid's bit for bit) has that cell's pixel
    j nx + i, the stream the sweep rolls it on; any other start a number in [2^52, 2^53)
    hashed from the bits of its two values (:func:`dice_sweep.physics.scatter.off_grid_streams`),
    never a pixel's, the same in every map it is rolled in (a zoom, a refinement level)."""
    grid_xs, grid_ys = np.asarray(grid_xs, dtype=np.float64), np.asarray(grid_ys, dtype=np.float64)
    xs = np.ascontiguousarray(xs, dtype=np.float64) + 0.0  # + 0.0: -0.0 and 0.0 are one start, one stream
    ys = np.ascontiguousarray(ys, dtype=np.float64) + 0.0
    pixels = np.empty(len(xs), dtype=np.int64)
    off_grid_streams(xs.view(np.uint64), ys.view(np.uint64), pixels)
    cols, rows = _index_on(grid_xs, xs), _index_on(grid_ys, ys)
    on_grid = (cols >= 0) & (rows >= 0)
    pixels[on_grid] = rows[on_grid] * len(grid_xs) + cols[on_grid]
    return pixels


class _ChunkRoll:
    """Picklable task of the pool: item k is ``mapper.roll`` of chunk k (with its streams)."""

    def __init__(self, mapper: Mapper, chunks, streams=None):
        self.mapper = mapper
        self.chunks = chunks
        self.streams = streams

    def __call__(self, k: int) -> Rolls:
        return self.mapper.roll(self.chunks[k], streams=None if self.streams is None else self.streams[k])


def roll_states(mapper: Mapper, states, workers: int = 1, on_chunk=None, streams=None) -> Rolls:
    """The mapper on any starts, cut into chunks of ``CHUNK_ROLLS`` over ``workers`` processes
    (the one worker pool, :func:`dice_sweep.executor.ordered_map`), on the engine that
    finishes them soonest.

    Parameters
    ----------
    mapper : Mapper
    states : array_like
        float (N, 6): starts, columns ``STATE_COLUMNS``.
    workers : int
        Processes; 1 rolls in this one. The result does not depend on it.
    on_chunk : callable, optional
        Called with the number of rolls of each finished chunk.
    streams : array_like, optional
        float (N, 2): each start's random stream (pixel, draw), see :meth:`Mapper.roll`.

    Returns
    -------
    Rolls
        In the order of ``states``.
    """
    states = np.ascontiguousarray(states, dtype=np.float64)
    chunks = [states[start : start + CHUNK_ROLLS] for start in range(0, len(states), CHUNK_ROLLS)]
    stream_chunks = None
    if streams is not None:
        streams = np.ascontiguousarray(streams, dtype=np.float64)
        stream_chunks = [streams[start : start + CHUNK_ROLLS] for start in range(0, len(states), CHUNK_ROLLS)]
    mapper = mapper.with_engine_for(states, len(states), min(workers, max(1, len(chunks))))
    if not chunks:
        return mapper.roll(states, streams=streams)
    if workers > 1 and len(chunks) > 1:
        mapper.warm_up(states[0])  # compile before forking, so that every worker inherits the kernel
        if streams is not None:
            mapper.roll(states[:1], streams=streams[:1])
    done = None if on_chunk is None else (lambda k: on_chunk(len(chunks[k])))
    results = ordered_map(_ChunkRoll(mapper, chunks, stream_chunks), len(chunks), workers, on_result=done)
    return Rolls(*(np.concatenate(parts) for parts in zip(*results)))


# --- starts on a plane of two initial values ------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Plane:
    """Starts that differ from ``base_state`` in two columns: the x and y of a grid's cells.

    Build it with :meth:`from_config` (the config's [initial] state, its grid's two columns).
    """

    base_state: np.ndarray
    x_column: int
    y_column: int

    @classmethod
    def from_config(cls, cfg) -> "Plane":
        """The plane of a config's ``[grid]`` (which the caller has checked it has)."""
        return cls(initial_state(cfg), STATE_COLUMNS.index(cfg.grid.x.param), STATE_COLUMNS.index(cfg.grid.y.param))

    def cells(self, x_values, y_values) -> np.ndarray:
        """Starts of the cells (x_values[k], y_values[k]): float64 (N, 6)."""
        states = np.empty((len(x_values), len(STATE_COLUMNS)))
        states[:] = self.base_state
        states[:, self.x_column] = x_values
        states[:, self.y_column] = y_values
        return states

    def grid(self, xs, ys) -> np.ndarray:
        """Starts of every cell of the grid xs x ys, row-major (y slow, x fast), as the maps
        are stored: float64 (len(ys) * len(xs), 6)."""
        xs, ys = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
        return self.cells(np.tile(xs, len(ys)), np.repeat(ys, len(xs)))


def initial_states(cfg, xs, ys) -> np.ndarray:
    """Starts of the grid cells of ``cfg`` with axis values xs (fast) and ys (slow).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Gives the swept parameters (``cfg.grid``) and the unswept ones (``cfg.initial``).
    xs, ys : array_like
        Values of ``cfg.grid.x.param`` and ``cfg.grid.y.param``.

    Returns
    -------
    numpy.ndarray
        float64 (len(ys) * len(xs), 6), columns ``STATE_COLUMNS``, row-major (y slow, x fast).
    """
    return Plane.from_config(cfg).grid(xs, ys)

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

Where boundaries cover most of the map (a chaotic region, or a grid too small for its levels)
refinement rolls more than the full grid would: every level rolls again the cells the level
before rolled. Before each level the rolls still to come are estimated from the share of cells
on a boundary now and its change since the level before (:func:`estimated_rolls`); when the
estimate reaches the rolls of the full grid, the full grid is rolled instead (every pixel at
its own centre, as a full sweep) and the sweep says so.

At the last level a pixel stays filled only where refinement has shown its region holds one
side (:func:`unproven_cells`, issue 33): pixels on the map's edge are rolled, and every
pixel within THIN_BUFFER pixels of a rolled pixel on a boundary, again around each boundary
that turns up, so that a filled region lies inside a ring of rolled pixels of its own side,
away from boundaries. What it can still miss: an island of another side wholly inside a filled
region, more than THIN_BUFFER pixels from every boundary seen, between the coarse cells'
centres. docs/chaos.md measures the pixels that differ from a full sweep on every paper config.

A probability sweep (``[scatter] draws`` M > 1) is refined by the same rule on the side that
all M draws of a cell end on: a cell whose draws do not all agree (p < 1 for every side) is
UNSURE, on a boundary whatever its neighbours, so its children are always rolled and never
filled, and the thin-feature buffer grows around it as around any boundary. A filled pixel
therefore carries p = 1 for one side from a cell whose every draw ended there. A cell is rolled
M times on the streams :func:`dice_sweep.mapper.start_pixels` gives its start: at the last
level a pixel's own (j nx + i, as the full sweep's), at coarser levels streams no pixel has.
One draw of a random law (spreads above 0, draws = 1) has no p = 1 to see and is refused
(:func:`check_refinable`).
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time

import numpy as np
from tqdm import tqdm

from dice_sweep.config import cell_centres
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import workers_or_default
from dice_sweep.mapper import Mapper, Plane, draw_streams, roll_states, start_pixels
from dice_sweep.physics.layout import COUNT_COLUMNS
from dice_sweep.storage import (
    NO_ANSWER,
    PROBABILITY_PREFIX,
    create_whole,
    draws_to_maps,
    exists_error,
    rolls_to_maps,
    write_refinement_maps,
)
from dice_sweep.sweep import SweepInterrupted, TileGrid, sweep_header

MAX_LEVELS = 12  # 2^12 = 4096 times coarser: more would leave almost no coarse grid
PRIOR_GROWTH = 0.5  # change of the boundary share per level before two levels are seen: a smooth boundary's halves
# Cells of the last level (pixels) around a boundary that are rolled whatever their parents
# said: a chaotic boundary sheds islands and filaments thinner than the coarse spacing next to
# it. With 3, fig13 at 1024^2 still differed from the full sweep in 144 pixels (0.0137 %),
# 57 of them 4 pixels from a boundary; docs/chaos.md, "Adaptive refinement", measures 4.
THIN_BUFFER = 4
UNSURE = -3  # label of a cell whose draws do not all end alike (no outcome code: sides >= 0, no answer -1)


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


def sure_outcome(maps) -> np.ndarray:
    """(ny, nx) labels refinement compares: a map of one roll per cell, its outcome; a
    probability map, the outcome all of a cell's draws end on, :data:`UNSURE` where they differ."""
    if NO_ANSWER not in maps:
        return maps["outcome"]
    shares = [maps[name] for name in maps if name.startswith(PROBABILITY_PREFIX)] + [maps[NO_ANSWER]]
    return np.where(np.max(shares, axis=0) == 1.0, maps["outcome"], UNSURE)


def refine_boundary(labels) -> np.ndarray:
    """bool map of the cells refinement treats as on a boundary: those whose label differs from a
    neighbour's (:func:`boundary_cells`), and every :data:`UNSURE` one."""
    return boundary_cells(labels) | (np.asarray(labels) == UNSURE)


def check_refinable(cfg) -> None:
    """Refuse ``--refine`` for one draw per cell of a random law (module docstring)."""
    if cfg.scatter.on and cfg.scatter.draws == 1:
        raise DiceSweepError(f"--refine: {cfg.source}: [scatter] draws = 1 with spreads above 0 is one draw of a random law, "
                             "with no region of one sure side to fill (allowed with --refine: draws > 1, or spreads and floors 0)")


def level_values(lo: float, hi: float, cells: int) -> np.ndarray:
    """Cell centres of one level of an axis (:func:`dice_sweep.config.cell_centres`)."""
    return cell_centres(lo, hi, cells)


def check_levels(cfg, levels: int) -> tuple[int, int]:
    """(rows, columns) of the coarsest level; refuse levels the grid cannot be halved into
    (the ``--refine`` check, made once, by dice_sweep.app.sweep).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        A config with a grid.
    levels : int

    Raises
    ------
    DiceSweepError
        If ``levels`` is outside 0 .. ``MAX_LEVELS`` or a grid axis is not divisible by 2^levels.
    """
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
    return coarse_shape(cfg.grid, levels)


def coarse_shape(grid, levels: int) -> tuple[int, int]:
    """(rows, columns) of the coarsest level of ``grid`` halved ``levels`` times (checked by
    :func:`check_levels`)."""
    return grid.y.num // 2**levels, grid.x.num // 2**levels


@dataclasses.dataclass(frozen=True)
class RefinedMaps:
    """The result of :func:`refine_maps`.

    Attributes
    ----------
    maps : dict of str to numpy.ndarray
        The stored (ny, nx) maps by map name (as :func:`dice_sweep.storage.rolls_to_maps`).
    refine_level : numpy.ndarray
        uint8 (ny, nx): level whose roll gave each pixel its value (``levels`` = rolled at
        the pixel's own centre).
    levels : int
    rolls : int
        Rolls made, all levels together.
    rolls_per_level : tuple of int
    decision : str
        One line: refined, or why the full grid was rolled instead.
    fell_back : bool
        True if refinement was given up for the full grid (every pixel then at ``levels``).
    """

    maps: dict[str, np.ndarray]
    refine_level: np.ndarray
    levels: int
    rolls: int
    rolls_per_level: tuple[int, ...]
    decision: str = ""
    fell_back: bool = False

    @property
    def simulated(self) -> np.ndarray:
        """bool (ny, nx): pixels rolled at their own centre."""
        return self.refine_level == self.levels

    @property
    def rolls_saved(self) -> float:
        """Share of the rolls of a full sweep that were not made (negative if more were)."""
        return 1.0 - self.rolls / self.refine_level.size


def estimated_rolls(share: float, previous_share: float | None, cells_next: int, levels_left: int) -> int:
    """Rolls the levels still to come would take, estimated before the next level.

    The next level rolls the children of the cells now on a boundary (``share`` of this
    level's cells; a share of its ``cells_next`` cells), more where boundaries run on. The
    share is taken to change by the same factor per level as from the level before (at most
    1: boundaries of dimension d cover a share that falls as 2^(d-2) per level), by
    :data:`PRIOR_GROWTH` before two levels are seen.

    Parameters
    ----------
    share, previous_share : float
        Shares of cells on a boundary at this level and at the level before (None at level 0).
    cells_next : int
        Cells of the next level.
    levels_left : int
        Levels still to roll, the next one included.

    Returns
    -------
    int
    """
    growth = PRIOR_GROWTH if not previous_share else min(share / previous_share, 1.0)
    return int(sum(cells_next * 4**k * min(1.0, share * growth**k) for k in range(levels_left)))


@dataclasses.dataclass(frozen=True, eq=False)
class _Cells:
    """How refinement rolls cells: the mapper and plane, and for a probability sweep its draws
    per cell, the full grid's centres (each start's streams) and the die's sides."""

    mapper: Mapper
    plane: Plane
    draws: int = 1
    stochastic: bool = False
    grid_xs: np.ndarray = None
    grid_ys: np.ndarray = None
    sides: int = 0

    @classmethod
    def from_config(cls, cfg) -> "_Cells":
        grid = cfg.grid
        return cls(Mapper.from_config(cfg), Plane.from_config(cfg), cfg.scatter.draws, cfg.scatter.on or cfg.scatter.draws > 1,
                   level_values(grid.x.min, grid.x.max, grid.x.num), level_values(grid.y.min, grid.y.max, grid.y.num),
                   cfg.die.sides)

    @property
    def each(self) -> str:
        """What a roll of a cell is, for the lines on stderr: M draws in a probability sweep."""
        return f" (a roll of a cell: its {self.draws} draws)" if self.draws > 1 else ""

    def roll(self, xs, ys, rows, cols, workers, on_chunk) -> dict[str, np.ndarray]:
        """Roll cells (rows[k], cols[k]) of a level with centres xs, ys; 1-D maps by dataset."""
        states = self.plane.cells(xs[cols], ys[rows])
        if not self.stochastic:
            return rolls_to_maps(COUNT_COLUMNS, (len(rows),), *roll_states(self.mapper, states, workers, on_chunk))
        streams = draw_streams(start_pixels(self.grid_xs, self.grid_ys, xs[cols], ys[rows]), self.draws)
        rolls = roll_states(self.mapper, np.repeat(states, self.draws, axis=0), workers, on_chunk, streams=streams)
        if self.draws == 1:
            return rolls_to_maps(COUNT_COLUMNS, (len(rows),), *rolls)
        return draws_to_maps(COUNT_COLUMNS, (len(rows),), self.sides, self.draws, *rolls)


def refine_maps(cfg, levels: int, *, workers: int = 1, on_chunk=None, fallback: bool = True, log=None) -> RefinedMaps:
    """Compute the maps of ``cfg.grid`` by quadtree refinement over ``levels`` levels, or by
    rolling the full grid once the refinement cannot save rolls (module docstring).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        Config whose grid (``num`` divisible by 2^levels on both axes) is the finest level.
    levels : int
        Number of halvings (:func:`check_levels`); 0 is a full sweep.
    workers : int
        Worker processes for the rolls.
    on_chunk : callable, optional
        Called with the number of rolls of each finished chunk (progress).
    fallback : bool
        Roll the full grid instead once the estimated rolls left reach its rolls (False:
        always refine, e.g. to measure refinement itself).
    log : callable, optional
        Called with :attr:`RefinedMaps.decision` as soon as it is made.

    Returns
    -------
    RefinedMaps
    """
    grid = cfg.grid
    ny0, nx0 = coarse_shape(grid, levels)
    full = grid.y.num * grid.x.num
    cells = _Cells.from_config(cfg)
    maps = _roll_level(cells, grid, (ny0, nx0), workers, on_chunk)
    refine_level = np.zeros((ny0, nx0), dtype=np.uint8)
    rolls_per_level = [ny0 * nx0]
    previous_share = None
    for level in range(1, levels + 1):
        boundary = refine_boundary(sure_outcome(maps))
        share = float(boundary.mean())
        estimate = estimated_rolls(share, previous_share, 4 * boundary.size, levels - level + 1)
        if fallback and estimate >= full:
            decision = (
                f"--refine {levels}: rolled the full {grid.y.num} x {grid.x.num} grid instead, after level {level - 1}: "
                f"{100 * share:.0f} % of its cells lie on a boundary, so refining would take about {estimate} more "
                f"rolls, the full grid {full}{cells.each}"
            )
            if log is not None:
                log(decision)
            maps = _roll_level(cells, grid, (grid.y.num, grid.x.num), workers, on_chunk)
            refine_level = np.full(maps["outcome"].shape, levels, dtype=np.uint8)
            rolls_per_level += [0] * (levels - level) + [full]
            return RefinedMaps(maps, refine_level, levels, sum(rolls_per_level), tuple(rolls_per_level), decision, True)
        previous_share = share
        refine = np.repeat(np.repeat(boundary, 2, axis=0), 2, axis=1)
        maps = {name: np.repeat(np.repeat(values, 2, axis=0), 2, axis=1) for name, values in maps.items()}
        refine_level = np.repeat(np.repeat(refine_level, 2, axis=0), 2, axis=1)
        xs = level_values(grid.x.min, grid.x.max, refine.shape[1])
        ys = level_values(grid.y.min, grid.y.max, refine.shape[0])
        rolls = _roll_and_follow(refine, maps, refine_level, level, cells, xs, ys, workers, on_chunk)
        while level == levels:
            # the last level: until no filled cell lies near a boundary or on the map's edge
            # (a boundary found there grows the buffer, so look again after each round)
            unproven = unproven_cells(sure_outcome(maps), refine_level < level)
            if not unproven.any():
                break
            rolls += _roll_and_follow(unproven, maps, refine_level, level, cells, xs, ys, workers, on_chunk)
        rolls_per_level.append(rolls)
    rolls = sum(rolls_per_level)
    decision = f"--refine {levels}: refined in {rolls} rolls, {100 * rolls / full:.1f} % of the full grid's {full}{cells.each}"
    if rolls > full:
        decision += "; more than the full grid, as its coarse levels lie almost all on boundaries: use fewer levels"
    if log is not None:
        log(decision)
    return RefinedMaps(maps, refine_level, levels, rolls, tuple(rolls_per_level), decision)


def grown(mask, steps: int) -> np.ndarray:
    """bool map of the cells within ``steps`` cells of a cell of ``mask``, diagonals counting
    as one step (a square of side 2 steps + 1 around each)."""
    out = np.asarray(mask, dtype=bool).copy()
    for _ in range(steps):
        out[1:, :] |= out[:-1, :].copy()
        out[:-1, :] |= out[1:, :].copy()
        out[:, 1:] |= out[:, :-1].copy()
        out[:, :-1] |= out[:, 1:].copy()
    return out


def unproven_cells(outcome, filled) -> np.ndarray:
    """bool map of the ``filled`` cells of the last level that refinement must still roll: those
    within :data:`THIN_BUFFER` cells of a rolled cell on a boundary (where thin features and
    islands lie), and those on the edge of the map (a region filled up to the edge is not
    enclosed by rolled cells).

    Parameters
    ----------
    outcome : numpy.ndarray
        (ny, nx) outcomes of the last level, filled cells included (a probability map's
        :func:`sure_outcome`: UNSURE cells count as on a boundary).
    filled : numpy.ndarray
        bool (ny, nx): cells not rolled at their own centres.

    Returns
    -------
    numpy.ndarray
        bool (ny, nx).
    """
    filled = np.asarray(filled, dtype=bool)
    unproven = grown(refine_boundary(outcome) & ~filled, THIN_BUFFER)
    unproven[[0, -1], :] = True
    unproven[:, [0, -1]] = True
    return unproven & filled


def _roll_and_follow(refine, maps, refine_level, level, cells: _Cells, xs, ys, workers, on_chunk) -> int:
    """Roll the cells of ``refine`` at ``level`` into ``maps``, then every cell not yet rolled at
    this level that lies on a boundary, until none is left; returns the rolls."""
    rolls = 0
    while refine.any():
        # a boundary found at this level can run on into a block that was not refined:
        # follow it there, until every cell on a boundary was rolled at this level
        rows, cols = np.nonzero(refine)
        for name, values in cells.roll(xs, ys, rows, cols, workers, on_chunk).items():
            maps[name][rows, cols] = values
        refine_level[rows, cols] = level
        rolls += len(rows)
        refine = refine_boundary(sure_outcome(maps)) & (refine_level < level)
    return rolls


def _roll_level(cells: _Cells, grid, shape, workers, on_chunk) -> dict[str, np.ndarray]:
    """Every cell of the level of ``shape`` (rows, columns) of ``grid``, rolled at its centre."""
    rows, cols = np.indices(shape).reshape(2, -1)
    xs, ys = level_values(grid.x.min, grid.x.max, shape[1]), level_values(grid.y.min, grid.y.max, shape[0])
    return {name: values.reshape(shape) for name, values in cells.roll(xs, ys, rows, cols, workers, on_chunk).items()}


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
    fell_back : bool
        True if the full grid was rolled instead of refining.
    draws : int
        Rolls of each cell rolled (a probability sweep's M; ``rolls`` counts cells).
    """

    path: str
    shape: tuple[int, int]
    levels: int
    rolls: int
    simulated: int
    seconds: float
    fell_back: bool = False
    draws: int = 1

    def describe(self) -> str:
        """One line for the user."""
        ny, nx = self.shape
        full = ny * nx
        how = "--refine {}: the full grid, as refining could not save rolls" if self.fell_back else "refined over {} levels"
        return (
            f"{self.path} ({ny} x {nx}, {how.format(self.levels)}): {self.rolls * self.draws} rolls "
            f"({100 * self.rolls / full:.1f} % of a full sweep) in {self.seconds:.1f} s, "
            f"{self.simulated} pixels ({100 * self.simulated / full:.1f} %) rolled at their own centre, complete"
        )


def write_refined(path, cfg, refined: RefinedMaps) -> None:
    """Write refined maps as a complete sweep file (docs/hdf5.md) plus the refinement maps."""
    header = sweep_header(cfg)
    tiles = TileGrid(header.shape, header.tile_shape)
    with create_whole(path, header, tiles.count) as sweep_file:
        for index in range(tiles.count):
            rows, cols = tiles.bounds(index)
            sweep_file.write_tile(index, rows, cols, {name: values[rows, cols] for name, values in refined.maps.items()})
        write_refinement_maps(sweep_file, refined.refine_level, refined.levels)
        sweep_file.mark_complete()


def run_refined_sweep(cfg, out_path, levels: int, *, workers: int | None = None, progress: bool = True,
                      log=None) -> RefineSummary:
    """Sweep ``cfg.grid`` by quadtree refinement and write it to a new HDF5 file.

    The file has the layout of a full sweep (docs/hdf5.md) plus ``/simulated`` and
    ``/refine_level``. It is written only at the end: an interrupted refinement leaves no
    file (and there is no ``--resume``).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
    out_path : str or os.PathLike
        File to create, on a path checked before (:func:`dice_sweep.outputs.check_outputs`);
        must not exist.
    levels : int
        Number of halvings of the grid (0 = every pixel rolled), checked before
        (:func:`check_levels`).
    workers : int, optional
        Worker processes; default all cores this process may use.
    progress : bool
        Show a tqdm bar on stderr (only when stderr is a terminal).
    log : callable, optional
        Called with one line when it is decided whether to refine or to roll the full grid
        (:func:`refine_maps`).

    Returns
    -------
    RefineSummary

    Raises
    ------
    DiceSweepError
        If the output exists.
    dice_sweep.sweep.SweepInterrupted
        On Ctrl-C (the CLI exits with 130); no file is written.
    """
    started = time.perf_counter()
    workers = workers_or_default(workers)
    if os.path.exists(out_path):
        raise exists_error(out_path, "remove it or choose another output file (--refine has no --resume)")
    try:
        with tqdm(unit=" rolls", unit_scale=True, desc=os.path.basename(str(out_path)), file=sys.stderr,
                  disable=not (progress and sys.stderr.isatty())) as bar:
            refined = refine_maps(cfg, levels, workers=workers, on_chunk=bar.update, log=log and _beside(bar, log))
    except KeyboardInterrupt:
        raise SweepInterrupted(
            f"{out_path}: interrupted; a refined sweep is written only at its end, so nothing was written"
        ) from None
    write_refined(out_path, cfg, refined)
    return RefineSummary(
        str(out_path), refined.refine_level.shape, levels, refined.rolls, int(refined.simulated.sum()),
        time.perf_counter() - started, refined.fell_back, cfg.scatter.draws,
    )


def _beside(bar, log):
    """``log`` made to print its line above a progress bar on the same terminal."""
    def write(line):
        with bar.external_write_mode():
            log(line)
    return write


def compare_with_full(refined_outcome, full_outcome) -> float:
    """Share of pixels whose outcome differs between a refined and a full map of one grid."""
    refined_outcome, full_outcome = np.asarray(refined_outcome), np.asarray(full_outcome)
    if refined_outcome.shape != full_outcome.shape:
        raise DiceSweepError(f"maps {refined_outcome.shape} and {full_outcome.shape}: not of the same grid")
    return float(np.mean(refined_outcome != full_outcome))


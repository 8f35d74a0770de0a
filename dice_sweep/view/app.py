"""What ``dice-sweep view`` serves, apart from HTTP: the file's map, zoomed maps computed by
the kernel, single rolls with their paths, and configs that reproduce a view (docs/view.md).

Every answer is a plain dict ready for JSON. Query strings are checked here: a bad one is a
:class:`QueryError` naming the parameter and its allowed range, which the server answers
with HTTP 400.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import threading
import time

import numpy as np

from dice_sweep.chaos import DEFAULT_BOX_SIZE, basin_entropy, outcome_fractions
from dice_sweep.chaos.measures import measure_probability, shannon_entropy
from dice_sweep.config import PARAM_UNITS, Axis, Grid, check_initial_clear, config_to_toml, parse_config
from dice_sweep.errors import ConfigError, DiceSweepError
from dice_sweep.executor import workers_or_default
from dice_sweep.mapper import Mapper, initial_states, start_pixels
from dice_sweep.physics.layout import EVENT_IMPACT, REC_ENERGY, REC_EVENT, REC_KIND, REC_T, SEG_SLIDE, STATE_COLUMNS
from dice_sweep.storage import read_sweep

MAX_PIXELS = 512  # cells per axis of a zoomed map: 262144 rolls and ~0.6 MB of JSON at most
MAX_FILE_PIXELS = 1024  # cells per axis of the file's map sent to the page; a larger file is sampled
MAX_MAPS_AT_ONCE = 4  # maps being computed at once; more get HTTP 503
ZOOM_OUT_WIDTHS = 1.0  # ranges may reach this many widths of the file's range beyond each edge
MIN_SPAN_SHARE = 1e-9  # narrowest range, as a share of the file's: finer, cell centres round together
NOT_COMPUTED = -128  # outcome code of a cell of an incomplete file not computed yet
PATH_RATE = 240.0  # path samples per simulated second: smooth at a 60 Hz animation slowed 4 times
MAX_PATH_POINTS = 4000
MAX_IMPACTS_LISTED = 1000
TOUCH_SHARE = 1e-6  # x R: corners this close to a surface at an impact touch it
MAP_PARAMETERS = ("xmin", "xmax", "ymin", "ymax", "nx", "ny")
ROLL_PARAMETERS = ("x", "y")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
_INTEGER = re.compile(r"[+-]?\d{1,9}")


class QueryError(DiceSweepError):
    """A bad query parameter: HTTP 400 with ``{"error": ..., "parameter": ...}``."""

    def __init__(self, parameter: str, message: str):
        self.parameter = parameter
        super().__init__(f"{parameter}: {message}")

    def to_dict(self) -> dict:
        return {"error": str(self), "parameter": self.parameter}


class Busy(DiceSweepError):
    """Too many maps are being computed at once: HTTP 503."""


@dataclasses.dataclass(frozen=True)
class MapRequest:
    """A checked map request: the range and cells asked for, and the config that rolls them."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float
    nx: int
    ny: int
    cfg: object  # dice_sweep.config.Config with this grid


def _hex(rgba) -> str:
    return "#" + "".join(f"{round(255 * float(channel)):02x}" for channel in rgba[:3])


def _finite_or_none(value: float):
    return None if value is None or not math.isfinite(value) else float(value)


def map_stats(outcome: np.ndarray, sides: int, computed: np.ndarray | None = None) -> dict:
    """Shares of each side and of undecided rolls, and the basin entropy (dice_sweep.chaos),
    of a map; shares over the computed cells only, the entropy only for a whole map."""
    values = outcome[computed] if computed is not None else outcome.ravel()
    shares = outcome_fractions(values, sides) if values.size else {}
    entropy = None
    if values.size == outcome.size and min(outcome.shape) >= DEFAULT_BOX_SIZE:
        measured = basin_entropy(outcome, DEFAULT_BOX_SIZE)
        entropy = {"box_size": measured.box_size, "Sb": measured.sb, "Sbb": _finite_or_none(measured.sbb),
                   "boxes": measured.boxes, "boundary_boxes": measured.boundary_boxes,
                   "Sbb_above_log2": measured.fractal_by_log2}
    return {
        "cells": int(values.size),
        "shares": {"undecided": float(shares.get(-1, 0.0)), "sides": [float(shares.get(k, 0.0)) for k in range(sides)]},
        "basin_entropy": entropy,
    }


def draw_shares(outcomes: np.ndarray, sides: int) -> np.ndarray:
    """float32 (n + 1, ...): the share of the draws (last axis of ``outcomes``) ending on each
    side, then without one: a probability sweep's /probability_k and /no_answer."""
    codes = np.where(outcomes < 0, sides, outcomes)
    return np.stack([(codes == k).mean(axis=-1) for k in range(sides + 1)]).astype(np.float32)


def probability_view(probability: np.ndarray, draws: int, computed: np.ndarray | None = None) -> dict:
    """What the page draws of a probability map (n + 1, ny, nx), as the sweep's picture does
    (dice_sweep.plotting.shaded_sides): ``outcome``, the most likely outcome (side, -1 no
    answer; NOT_COMPUTED where not ``computed``), shaded by ``p_max``, its probability, and
    ``entropy``, -sum p ln p in nats; as arrays, and the map's probability measures
    (:func:`dice_sweep.chaos.measures.measure_probability`) when it is whole."""
    probability = np.nan_to_num(probability)  # cells not computed: no shares
    sides = probability.shape[0] - 1
    best = np.argmax(probability, axis=0)
    outcome = np.where(best == sides, -1, best).astype(np.int16)
    if computed is not None:
        outcome[~computed] = NOT_COMPUTED
    measures = measure_probability(probability, draws).to_dict() if computed is None or computed.all() else None
    return {"outcome": outcome, "p_max": probability.max(axis=0), "entropy": shannon_entropy(probability), "measures": measures}


JSON_DIGITS = 6  # decimals of the shares and entropies sent: a third of the bytes of float32's repr


def _json_maps(maps: dict, listed: bool = True) -> dict:
    """The maps of ``maps`` (not its ``measures``) ready for JSON: floats rounded to
    JSON_DIGITS decimals; as lists, or as arrays (``listed`` False)."""
    ready = {name: np.round(values, JSON_DIGITS) if values.dtype.kind == "f" else values
             for name, values in maps.items() if name != "measures"}
    return {name: values.tolist() for name, values in ready.items()} if listed else ready


def _sampled(cells: int) -> np.ndarray:
    """Indices of the cells sent for an axis of ``cells`` cells: all of them up to
    MAX_FILE_PIXELS, else the cell under the centre of each of MAX_FILE_PIXELS equal parts."""
    if cells <= MAX_FILE_PIXELS:
        return np.arange(cells)
    return ((np.arange(MAX_FILE_PIXELS) + 0.5) * cells / MAX_FILE_PIXELS).astype(np.int64)


def _single(query: dict, name: str) -> str:
    values = query.get(name)
    if not values:
        raise QueryError(name, "missing")
    if len(values) > 1:
        raise QueryError(name, f"given {len(values)} times (allowed: once)")
    return values[0]


def _check_known(query: dict, allowed) -> None:
    for name in query:
        if name not in allowed:
            raise QueryError(name, f"unknown parameter (allowed: {', '.join(allowed)})")


def _number(query: dict, name: str) -> float:
    text = _single(query, name).strip()
    value = float(text) if _NUMBER.fullmatch(text) else math.nan
    if not math.isfinite(value):
        raise QueryError(name, f"{text[:40]!r} is not a finite number")
    return value


def _integer(query: dict, name: str, low: int, high: int) -> int:
    text = _single(query, name).strip()
    if not _INTEGER.fullmatch(text) or not low <= int(text) <= high:
        raise QueryError(name, f"{text[:40]!r} is outside the allowed range [{low}, {high}] (a whole number)")
    return int(text)


class ViewApp:
    """A sweep file opened for viewing.

    Parameters
    ----------
    path : str or os.PathLike
        A sweep file (``dice-sweep sweep`` or ``merge``); read and checked here.
    workers : int, optional
        Processes rolling zoomed maps; default all cores.

    Raises
    ------
    DiceSweepError
        The file is missing, not a sweep file, or its config cannot be read.
    """

    def __init__(self, path, workers: int | None = None):
        self.path = os.fspath(path)
        self.sweep = read_sweep(self.path)
        self.cfg = parse_config(self.sweep.config_toml, source=f"{self.path}: config_toml")
        if self.cfg.grid is None:
            raise DiceSweepError(f"{self.path}: its config has no [grid] (not a sweep file)")
        self.workers = workers_or_default(workers)
        self.sides = self.cfg.die.sides
        self.mapper = Mapper.from_config(self.cfg)
        # the random law: zooms roll each start on its streams (start_pixels), as the sweep did;
        # with draws > 1 they show probabilities (docs/view.md, "Probability files")
        self.draws = self.cfg.scatter.draws
        self.stochastic = self.cfg.scatter.on or self.draws > 1
        self._pool = None
        self._maps = threading.BoundedSemaphore(MAX_MAPS_AT_ONCE)
        from dice_sweep.plotting import NOT_COMPUTED_COLOR, UNDECIDED_COLOR, outcome_colors, outcome_title

        self.colors = {"sides": [_hex(c) for c in outcome_colors(self.sides)], "undecided": _hex(UNDECIDED_COLOR),
                       "not_computed": _hex(NOT_COMPUTED_COLOR)}
        self.complete = bool(self.sweep.complete and self.sweep.computed.all())
        self.title = outcome_title(self.cfg, self.complete)

    # --- life cycle -----------------------------------------------------------------------

    def start(self) -> None:
        """Start the worker processes (in the background: the first zoom waits for them)."""
        from dice_sweep.roll import initial_state
        from dice_sweep.view.pool import RollPool

        self._pool = RollPool(self.mapper, initial_state(self.cfg), self.workers)
        self._pool.start()

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.close()

    # --- the file -------------------------------------------------------------------------

    def _axis(self, name: str) -> dict:
        axis = getattr(self.cfg.grid, name)
        low, high = self.limits(name)
        return {"param": axis.param, "unit": PARAM_UNITS[axis.param], "min": axis.min, "max": axis.max,
                "num": axis.num, "limits": [low, high]}

    def limits(self, name: str) -> tuple[float, float]:
        """Range the API accepts on axis ``name`` ("x" or "y"): the file's, widened by
        ZOOM_OUT_WIDTHS of its width on each side."""
        axis = getattr(self.cfg.grid, name)
        width = axis.max - axis.min
        return axis.min - ZOOM_OUT_WIDTHS * width, axis.max + ZOOM_OUT_WIDTHS * width

    def file_json(self) -> dict:
        """The file's own map and everything the page needs to draw it (``GET /api/file``).

        A file wider than MAX_FILE_PIXELS cells on an axis is sent sampled: column k of the
        map sent is the file's column ``x.index[k]``, the one under the centre of k when the
        range is cut into as many equal columns (rows likewise), so every value sent is a
        cell's own outcome and the page knows which cell it is.
        """
        sweep = self.sweep
        computed = sweep.computed
        outcome = np.where(computed, sweep.outcome, NOT_COMPUTED).astype(np.int16)
        shown = {"outcome": outcome}
        if sweep.probability is not None:
            shown = probability_view(sweep.probability, self.draws, computed)
        rows, cols = (_sampled(n) for n in outcome.shape)
        x_axis, y_axis = self._axis("x"), self._axis("y")
        sampled = len(cols) < outcome.shape[1] or len(rows) < outcome.shape[0]
        if sampled:
            x_axis["index"], y_axis["index"] = cols.tolist(), rows.tolist()
        maps = _json_maps({name: values[np.ix_(rows, cols)] if sampled else values for name, values in shown.items() if name != "measures"})
        return {
            "name": os.path.basename(self.path),
            "title": self.title,
            "sides": self.sides,
            "complete": self.complete,
            "created": sweep.created,
            "dice_sweep_version": sweep.dice_sweep_version,
            "x": x_axis,
            "y": y_axis,
            **maps,
            "draws": self.draws if sweep.probability is not None else 1,
            "colors": self.colors,
            "stats": {**map_stats(shown["outcome"], self.sides, None if computed.all() else computed),
                      "probability": shown.get("measures")},
            "max_pixels": MAX_PIXELS,
            "not_computed_code": NOT_COMPUTED,
        }

    # --- maps -----------------------------------------------------------------------------

    def _range(self, query: dict, name: str) -> tuple[float, float]:
        low_name, high_name = f"{name}min", f"{name}max"
        low, high = _number(query, low_name), _number(query, high_name)
        allowed_low, allowed_high = self.limits(name)
        param = getattr(self.cfg.grid, name).param
        allowed = f"[{allowed_low:.10g}, {allowed_high:.10g}] {PARAM_UNITS[param]} ({param}: the file's range and one width beyond each edge)"
        for label, value in ((low_name, low), (high_name, high)):
            if not allowed_low <= value <= allowed_high:
                raise QueryError(label, f"{value:.10g} is outside the allowed range {allowed}")
        if not high > low:
            raise QueryError(high_name, f"{high:.10g} is not above {low_name} = {low:.10g} (allowed: {high_name} > {low_name})")
        span = MIN_SPAN_SHARE * (allowed_high - allowed_low) / (1 + 2 * ZOOM_OUT_WIDTHS)
        if high - low < span:
            raise QueryError(high_name, f"{high_name} - {low_name} = {high - low:.3g} is below the narrowest range "
                             f"{span:.3g} {PARAM_UNITS[param]} (allowed: at least {MIN_SPAN_SHARE:g} of the file's range)")
        return low, high

    def map_request(self, query: dict) -> MapRequest:
        """Check the query of ``GET /api/map`` (or ``/api/config``) and build its config.

        Raises
        ------
        QueryError
            Naming the first bad parameter and its allowed range.
        """
        _check_known(query, MAP_PARAMETERS)
        xmin, xmax = self._range(query, "x")
        ymin, ymax = self._range(query, "y")
        nx = _integer(query, "nx", 1, MAX_PIXELS)
        ny = _integer(query, "ny", 1, MAX_PIXELS)
        grid = Grid(x=Axis(self.cfg.grid.x.param, xmin, xmax, nx), y=Axis(self.cfg.grid.y.param, ymin, ymax, ny))
        wanted = dataclasses.replace(self.cfg, grid=grid)
        try:  # the sweep's own checks (a start with a corner inside the table, ...)
            cfg = parse_config(config_to_toml(wanted), source=os.path.basename(self.path))
        except ConfigError as error:
            raise QueryError(self._query_name(error.key), error.message) from None
        return MapRequest(xmin, xmax, ymin, ymax, nx, ny, cfg)

    def _query_name(self, key: str) -> str:
        """The query parameter behind a config key of the grid (``grid.y.min`` -> ``ymin``)."""
        parts = key.split(".")
        if len(parts) == 3 and parts[0] == "grid":
            return {"min": f"{parts[1]}min", "max": f"{parts[1]}max", "num": f"n{parts[1]}"}.get(parts[2], key)
        if len(parts) == 2 and parts[0] == "grid":
            # a start inside a surface: the table lies below y0's low end, walls on either side
            low_end = getattr(self.cfg.grid, parts[1]).param == "y0"
            return f"{parts[1]}min" if low_end else f"{parts[1]}min,{parts[1]}max"
        return key

    def compute_map(self, request: MapRequest, on_band=None, cancelled=None) -> dict:
        """Roll every cell of ``request`` with the file's config (``GET /api/map``).

        The starts are those a sweep of ``request.cfg`` rolls, so the file's own range and
        size give the file's outcome array exactly; a probability file's zoom shows its
        shares (:meth:`roll_zoom`, :func:`probability_view`). ``on_band(first_row, end_row,
        rows, rolls_done)`` reports progress; ``cancelled()`` stops (dice_sweep.view.pool).
        """
        if self._pool is None:
            raise RuntimeError("ViewApp.start() was not called")
        if not self._maps.acquire(blocking=False):
            raise Busy(f"{MAX_MAPS_AT_ONCE} maps are being computed already; retry when one is done")
        try:
            started = time.perf_counter()
            outcome, engine = self.roll_zoom(request, on_band and self._shaded_bands(on_band), cancelled)
            seconds = time.perf_counter() - started
        finally:
            self._maps.release()
        shown = {"outcome": outcome}
        if self.stochastic:
            shown = probability_view(draw_shares(outcome, self.sides), self.draws) if self.draws > 1 else {"outcome": outcome[..., 0]}
        grid = request.cfg.grid
        return {
            "xmin": request.xmin, "xmax": request.xmax, "ymin": request.ymin, "ymax": request.ymax,
            "nx": request.nx, "ny": request.ny,
            "x_param": grid.x.param, "y_param": grid.y.param,
            "x": grid.x.values().tolist(), "y": grid.y.values().tolist(),
            **_json_maps(shown),
            "draws": self.draws if self.stochastic else 1,
            "stats": {**map_stats(shown["outcome"], self.sides), "probability": shown.get("measures")},
            "rolls": int(outcome.size),
            "seconds": seconds,
            "engine": engine,
        }

    def roll_zoom(self, request: MapRequest, on_band=None, cancelled=None):
        """(outcome, engine) of the cells of ``request`` rolled by the worker pool: an int8
        (ny, nx) map; with the file's random law, each start rolled ``draws`` times on its
        streams, (ny, nx, draws). A start's streams are :func:`dice_sweep.mapper.start_pixels`'s
        on the file's grid: a zoom cell on a file cell's centre rolls that cell's draws, any
        other start streams of its own (docs/view.md, "Probability files")."""
        grid = request.cfg.grid
        xs, ys = grid.x.values(), grid.y.values()
        states = initial_states(request.cfg, xs, ys)
        mapper = Mapper.from_config(request.cfg).with_engine_for(states, len(states), self.workers)
        pixels = None
        if self.stochastic:
            pixels = start_pixels(self.sweep.x.values, self.sweep.y.values, np.tile(xs, len(ys)), np.repeat(ys, len(xs)))
        return self._pool.roll_map(mapper, states, (request.ny, request.nx), on_band, cancelled, pixels, self.draws), mapper.engine

    def _shaded_bands(self, on_band):
        """``on_band`` given the rows of a map rolled ``draws`` times per start as the page
        draws them: the most likely outcome, and with draws > 1 its probability and the entropy."""
        def band(first, end, rows, done):
            if not self.stochastic:
                return on_band(first, end, rows, done)
            if self.draws == 1:
                return on_band(first, end, rows[..., 0], done)
            shown = probability_view(draw_shares(rows, self.sides), self.draws)
            return on_band(first, end, shown["outcome"], done, **_json_maps({"p_max": shown["p_max"], "entropy": shown["entropy"]}, False))
        return band

    def config_text(self, request: MapRequest) -> str:
        """A config that ``dice-sweep sweep`` turns into this view (``GET /api/config``)."""
        grid = request.cfg.grid
        view = (f"{grid.x.param} in [{grid.x.min!r}, {grid.x.max!r}] {PARAM_UNITS[grid.x.param]}, "
                f"{grid.y.param} in [{grid.y.min!r}, {grid.y.max!r}] {PARAM_UNITS[grid.y.param]}, "
                f"{grid.x.num} x {grid.y.num} cells")
        return (f"# A view of {os.path.basename(self.path)} in dice-sweep view: {view}.\n"
                "# Reproduce it: dice-sweep sweep THIS.toml -o view.h5 --png view.png\n\n"
                + config_to_toml(request.cfg))

    # --- one roll -------------------------------------------------------------------------

    def roll_start(self, query: dict):
        """Check the query of ``GET /api/roll``: (config of the roll from (x, y), x, y)."""
        _check_known(query, ROLL_PARAMETERS)
        values = {}
        for name in ROLL_PARAMETERS:
            value = _number(query, name)
            low, high = self.limits(name)
            param = getattr(self.cfg.grid, name).param
            if not low <= value <= high:
                raise QueryError(name, f"{value:.10g} is outside the allowed range [{low:.10g}, {high:.10g}] "
                                 f"{PARAM_UNITS[param]} ({param}: the file's range and one width beyond each edge)")
            values[param] = value
        cfg = self.cfg.with_initial(**values)
        try:
            check_initial_clear(cfg)
        except ConfigError as error:
            name = next((n for n in ROLL_PARAMETERS if error.key == f"initial.{getattr(self.cfg.grid, n).param}"), "x,y")
            raise QueryError(name, error.message) from None
        return cfg, values[self.cfg.grid.x.param], values[self.cfg.grid.y.param]

    def roll_json(self, query: dict) -> dict:
        """One roll from the point (x, y) of the map, its path and its impacts (``GET /api/roll``)."""
        from dice_sweep.roll import initial_state, roll_config, sample_path

        cfg, x, y = self.roll_start(query)
        report = roll_config(cfg)
        points = int(min(MAX_PATH_POINTS, max(2, math.ceil(report.t_end * PATH_RATE) + 1)))
        times = np.linspace(0.0, report.t_end, points)
        path = sample_path(cfg, report, times)
        impacts = self._impacts(cfg, report)
        start = initial_state(cfg)
        return {
            "x": x, "y": y,
            "x_param": cfg.grid.x.param, "y_param": cfg.grid.y.param,
            "start": dict(zip(STATE_COLUMNS, start.tolist())),
            "outcome": report.outcome,
            "status": report.status_name,
            "status_code": report.status,
            "t_decided": _finite_or_none(report.t_decided),
            "t_end": report.t_end,
            "counts": report.counts,
            "impacts": impacts[:MAX_IMPACTS_LISTED],
            "impacts_listed": min(len(impacts), MAX_IMPACTS_LISTED),
            "path": {"t": times.tolist(), "x": path[:, 0].tolist(), "y": path[:, 1].tolist(), "phi": path[:, 2].tolist()},
            "die": {"sides": cfg.die.sides, "circumradius": cfg.die.circumradius, "walls": cfg.walls.separation},
            "colors": self.colors,
        }

    def _impacts(self, cfg, report) -> list[dict]:
        """The impacts of a roll from its segment records: time, surface, corner, pose and
        the energy per unit mass left after it (J/kg)."""
        from dice_sweep.geometry import corners
        from dice_sweep.roll import sample_path

        records = report.records
        # a slide on a side ends with a record marked as an impact too: not a collision
        after_slide = np.r_[False, records[:-1, REC_KIND] == SEG_SLIDE]
        rows = records[(records[:, REC_EVENT] == EVENT_IMPACT) & ~after_slide]
        if len(rows) == 0:
            return []
        poses = sample_path(cfg, report, rows[:, REC_T])
        half = None if cfg.walls.separation is None else cfg.walls.separation / 2
        listed = []
        for row, pose in zip(rows, poses):
            points = corners(cfg.die.sides, cfg.die.circumradius, pose[0], pose[1], pose[2])
            gaps = {"table": points[:, 1]}
            if half is not None:
                gaps.update({"left wall": points[:, 0] + half, "right wall": half - points[:, 0]})
            nearest = min(gaps, key=lambda name: gaps[name].min())
            # table and wall at once (a corner in the room's corner) is one impact of both
            touching = [name for name in gaps if gaps[name].min() <= gaps[nearest].min() + TOUCH_SHARE * cfg.die.circumradius]
            listed.append({
                "t": float(row[REC_T]), "surface": " and ".join(touching), "corner": int(np.argmin(gaps[nearest])),
                "x": float(pose[0]), "y": float(pose[1]), "phi": float(pose[2]), "energy": float(row[REC_ENERGY]),
            })
        return listed

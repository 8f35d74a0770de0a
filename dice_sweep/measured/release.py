"""The final-state map of a forecast's release states (``dice-sweep forecast``, issue 18).

Where the tracked throws sit in the chaos of their model: the sides of a grid of release
states over the two initial values that vary most over the drops (or two given ones), the
other four at the drops' medians, at the fitted parameters; the map's chaos measures
(:func:`dice_sweep.chaos.measures.measure_map`) and, for the drops, the box entropy around
them, whether the map's side is the one they rested on, and how wide their release states'
uncertainty is in cells. The grid is rolled by the mapper on the one worker pool.
"""

import dataclasses
import math

import numpy as np

from dice_sweep.chaos.measures import DEFAULT_BOX_SIZE, measure_map
from dice_sweep.config import PARAM_UNITS, Axis, Grid
from dice_sweep.measured import forecast as fc
from dice_sweep.measured.fit import kernel_config


def release_map(cfg, source, run, size, axes=None, workers=1):
    """The final-state map over the release states (the two initial values that vary most,
    or ``axes``), the other initial values at the drops' medians, the fitted parameters;
    its chaos measures and where the drops sit.

    Parameters
    ----------
    cfg : Config
        The die and the declared model.
    source : FitSource
        The fit (:func:`dice_sweep.measured.forecast.parse_fit`): its effects and parameters.
    run : ForecastRun
        The forecast (:func:`dice_sweep.measured.forecast.run_forecast`): its release states.
    size : int
        Cells per axis.
    axes : (str, str), optional
        The two initial values (of ``forecast.STATE_COLUMNS``); default the two that vary most.
    workers : int
        Processes of the worker pool.

    Returns
    -------
    summary : dict
        JSON-ready: the axes and why, ranges, measures, where the drops sit.
    picture : dict
        What :func:`dice_sweep.plotting.plot_release_map` draws.
    """
    from dice_sweep.mapper import Mapper, initial_states, roll_states

    flights = run.release
    states = fc.true_states(cfg, source.params, np.array([f.state for f in flights]).reshape(-1, 6))
    observed = np.array([run.observed[f.traj] for f in flights], dtype=np.int64)
    held = np.array([f.traj in run.held_out_traj for f in flights], dtype=bool)
    chosen = fc.choose_map_axes(states, cfg) if axes is None else tuple(axes)
    columns = [fc.STATE_COLUMNS.index(name) for name in chosen]
    sides = cfg.die.sides
    centre = fc.phase_centre(states[:, 2], sides)
    folded, turns = fc.fold_phase(states[:, 2], sides, centre)
    if "phi0" in chosen:  # a turn by 2 pi / n is the same throw with the sides renamed
        states = states.copy()
        states[:, 2] = folded
        shown_side = (observed + turns) % sides
    else:
        shown_side = observed
    ranges = [fc.map_range(states[:, c], name, cfg) for name, c in zip(chosen, columns)]
    fixed = np.median(states, axis=0)
    model = kernel_config(cfg, source.spec(cfg), source.params)
    model = model.with_initial(**{name: float(fixed[k]) for k, name in enumerate(fc.STATE_COLUMNS) if name not in chosen})
    grid = Grid(Axis(chosen[0], *ranges[0], size), Axis(chosen[1], *ranges[1], size))
    model = dataclasses.replace(model, grid=grid)
    xs, ys = grid.x.values(), grid.y.values()
    starts = initial_states(model, xs, ys)
    clear = fc.clear_starts(model, starts)
    outcome = np.full(len(starts), -1, np.int8)
    if clear.any():
        outcome[clear] = roll_states(Mapper.from_config(model), starts[clear], workers)[0]
    outcome = outcome.reshape(size, size)
    measures = measure_map(outcome, sides, DEFAULT_BOX_SIZE, x_step=(ranges[0][1] - ranges[0][0]) / size,
                           y_step=(ranges[1][1] - ranges[1][0]) / size)
    col = np.floor((states[:, columns[0]] - ranges[0][0]) / (ranges[0][1] - ranges[0][0]) * size).astype(np.int64)
    row = np.floor((states[:, columns[1]] - ranges[1][0]) / (ranges[1][1] - ranges[1][0]) * size).astype(np.int64)
    inside = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    box = measures.entropy.box_entropy
    boxed = inside & (row // DEFAULT_BOX_SIZE < box.shape[0]) & (col // DEFAULT_BOX_SIZE < box.shape[1])
    local = box[row[boxed] // DEFAULT_BOX_SIZE, col[boxed] // DEFAULT_BOX_SIZE]
    agrees = outcome[row[inside], col[inside]] == shown_side[inside]
    block = np.median(np.array([f.cov[np.ix_(columns, columns)] for f in flights]), axis=0)
    cell = np.array([(r[1] - r[0]) / size for r in ranges])
    spread = fc.spreads(states, cfg)
    summary = {
        "axes": list(chosen),
        "axes_rule": ("the two initial values whose spread over the drops' release states (standard deviation in the die's own "
                      "scales: R for x0, y0; 2 pi / n for phi0, folded about its circular mean; sqrt(g R) for vx0, vy0; sqrt(g / R) "
                      "for omega0; x0 only between walls) is largest" if axes is None else "given by --map-axes"),
        "spreads_natural": {name: float(spread[k]) for k, name in enumerate(fc.STATE_COLUMNS)},
        "ranges": {name: list(r) for name, r in zip(chosen, ranges)},
        "units": {name: PARAM_UNITS[name] for name in chosen},
        "size": [size, size],
        "fixed": {name: float(fixed[k]) for k, name in enumerate(fc.STATE_COLUMNS) if name not in chosen},
        "phi0_folded": "phi0" in chosen,
        "cells_inside_table": int((~clear).sum()),
        "measures": measures.to_dict(),
        "alpha_text": measures.uncertainty.fit.text(),
        "f_1_pixel": float(measures.uncertainty.fraction[0]),
        "drops": int(len(flights)),
        "drops_in_map": int(inside.sum()),
        "drops_box_entropy_mean": float(local.mean()) if local.size else math.nan,
        "drops_on_boundary_boxes": float(np.mean(local > 0)) if local.size else math.nan,
        "drops_side_as_map": float(agrees.mean()) if agrees.size else math.nan,
        "release_sd_in_cells": {name: float(math.sqrt(block[k, k]) / cell[k]) for k, name in enumerate(chosen)},
    }
    picture = {"outcome": outcome, "x": xs, "y": ys, "x_label": f"{chosen[0]} ({PARAM_UNITS[chosen[0]]})",
               "y_label": f"{chosen[1]} ({PARAM_UNITS[chosen[1]]})", "drops_x": states[:, columns[0]],
               "drops_y": states[:, columns[1]], "drops_side": shown_side, "held_out": held, "cfg": model}
    return summary, picture

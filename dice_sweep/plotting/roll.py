"""One roll as the paper's graphics window drew it (Smith 2014, Fig. 5): the die's outline
along its path, side 0 in its own colour, as a picture or an animated GIF.
"""

import math
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from dice_sweep.geometry import outline
from dice_sweep.outputs import written
from dice_sweep.plotting.common import (
    save_figure,
    ANIMATION_DPI,
    ANIMATION_FIGSIZE,
    MAX_ANIMATION_FRAMES,
    PATH_POINTS_PER_FRAME,
    ROLL_FIGSIZE,
    outcome_colors,
)


def _die_outline(cfg, state):
    """Outline of the die in a state row (x, y, phi, ...): ``(points, side 0)``, each (m, 2),
    the closed outline (arcs at rounded corners) and side 0's straight part."""
    arcs = outline(cfg.die.sides, cfg.die.circumradius, state[0], state[1], state[2], cfg.effects.corner_radius)
    return arcs.reshape(-1, 2), np.array([arcs[0, -1], arcs[1, 0]])


def _roll_outcome_text(report):
    side = "undecided" if report.outcome < 0 else f"side {report.outcome}"
    return f"{side} after {report.impacts} impacts, {report.t_end:.3f} s"


def _draw_roll_scene(ax, cfg, path, report):
    """Table, walls, centre path, limits and labels shared by the picture and the animation."""
    radius = cfg.die.circumradius
    separation = cfg.walls.separation
    margin = 1.5 * radius
    if separation is None:
        xmin, xmax = path[:, 0].min() - margin, path[:, 0].max() + margin
    else:
        xmin, xmax = -separation / 2 - margin, separation / 2 + margin
    ymax = max(path[:, 1].max(), 0.0) + margin
    ax.axhspan(-margin, 0.0, color="0.85", zorder=0)
    ax.axhline(0.0, color="0.3", linewidth=1.0)
    if separation is not None:
        for wall_x in (-separation / 2, separation / 2):
            ax.axvline(wall_x, color="0.3", linewidth=1.5)
    ax.plot(path[:, 0], path[:, 1], color="tab:blue", linewidth=0.8, alpha=0.7)
    # Autoscaled limits (not fixed ones) let the equal aspect widen the view to fill the axes.
    ax.update_datalim([(xmin, -margin), (xmax, ymax)])
    ax.margins(0.0)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(_roll_outcome_text(report), fontsize="medium")


def _add_die(ax, cfg, state, alpha=1.0):
    """Draw the die outline with side 0 in the colour of side 0; return (outline, side 0)."""
    xy, side = _die_outline(cfg, state)
    shape = ax.add_patch(Polygon(xy, closed=True, fill=False, edgecolor="black", linewidth=1.0, alpha=alpha))
    (side0,) = ax.plot(side[:, 0], side[:, 1], color=outcome_colors(cfg.die.sides)[0], linewidth=2.0, alpha=alpha)
    return shape, side0


def _move_die(artists, cfg, state):
    shape, side0 = artists
    xy, side = _die_outline(cfg, state)
    shape.set_xy(xy)
    side0.set_data(side[:, 0], side[:, 1])


def plot_roll(cfg, report, png_path, path_sampler, *, frames=12, dpi=150):
    """Write a picture of one roll like the paper's graphics window (Smith 2014, Fig. 5).

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        The roll's config.
    report : dice_sweep.roll.RollReport
        Result of the roll; uses ``t_end`` (s), ``outcome`` and ``impacts``.
    png_path : str or pathlib.Path
        PNG to write.
    frames : int
        Number of die outlines drawn at equal time intervals from 0 to ``t_end``.
    dpi : float
        Pixels per inch.
    path_sampler : callable
        ``(cfg, report, times) -> (T, 6)`` states (x, y, phi, vx, vy, omega) of the centre,
        e.g. :func:`dice_sweep.roll.sample_path`.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    sampler = path_sampler
    intervals = max(frames - 1, 1)
    times = np.linspace(0.0, report.t_end, intervals * PATH_POINTS_PER_FRAME + 1)
    path = np.asarray(sampler(cfg, report, times))
    fig = Figure(figsize=ROLL_FIGSIZE, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    _draw_roll_scene(ax, cfg, path, report)
    outline_rows = path[:: PATH_POINTS_PER_FRAME][:frames]
    for i, state in enumerate(outline_rows):
        _add_die(ax, cfg, state, alpha=0.25 + 0.75 * (i + 1) / len(outline_rows))  # later = darker
    save_figure(fig, png_path, dpi)
    return Path(png_path)


def animate_roll(cfg, report, gif_path, path_sampler, *, fps=30, max_frames=MAX_ANIMATION_FRAMES):
    """Write an animated GIF of one roll, one frame every 1/fps s of simulated time.

    A roll longer than ``max_frames / fps`` is subsampled to ``max_frames`` frames spread
    over the whole roll, so it plays faster than real time.

    Parameters
    ----------
    cfg, report, path_sampler
        As in :func:`plot_roll`.
    gif_path : str or pathlib.Path
        GIF to write.
    fps : float
        Frames per second of simulated time and of playback.
    max_frames : int
        Most frames written.

    Returns
    -------
    pathlib.Path
        ``gif_path``.
    """
    sampler = path_sampler
    intervals = math.ceil(report.t_end * fps)
    if intervals < max_frames:
        times = np.minimum(np.arange(intervals + 1) / fps, report.t_end)  # last frame at rest
    else:
        times = np.linspace(0.0, report.t_end, max_frames)
    path = np.asarray(sampler(cfg, report, times))
    fig = Figure(figsize=ANIMATION_FIGSIZE, dpi=ANIMATION_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    _draw_roll_scene(ax, cfg, path, report)
    die = _add_die(ax, cfg, path[0])
    # The clock makes every frame differ, so the GIF writer never merges frames of a die at rest.
    clock = ax.text(0.02, 0.95, "", transform=ax.transAxes, va="top", fontsize="small")
    writer = PillowWriter(fps=fps)
    with written(gif_path) as temporary, writer.saving(fig, str(temporary), dpi=ANIMATION_DPI):
        for t, state in zip(times, path):
            _move_die(die, cfg, state)
            clock.set_text(f"t = {t:.3f} s")
            writer.grab_frame()
    return Path(gif_path)

"""Final-state diagrams: the outcome map of a sweep in the paper's colours, a zoom box, several
maps side by side, and where quadtree refinement rolled.
"""

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from dice_sweep.errors import DiceSweepError
from dice_sweep.plotting.common import (
    save_figure,
    BOX_COLOR,
    MAX_SIDE_LABELS,
    NOT_COMPUTED_COLOR,
    OUTCOME_FIGSIZE,
    UNDECIDED_COLOR,
    cell_extent,
    panel_figure,
    draw_scalar_map,
    outcome_colors,
    sweep_axes,
)


def draw_outcome_map(ax, outcome, x_values, y_values, x_label, y_label, sides, title=None, *, extent=None, computed=None):
    """Draw a final-state diagram on ``ax`` with a colour bar naming the sides.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Axes of a :class:`matplotlib.figure.Figure`; the colour bar is added beside it.
    outcome : array_like of int, shape (ny, nx)
        Side 0..n-1 of each roll, -1 for undecided; row i belongs to ``y_values[i]``.
    x_values, y_values : array_like of float, shapes (nx,) and (ny,)
        Cell centres of the two axes (equally spaced), in the parameters' SI units.
    x_label, y_label : str
        Axis labels with parameter and unit, see :func:`~dice_sweep.plotting.common.axis_label`.
    sides : int
        Number of sides n of the die.
    title : str, optional
        Title of the axes.
    extent : tuple of 4 float, optional
        (xmin, xmax, ymin, ymax) covered by the cells; by default inferred from the centres
        (a single cell then gets width 1).
    computed : array_like of bool, shape (ny, nx), optional
        False for cells of an incomplete sweep not computed yet: drawn in
        :data:`NOT_COMPUTED_COLOR`, with a "not computed" entry on the colour bar.

    Returns
    -------
    matplotlib.image.AxesImage
        The drawn image; its extent is exactly the outer cell edges.
    """
    # Colour index -2 (not computed), -1 (undecided) .. n-1 (sides) maps onto bins centred on
    # the integers; -2 only when some cell is not computed.
    outcome = np.asarray(outcome)
    missing = None if computed is None else ~np.asarray(computed, dtype=bool)
    first = -2 if missing is not None and missing.any() else -1
    if first == -2:
        outcome = np.where(missing, -2, outcome)
    colors = [NOT_COMPUTED_COLOR, UNDECIDED_COLOR][first + 2:]
    cmap = ListedColormap(np.vstack([*colors, outcome_colors(sides)]))
    norm = BoundaryNorm(np.arange(first - 0.5, sides), cmap.N)
    image = ax.imshow(
        outcome,
        cmap=cmap,
        norm=norm,
        origin="lower",
        extent=extent or (*cell_extent(x_values), *cell_extent(y_values)),
        interpolation="nearest",
        aspect="auto",
    )
    named = {-2: "not computed", -1: "undecided"}
    sides_shown = np.arange(sides)[:: math.ceil((sides + 1) / MAX_SIDE_LABELS)]
    ticks = np.concatenate([np.arange(first, 0), sides_shown])
    colorbar = ax.figure.colorbar(image, ax=ax, ticks=ticks)
    colorbar.ax.set_yticklabels([named.get(k, f"side {k}") for k in ticks])
    colorbar.ax.tick_params(labelsize="small" if sides <= 12 else "x-small")
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    if title:
        ax.set_title(title, fontsize="medium")
    return image


def shaded_sides(probability, sides, computed=None) -> np.ndarray:
    """RGB (ny, nx, 3) of a probability map: the colour of the most likely outcome (a side's,
    or black for no answer) faded towards white as its probability falls from 1 to 1/(n + 1)
    (n + 1 outcomes equally likely: white). ``probability``: (n + 1, ny, nx), row n no answer;
    cells not ``computed`` grey."""
    p = np.nan_to_num(np.asarray(probability, dtype=float))
    best = np.argmax(p, axis=0)
    colors = np.vstack([outcome_colors(sides), UNDECIDED_COLOR])[:, :3]
    floor = 1.0 / (sides + 1)
    strength = np.clip((p.max(axis=0) - floor) / (1.0 - floor), 0.0, 1.0)[..., None]
    rgb = 1.0 - strength * (1.0 - colors[best])
    if computed is not None:
        rgb[~np.asarray(computed, dtype=bool)] = NOT_COMPUTED_COLOR[:3]
    return rgb


def draw_probability_map(ax, probability, x_values, y_values, x_label, y_label, sides, title=None, *, extent=None,
                         computed=None):
    """Draw the most likely side of each cell shaded by its probability (:func:`shaded_sides`)
    on ``ax``, with a key of the side colours at p = 1. Arguments as :func:`draw_outcome_map`,
    with ``probability`` (n + 1, ny, nx) instead of the outcome map."""
    image = ax.imshow(shaded_sides(probability, sides, computed), origin="lower", interpolation="nearest", aspect="auto",
                      extent=extent or (*cell_extent(x_values), *cell_extent(y_values)))
    key = ListedColormap(np.vstack([UNDECIDED_COLOR, outcome_colors(sides)]))
    colorbar = ax.figure.colorbar(ScalarMappable(BoundaryNorm(np.arange(-1.5, sides), key.N), key), ax=ax,
                                  ticks=np.arange(-1, sides)[:: math.ceil((sides + 1) / MAX_SIDE_LABELS)])
    colorbar.ax.set_yticklabels(["no answer" if k < 0 else f"side {k}" for k in colorbar.get_ticks().astype(int)])
    colorbar.ax.tick_params(labelsize="small" if sides <= 12 else "x-small")
    colorbar.set_label(f"most likely; white: p = 1/{sides + 1}", fontsize="small")
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    if title:
        ax.set_title(title, fontsize="medium")
    return image


def draw_box(ax, box):
    """Draw the zoom rectangle ``box = (xmin, xmax, ymin, ymax)`` (Smith 2014, Figs 9, 11)."""
    xmin, xmax, ymin, ymax = box
    ax.add_patch(
        Rectangle((xmin, ymin), xmax - xmin, ymax - ymin, fill=False, edgecolor=BOX_COLOR, linewidth=1.5)
    )


def parse_box(text):
    """Parse ``"XMIN,XMAX,YMIN,YMAX"`` (the ``--box`` option) into four floats.

    Raises
    ------
    DiceSweepError
        If there are not four finite numbers with XMIN < XMAX and YMIN < YMAX.
    """
    try:
        box = tuple(float(part) for part in text.split(","))
    except ValueError:
        box = ()
    if len(box) != 4 or not all(map(math.isfinite, box)) or box[0] >= box[1] or box[2] >= box[3]:
        raise DiceSweepError(f"--box: expected XMIN,XMAX,YMIN,YMAX with XMIN < XMAX and YMIN < YMAX, got {text!r}")
    return box


def check_box(box, extent):
    """``box`` if it lies inside ``extent`` = (xmin, xmax, ymin, ymax) of the map, edges
    included; else a one-line :class:`DiceSweepError` naming ``--box`` (a box outside the
    map was drawn nowhere, without a word)."""
    xmin, xmax, ymin, ymax = extent
    if not (xmin <= box[0] and box[1] <= xmax and ymin <= box[2] and box[3] <= ymax):
        raise DiceSweepError(f"--box: {','.join(f'{v:g}' for v in box)} is not inside the map (allowed: XMIN, XMAX "
                             f"in [{xmin:g}, {xmax:g}], YMIN, YMAX in [{ymin:g}, {ymax:g}])")
    return box


def outcome_title(cfg, complete=True):
    """Title of a final-state diagram: n, the restitution coefficients and the walls.

    Parameters
    ----------
    cfg : dice_sweep.config.Config
        The sweep's resolved config.
    complete : bool
        False marks the title "(incomplete)": part of the grid has not been run.
    """
    separation = cfg.walls.separation
    walls = "no walls" if separation is None else f"walls {separation:g} m apart"
    title = (
        f"n = {cfg.die.sides}, beta_normal = {cfg.contact.beta_normal:g}, "
        f"beta_tangential = {cfg.contact.beta_tangential:g}, {walls}"
    )
    extras = [] if cfg.contact.model == "paper" else [f"{cfg.contact.model} model"]
    if math.isfinite(cfg.contact.friction):
        extras.append(f"mu = {cfg.contact.friction:g}")
    effects = cfg.effects
    if effects.air_drag:
        extras.append(f"drag {effects.air_drag:g}/m")
    if any(effects.com_offset):
        extras.append(f"loaded ({effects.com_offset[0]:g}, {effects.com_offset[1]:g}) m")
    if effects.speed_restitution:
        extras.append(f"k = {effects.speed_restitution:g} s/m")
    if cfg.world.g != 9.81:
        extras.append(f"g = {cfg.world.g:g}")
    if cfg.scatter.on:
        law = cfg.scatter
        floors = f" (floors {law.corner_floor:.3g}, {law.flat_floor:.3g} sqrt(gR))" if law.corner_floor or law.flat_floor else ""
        extras.append(f"impacts scattered: corner {law.corner:.3g}, flat {law.flat:.3g}{floors}")
    if extras:
        title += "\n" + ", ".join(extras)
    return title if complete else f"{title} (incomplete)"


def outcome_figure(
    outcome, x_values, y_values, x_label, y_label, sides, *, title=None, box=None, extent=None, dpi=150, computed=None
):
    """A :class:`~matplotlib.figure.Figure` holding one final-state diagram.

    Parameters are those of :func:`draw_outcome_map`, plus ``box`` (the zoom rectangle
    ``(xmin, xmax, ymin, ymax)``, optional) and ``dpi`` (pixels per inch of the figure).
    """
    fig = Figure(figsize=OUTCOME_FIGSIZE, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_outcome_map(ax, outcome, x_values, y_values, x_label, y_label, sides, title=title, extent=extent,
                     computed=computed)
    if box is not None:
        draw_box(ax, box)
    return fig


def sweep_figure(sweep, title, *, box=None, dpi=150):
    """The final-state diagram of a sweep read by :func:`dice_sweep.storage.read_sweep`.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        Outcome map, axes (values, parameter, unit, range) and which cells were computed; an
        incomplete sweep is drawn with the cells not run in :data:`NOT_COMPUTED_COLOR`.
    title : str
        E.g. :func:`outcome_title` of the sweep's config.
    box : tuple of 4 float, optional
        Zoom rectangle ``(xmin, xmax, ymin, ymax)`` in the axes' units.
    dpi : float
        Pixels per inch.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if box is not None:
        check_box(box, sweep.extent)
    return outcome_figure(
        sweep.outcome,
        *sweep_axes(sweep),
        sweep.sides,
        title=title,
        box=box,
        extent=sweep.extent,
        dpi=dpi,
        computed=sweep.computed,
    )


def probability_figure(sweep, entropy, title, *, box=None, dpi=150):
    """The final-state diagram of a probability sweep (M draws per cell): the most likely side
    shaded by its probability beside ``entropy``, the (ny, nx) outcome entropy in nats (NaN
    where not computed); one title over both. ``box`` is drawn on the first."""
    if box is not None:
        check_box(box, sweep.extent)
    fig, (ax_side, ax_entropy) = panel_figure(2, dpi, OUTCOME_FIGSIZE)
    axes = sweep_axes(sweep)
    draw_probability_map(ax_side, sweep.probability, *axes, sweep.sides, extent=sweep.extent, computed=sweep.computed,
                         title=f"most likely side, shaded by its probability ({sweep.draws} draws per cell)")
    draw_scalar_map(ax_entropy, entropy, *axes, extent=sweep.extent, label="nats", vmin=0.0, vmax=math.log(sweep.sides + 1),
                    cmap="magma", title=f"outcome entropy: mean {np.nanmean(entropy):.3f} nats")
    if box is not None:
        draw_box(ax_side, box)
    fig.suptitle(title, fontsize="medium")
    return fig


def plot_comparison(sweeps, titles, png_path, *, dpi=100):
    """Final-state diagrams of several sweeps side by side in one picture.

    Parameters
    ----------
    sweeps : sequence of dice_sweep.storage.SweepData
        Drawn left to right.
    titles : sequence of str
        One title per panel.
    png_path : str or pathlib.Path
        Picture to write.
    dpi : float
        Pixels per inch.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    fig, axes = panel_figure(len(sweeps), dpi, OUTCOME_FIGSIZE)
    for ax, sweep, title in zip(axes, sweeps, titles):
        draw_outcome_map(
            ax,
            sweep.outcome,
            *sweep_axes(sweep),
            sweep.sides,
            title=title,
            extent=sweep.extent,
            computed=sweep.computed,
        )
    save_figure(fig, png_path, dpi)
    return Path(png_path)


def plot_refinement(sweep, refine_level, levels, png_path, *, dpi=100):
    """A refined sweep's final-state diagram beside the level each pixel's value came from.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        The refined sweep.
    refine_level : array_like of int, shape (ny, nx)
        Level whose roll gave each pixel its value (``/refine_level``, docs/hdf5.md).
    levels : int
        The finest level (pixels rolled at their own centre).
    png_path : str or pathlib.Path
    dpi : float

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    fig, (ax_outcome, ax_level) = panel_figure(2, dpi)
    axes = sweep_axes(sweep)
    ny, nx = sweep.outcome.shape
    draw_outcome_map(ax_outcome, sweep.outcome, *axes, sweep.sides, title=f"refined sweep, {ny} x {nx}", extent=sweep.extent,
                     computed=sweep.computed)
    simulated = np.mean(np.asarray(refine_level) == levels)
    draw_scalar_map(ax_level, refine_level, *axes, label="level (0 = coarsest)", vmin=0, vmax=levels, extent=sweep.extent,
                    title=f"level of each pixel's roll; {100 * simulated:.1f} % rolled at their own centre ({levels})")
    save_figure(fig, png_path, dpi)
    return Path(png_path)

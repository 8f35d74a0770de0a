"""Pictures: final-state diagrams of a sweep and the path of one roll.

The only module that imports matplotlib. It uses the object API only (``Figure`` drawn on an
Agg canvas, never pyplot), so it keeps no global state and needs no display.

Colours follow Smith 2014: for n = 4 sides 0-3 are red, green, cyan and violet (Fig. 8); for
any other n a rainbow runs from red (side 0) to violet (side n - 1) (Figs 9, 11); undecided
rolls (outcome -1) are black; cells of an incomplete sweep not computed yet are grey.
"""

import math
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap, hsv_to_rgb
from matplotlib.figure import Figure
from matplotlib.patches import Polygon, Rectangle

from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import corners

VIOLET_HUE = 0.78  # HSV hue of the rainbow's last side; 1.0 would wrap back to red
FOUR_SIDE_COLORS = np.array(
    [
        (1.0, 0.0, 0.0, 1.0),  # red
        (0.0, 0.75, 0.0, 1.0),  # green, darker than (0, 1, 0) to stand apart from cyan
        (0.0, 1.0, 1.0, 1.0),  # cyan
        (*hsv_to_rgb((VIOLET_HUE, 1.0, 1.0)), 1.0),  # violet, as the rainbow's end
    ]
)
UNDECIDED_COLOR = (0.0, 0.0, 0.0, 1.0)
NOT_COMPUTED_COLOR = (0.6, 0.6, 0.6, 1.0)  # cells of an incomplete sweep; grey is no side's colour
BOX_COLOR = "white"  # zoom rectangle: absent from every outcome colour table
MAX_SIDE_LABELS = 24  # colour bar ticks beyond this are thinned to stay legible

# Whole inches, so an integer dpi gives exactly figsize * dpi pixels (Agg truncates fractions).
OUTCOME_FIGSIZE = (7, 5)
ROLL_FIGSIZE = (7, 5)
ANIMATION_FIGSIZE = (5, 4)
ANIMATION_DPI = 80
MAX_ANIMATION_FRAMES = 300
PATH_POINTS_PER_FRAME = 40  # samples of the centre's path between two drawn outlines
DPI_RANGE = (10, 1000)  # --dpi; at most 7000 x 5000 pixels (140 MB of RGBA) for OUTCOME_FIGSIZE


def image_formats():
    """File extensions (with the dot) of the pictures a figure can be saved as: the formats
    of matplotlib's Agg canvas, ``.png`` first, then e.g. ``.pdf``, ``.svg``."""
    return tuple(f".{name}" for name in sorted(FigureCanvasAgg.get_supported_filetypes(), key=lambda name: (name != "png", name)))


def check_dpi(dpi, option="--dpi"):
    """``dpi`` if it lies in :data:`DPI_RANGE`, else a one-line :class:`DiceSweepError`."""
    low, high = DPI_RANGE
    if not low <= dpi <= high:
        width, height = OUTCOME_FIGSIZE
        raise DiceSweepError(f"{option}: {dpi} is outside the allowed range [{low}, {high}] "
                             f"(a {width} x {height} inch figure: at most {width * high} x {height * high} pixels)")
    return dpi


# --- final-state diagrams -------------------------------------------------------------------


def axis_label(param, unit):
    """Axis label of a swept parameter, e.g. ``axis_label("omega0", "rad/s") == "omega0 (rad/s)"``.

    Units come with the sweep file (:attr:`dice_sweep.storage.SweepAxis.unit`).
    """
    return f"{param} ({unit})"


def outcome_colors(sides):
    """RGBA colour of each side of an n-gon die in a final-state diagram.

    Parameters
    ----------
    sides : int
        Number of sides n >= 3.

    Returns
    -------
    numpy.ndarray
        Shape (n, 4), values in [0, 1]; row k is the colour of side k. n = 4 gives red, green,
        cyan, violet (Smith 2014, Fig. 8); other n a rainbow of HSV hues from 0 (red) to
        :data:`VIOLET_HUE` (violet). Undecided rolls use :data:`UNDECIDED_COLOR`.
    """
    if sides == 4:
        return FOUR_SIDE_COLORS.copy()
    hsv = np.ones((sides, 3))
    hsv[:, 0] = np.linspace(0.0, VIOLET_HUE, sides)
    return np.column_stack([hsv_to_rgb(hsv), np.ones(sides)])


def _cell_extent(values):
    """(first edge, last edge) of equal cells whose centres are ``values``.

    A single cell has no width to infer; it gets width 1 in the axis unit.
    """
    values = np.asarray(values, dtype=float)
    width = (values[-1] - values[0]) / (len(values) - 1) if len(values) > 1 else 1.0
    return values[0] - width / 2, values[-1] + width / 2


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
        Axis labels with parameter and unit, see :func:`axis_label`.
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
        extent=extent or (*_cell_extent(x_values), *_cell_extent(y_values)),
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


def sweep_figure(sweep, *, box=None, dpi=150):
    """The final-state diagram of a sweep read by :func:`dice_sweep.storage.read_sweep`.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        Outcome map, axes (values, parameter, unit, range), config text and ``complete`` flag;
        an incomplete sweep is drawn (cells not run in :data:`NOT_COMPUTED_COLOR`) and titled so.
    box : tuple of 4 float, optional
        Zoom rectangle ``(xmin, xmax, ymin, ymax)`` in the axes' units.
    dpi : float
        Pixels per inch.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from dice_sweep.config import parse_config

    if box is not None:
        check_box(box, sweep.extent)
    cfg = parse_config(sweep.config_toml, source=f"{sweep.path}: config_toml")
    return outcome_figure(
        sweep.outcome,
        sweep.x.values,
        sweep.y.values,
        axis_label(sweep.x.param, sweep.x.unit),
        axis_label(sweep.y.param, sweep.y.unit),
        sweep.sides,
        title=outcome_title(cfg, sweep.complete and bool(sweep.computed.all())),
        box=box,
        extent=sweep.extent,
        dpi=dpi,
        computed=sweep.computed,
    )


def plot_comparison(h5_paths, png_path, *, titles=None, dpi=100):
    """Final-state diagrams of several sweep files side by side in one PNG.

    Parameters
    ----------
    h5_paths : sequence of str or pathlib.Path
        Sweep files (docs/hdf5.md), drawn left to right.
    png_path : str or pathlib.Path
        PNG to write.
    titles : sequence of str, optional
        One title per panel; default: each file's config title.
    dpi : float
        Pixels per inch.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    from dice_sweep.config import parse_config
    from dice_sweep.storage import read_sweep

    sweeps = [read_sweep(path) for path in h5_paths]
    fig, axes = _panel_figure(len(sweeps), dpi, OUTCOME_FIGSIZE)
    for i, (ax, sweep) in enumerate(zip(axes, sweeps)):
        title = titles[i] if titles else outcome_title(parse_config(sweep.config_toml), sweep.complete)
        draw_outcome_map(
            ax,
            sweep.outcome,
            sweep.x.values,
            sweep.y.values,
            axis_label(sweep.x.param, sweep.x.unit),
            axis_label(sweep.y.param, sweep.y.unit),
            sweep.sides,
            title=title,
            extent=sweep.extent,
            computed=sweep.computed,
        )
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


def plot_residual_curves(curves, png_path, *, dpi=100, bin_width=0.008):
    """Median and 90th percentile of the per-frame pose error against time from the first
    impact, one colour per fit (measured-data reports).

    Parameters
    ----------
    curves : sequence of (label, times, errors)
        ``times`` in s from each track's first impact, ``errors`` in m, one entry per frame.
    png_path : str or pathlib.Path
    dpi : float
    bin_width : float
        Width (s) of the time bins.
    """
    fig = Figure(figsize=(7, 4), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for label, times, errors in curves:
        edges = np.arange(times.min(), times.max() + bin_width, bin_width)
        which = np.digitize(times, edges)
        centres, median, upper = [], [], []
        for k in np.unique(which):
            chosen = errors[which == k]
            centres.append(times[which == k].mean())
            median.append(np.median(chosen) * 1000)
            upper.append(np.percentile(chosen, 90) * 1000)
        line = ax.plot(centres, median, marker="o", label=f"{label} (median)")[0]
        ax.plot(centres, upper, linestyle="--", color=line.get_color(), label=f"{label} (90th percentile)")
    ax.axvline(0.0, color="grey", linewidth=0.8)
    ax.set_xlabel("time from the first impact (s)")
    ax.set_ylabel("pose error sqrt(dx^2 + dy^2 + (R dphi)^2) (mm)")
    ax.legend(fontsize="small")
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


def plot_outcome_file(h5_path, png_path, *, box=None, dpi=150, warn=None):
    """Write the final-state diagram of an HDF5 sweep file (docs/hdf5.md) as a PNG.

    Parameters
    ----------
    h5_path : str or pathlib.Path
        Sweep file, complete or not.
    png_path : str or pathlib.Path
        Picture to write (any of :func:`image_formats`); its size is :data:`OUTCOME_FIGSIZE`
        times ``dpi`` pixels.
    box, dpi
        As in :func:`sweep_figure`; ``dpi`` within :data:`DPI_RANGE`.
    warn : callable, optional
        Called with one line when some cells are not computed yet (an incomplete sweep or
        one shard); they are drawn in :data:`NOT_COMPUTED_COLOR` either way.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    from dice_sweep.storage import read_sweep  # lazy: drawing a roll needs no h5py

    check_dpi(dpi)
    sweep = read_sweep(h5_path)
    missing = int(np.count_nonzero(~sweep.computed))
    if missing and warn is not None:
        warn(f"{h5_path}: {missing} of {sweep.outcome.size} cells not computed yet, drawn grey as 'not computed' "
             "(finish the sweep with --resume, or merge its shards)")
    sweep_figure(sweep, box=box, dpi=dpi).savefig(png_path, dpi=dpi)
    return Path(png_path)


# --- one roll ------------------------------------------------------------------------------


def _default_path_sampler():
    """:func:`dice_sweep.roll.sample_path`, imported only when a roll is drawn."""
    from dice_sweep.roll import sample_path  # lazy: roll imports the numba kernel

    return sample_path


def _die_corners(cfg, state):
    """(n, 2) corners of the die in a state row (x, y, phi, ...)."""
    return corners(cfg.die.sides, cfg.die.circumradius, state[0], state[1], state[2])


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
    xy = _die_corners(cfg, state)
    outline = ax.add_patch(Polygon(xy, closed=True, fill=False, edgecolor="black", linewidth=1.0, alpha=alpha))
    (side0,) = ax.plot(xy[:2, 0], xy[:2, 1], color=outcome_colors(cfg.die.sides)[0], linewidth=2.0, alpha=alpha)
    return outline, side0


def _move_die(artists, cfg, state):
    outline, side0 = artists
    xy = _die_corners(cfg, state)
    outline.set_xy(xy)
    side0.set_data(xy[:2, 0], xy[:2, 1])


def plot_roll(cfg, report, png_path, *, frames=12, dpi=150, path_sampler=None):
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
    path_sampler : callable, optional
        ``(cfg, report, times) -> (T, 6)`` states (x, y, phi, vx, vy, omega) of the centre;
        defaults to :func:`dice_sweep.roll.sample_path`.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    sampler = path_sampler or _default_path_sampler()
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
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


def animate_roll(cfg, report, gif_path, *, fps=30, max_frames=MAX_ANIMATION_FRAMES, path_sampler=None):
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
    sampler = path_sampler or _default_path_sampler()
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
    with writer.saving(fig, str(gif_path), dpi=ANIMATION_DPI):
        for t, state in zip(times, path):
            _move_die(die, cfg, state)
            clock.set_text(f"t = {t:.3f} s")
            writer.grab_frame()
    return Path(gif_path)


# --- chaos measures, control maps, refinement (issue 6, docs/chaos.md) ----------------------

PANEL_FIGSIZE = (6, 5)  # inches per panel of a row of maps


def axis_labels(sweep) -> tuple[str, str]:
    """(x, y) axis labels of a sweep (dice_sweep.storage.SweepData): parameter and unit."""
    return axis_label(sweep.x.param, sweep.x.unit), axis_label(sweep.y.param, sweep.y.unit)


def box_entropy_panel(sweep, entropy, title=None) -> dict:
    """Keyword arguments of :func:`draw_scalar_map` for a map of box entropies.

    Parameters
    ----------
    sweep : dice_sweep.storage.SweepData
        The sweep the entropies were measured on (axes, units, sides).
    entropy : dice_sweep.chaos.BasinEntropy
    title : str, optional
        Default: box size, Sb and Sbb.
    """
    rows, cols = entropy.used_shape
    x_label, y_label = axis_labels(sweep)
    extent = (sweep.x.lo, sweep.x.lo + cols * sweep.x.cell_width, sweep.y.lo, sweep.y.lo + rows * sweep.y.cell_width)
    title = title or f"box entropy, {entropy.box_size} x {entropy.box_size} pixels: Sb = {entropy.sb:.3f}, Sbb = {entropy.sbb:.3f}"
    return dict(values=entropy.box_entropy, x_values=None, y_values=None, x_label=x_label, y_label=y_label,
                title=title, label="nats", vmin=0.0, vmax=math.log(sweep.sides + 1), cmap="magma", extent=extent)


def _panel_figure(panels, dpi, panel_size=None):
    """A Figure with one axes per panel in a row (each ``panel_size`` inches, default
    PANEL_FIGSIZE), and the list of axes."""
    width, height = panel_size or PANEL_FIGSIZE
    fig = Figure(figsize=(width * panels, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, [fig.add_subplot(1, panels, i + 1) for i in range(panels)]


def draw_scalar_map(ax, values, x_values, y_values, x_label, y_label, *, title=None, label=None,
                    vmin=None, vmax=None, cmap="viridis", extent=None):
    """Draw a map of one number per cell (an entropy, a probability, a level) with a colour bar.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    values : array_like of float, shape (ny, nx)
        Row i belongs to ``y_values[i]``.
    x_values, y_values : array_like of float
        Cell centres (equally spaced), used for the extent unless ``extent`` is given.
    x_label, y_label : str
        Axis labels, see :func:`axis_label`.
    title, label : str, optional
        Title of the axes and of the colour bar.
    vmin, vmax : float, optional
        Colour range.
    cmap : str
        Matplotlib colour map name.
    extent : tuple of 4 float, optional
        (xmin, xmax, ymin, ymax).

    Returns
    -------
    matplotlib.image.AxesImage
    """
    image = ax.imshow(
        np.asarray(values, dtype=float), cmap=cmap, vmin=vmin, vmax=vmax, origin="lower",
        extent=extent or (*_cell_extent(x_values), *_cell_extent(y_values)),
        interpolation="nearest", aspect="auto",
    )
    colorbar = ax.figure.colorbar(image, ax=ax)
    if label:
        colorbar.set_label(label)
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    if title:
        ax.set_title(title, fontsize="medium")
    return image


def plot_scalar_maps(panels, png_path, *, dpi=100):
    """Maps of one number per cell side by side in one PNG.

    Parameters
    ----------
    panels : sequence of dict
        Keyword arguments of :func:`draw_scalar_map` (without ``ax``), one per panel.
    png_path : str or pathlib.Path
    dpi : float

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    fig, axes = _panel_figure(len(panels), dpi)
    for ax, panel in zip(axes, panels):
        draw_scalar_map(ax, **panel)
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


def plot_uncertainty_curves(curves, labels, png_path, *, title=None, dpi=100):
    """The uncertain share f(eps) against eps, log-log, each with its fitted power law.

    Parameters
    ----------
    curves : sequence of dice_sweep.chaos.UncertaintyCurve
        Each has ``eps`` (pixels), ``fraction`` and ``fit`` (``alpha``, ``log_prefactor``,
        ``eps_lo``, ``eps_hi`` and ``text()``).
    labels : sequence of str
        Legend entry of each curve.
    png_path : str or pathlib.Path
    title : str, optional
    dpi : float

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    fig, (ax,) = _panel_figure(1, dpi)
    for curve, label, color in zip(curves, labels, _curve_colors(len(curves))):
        shown = curve.fraction > 0
        fit = curve.fit
        ax.loglog(curve.eps[shown], curve.fraction[shown], "o", color=color, markersize=4,
                  label=f"{label}: alpha = {fit.text()}")
        if math.isfinite(fit.alpha):
            eps = np.geomspace(fit.eps_lo, fit.eps_hi, 20)
            ax.loglog(eps, np.exp(fit.log_prefactor) * eps**fit.alpha, "-", color=color, linewidth=1.5)
    ax.set_xlabel("perturbation eps (pixels)")
    ax.set_ylabel("uncertain share f(eps)")
    ax.legend(fontsize="x-small")
    ax.set_title(title or "uncertainty exponent: f ~ eps^alpha on the fitted range (lines)", fontsize="medium")
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


def _curve_colors(count):
    return [hsv_to_rgb((hue, 0.9, 0.8)) for hue in np.linspace(0.0, VIOLET_HUE, max(count, 1))]


def plot_control_map(control, png_path, x_label, y_label, *, title=None, dpi=100):
    """Most likely side, its probability and the outcome entropy of a control map, in one PNG.

    Parameters
    ----------
    control : dice_sweep.chaos.ControlMap
        ``most_likely``, ``p_max``, ``entropy``, axes values, ``sides``, ``method``, ``sigmas``.
    png_path : str or pathlib.Path
    x_label, y_label : str
        Axis labels, see :func:`axis_label`.
    title : str, optional
        Suptitle; default names the method and the scatter.
    dpi : float

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    fig, (ax_side, ax_p, ax_entropy) = _panel_figure(3, dpi)
    axes = (control.x_values, control.y_values, x_label, y_label)
    draw_outcome_map(ax_side, control.most_likely, *axes, control.sides, title="most likely side")
    draw_scalar_map(ax_p, control.p_max, *axes, title="its probability", label="probability", vmin=0.0, vmax=1.0)
    draw_scalar_map(ax_entropy, control.entropy, *axes, title="outcome entropy", label="nats",
                    vmin=0.0, vmax=math.log(control.sides), cmap="magma")
    sigmas = ", ".join(f"sigma({name}) = {value:g}" for name, value in control.sigmas.items())
    fig.suptitle(title or f"{control.method.replace('_', ' ')}: {sigmas}", fontsize="medium")
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)


# --- measured impacts (docs/calibration.md) ------------------------------------------------

CALIBRATION_FIGSIZE = (10, 7)
CALIBRATION_RANGE = (2.0, 98.0)  # percentiles of all values that set each panel's x range


def plot_calibration(result, png_path, *, dpi=120, bins=40):
    """Histograms of the restitution coefficients measured at the impacts of tracked drops.

    One panel per coefficient (eq. 9, eq. 10 and their corner counterparts): clean first
    impacts filled, all clean impacts outlined, medians dashed. Values beyond the 2nd-98th
    percentiles of all impacts are left out of the picture and counted in the title.

    Parameters
    ----------
    result : dice_sweep.measured.calibrate.CalibrationResult
    png_path : str or pathlib.Path
    dpi : float
    bins : int
        Bins over each panel's range.

    Returns
    -------
    pathlib.Path
        ``png_path``.
    """
    from dice_sweep.measured.calibrate import COEFFICIENTS  # lazy: only this picture needs it

    fig = Figure(figsize=CALIBRATION_FIGSIZE, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    for panel, (name, meaning) in enumerate(COEFFICIENTS.items()):
        ax = fig.add_subplot(2, 2, panel + 1)
        first, every = result.values(name, "first"), result.values(name, "all")
        if every.size:
            low, high = np.percentile(every, CALIBRATION_RANGE)
            edges = np.linspace(low, high, bins + 1) if high > low else bins
            ax.hist(every, bins=edges, histtype="step", color="black", label=f"all impacts ({every.size})")
            ax.hist(first, bins=edges, color="tab:blue", alpha=0.6, label=f"first impacts ({first.size})")
            for values, color in ((every, "black"), (first, "tab:blue")):
                if values.size:
                    ax.axvline(np.median(values), color=color, linestyle="--", linewidth=1)
            hidden = int(np.count_nonzero((every < low) | (every > high)))
            ax.legend(fontsize="small")
        else:
            hidden = 0
            ax.text(0.5, 0.5, "no clean impact", transform=ax.transAxes, ha="center")
        ax.set_title(f"{name}: {meaning}" + (f" ({hidden} outside)" if hidden else ""), fontsize="small")
        ax.set_xlabel(name)
        ax.set_ylabel("impacts")
    fig.suptitle(f"{Path(result.path).name}: coefficients per impact", fontsize="medium")
    fig.savefig(png_path, dpi=dpi)
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
    fig, (ax_outcome, ax_level) = _panel_figure(2, dpi)
    axes = (sweep.x.values, sweep.y.values, axis_label(sweep.x.param, sweep.x.unit), axis_label(sweep.y.param, sweep.y.unit))
    ny, nx = sweep.outcome.shape
    draw_outcome_map(ax_outcome, sweep.outcome, *axes, sweep.sides, title=f"refined sweep, {ny} x {nx}", extent=sweep.extent,
                     computed=sweep.computed)
    simulated = np.mean(np.asarray(refine_level) == levels)
    draw_scalar_map(ax_level, refine_level, *axes, label="level (0 = coarsest)", vmin=0, vmax=levels, extent=sweep.extent,
                    title=f"level of each pixel's roll; {100 * simulated:.1f} % rolled at their own centre ({levels})")
    fig.savefig(png_path, dpi=dpi)
    return Path(png_path)

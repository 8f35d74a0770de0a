"""What every picture shares: the side colours of Smith 2014, figure sizes, the picture formats
and resolutions allowed, axis labels, a row of panels, a map of one number per cell.
"""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import hsv_to_rgb
from matplotlib.figure import Figure

from dice_sweep.errors import DiceSweepError
from dice_sweep.outputs import written


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


def save_figure(fig, path, dpi):
    """Save ``fig`` to ``path`` (its format by the extension) whole or not at all: under a
    temporary name, renamed once complete (dice_sweep.outputs.written). Returns ``path``."""
    with written(path) as temporary:
        fig.savefig(temporary, dpi=dpi)
    return Path(path)


def check_dpi(dpi, option="--dpi"):
    """``dpi`` if it lies in :data:`DPI_RANGE`, else a one-line :class:`DiceSweepError`."""
    low, high = DPI_RANGE
    if not low <= dpi <= high:
        width, height = OUTCOME_FIGSIZE
        raise DiceSweepError(f"{option}: {dpi} is outside the allowed range [{low}, {high}] "
                             f"(a {width} x {height} inch figure: at most {width * high} x {height * high} pixels)")
    return dpi


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


def cell_extent(values):
    """(first edge, last edge) of equal cells whose centres are ``values``.

    A single cell has no width to infer; it gets width 1 in the axis unit.
    """
    values = np.asarray(values, dtype=float)
    width = (values[-1] - values[0]) / (len(values) - 1) if len(values) > 1 else 1.0
    return values[0] - width / 2, values[-1] + width / 2


PANEL_FIGSIZE = (6, 5)  # inches per panel of a row of maps


def axis_labels(sweep) -> tuple[str, str]:
    """(x, y) axis labels of a sweep (dice_sweep.storage.SweepData): parameter and unit."""
    return axis_label(sweep.x.param, sweep.x.unit), axis_label(sweep.y.param, sweep.y.unit)


def sweep_axes(sweep) -> tuple:
    """(x values, y values, x label, y label) of a sweep: the axes arguments of
    :func:`~dice_sweep.plotting.maps.draw_outcome_map` and ``outcome_figure``."""
    return (sweep.x.values, sweep.y.values, *axis_labels(sweep))


def panel_figure(panels, dpi, panel_size=None):
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
        extent=extent or (*cell_extent(x_values), *cell_extent(y_values)),
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

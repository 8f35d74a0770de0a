"""Pictures of the chaos measures and control maps (docs/chaos.md): maps of box entropies,
uncertainty curves f(eps), the most likely side and its probability.
"""

import math
from pathlib import Path

import numpy as np
from matplotlib.colors import hsv_to_rgb
from dice_sweep.plotting.maps import draw_outcome_map
from dice_sweep.plotting.common import (
    save_figure,
    VIOLET_HUE,
    panel_figure,
    axis_labels,
    draw_scalar_map,
)



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
    fig, axes = panel_figure(len(panels), dpi)
    for ax, panel in zip(axes, panels):
        draw_scalar_map(ax, **panel)
    save_figure(fig, png_path, dpi)
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
    fig, (ax,) = panel_figure(1, dpi)
    for curve, label, color in zip(curves, labels, curve_colors(len(curves))):
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
    save_figure(fig, png_path, dpi)
    return Path(png_path)


def curve_colors(count):
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
    fig, (ax_side, ax_p, ax_entropy) = panel_figure(3, dpi)
    axes = (control.x_values, control.y_values, x_label, y_label)
    draw_outcome_map(ax_side, control.most_likely, *axes, control.sides, title="most likely side")
    draw_scalar_map(ax_p, control.p_max, *axes, title="its probability", label="probability", vmin=0.0, vmax=1.0)
    draw_scalar_map(ax_entropy, control.entropy, *axes, title="outcome entropy", label="nats",
                    vmin=0.0, vmax=math.log(control.sides), cmap="magma")
    sigmas = ", ".join(f"sigma({name}) = {value:g}" for name, value in control.sigmas.items())
    fig.suptitle(title or f"{control.method.replace('_', ' ')}: {sigmas}", fontsize="medium")
    save_figure(fig, png_path, dpi)
    return Path(png_path)

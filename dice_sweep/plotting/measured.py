"""Pictures of the measured-data loop: the per-impact coefficients of calibrate, and the pose
error against time of a fit.
"""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from dice_sweep.plotting.common import save_figure


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
    ax.set_ylabel("pose error (mm)\nsqrt(dx^2 + dy^2 + (R dphi)^2)")
    # outside the axes: with every track held out (cross-fitting) the curves fill the axes, and
    # a legend inside covered the line at the first impact
    fig.legend(loc="outside lower center", ncols=4, fontsize="small")
    save_figure(fig, png_path, dpi)
    return Path(png_path)


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
    fig = Figure(figsize=CALIBRATION_FIGSIZE, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    for panel, (name, meaning) in enumerate(result.coefficients.items()):
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
    save_figure(fig, png_path, dpi)
    return Path(png_path)

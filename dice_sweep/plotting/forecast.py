"""Pictures of the side forecasts of tracked drops (issue 18): the reliability diagram, skill
against the forecast point, and the final-state map of the release states with the drops on it.
"""

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from dice_sweep.plotting.common import outcome_colors, save_figure
from dice_sweep.plotting.maps import draw_outcome_map, outcome_title

FORECAST_FIGSIZE = (10, 4)
MAP_FIGSIZE = (7, 5)


def _figure(size, dpi):
    fig = Figure(figsize=size, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def plot_reliability(curves, png_path, *, title=None, dpi=100):
    """The reliability diagram: observed frequency against predicted probability (every track
    and side a pair), with 95 % Wilson intervals, the diagonal of a calibrated forecast; and
    beside it the number of pairs per bin.

    Parameters
    ----------
    curves : sequence of (label, bins)
        ``bins`` as :func:`dice_sweep.measured.forecast.reliability` gives them (dicts with
        ``p_low``, ``p_high``, ``pairs`` and, when not empty, ``mean_predicted``,
        ``observed_frequency``, ``ci95``).
    png_path : str or pathlib.Path
    """
    fig = _figure(FORECAST_FIGSIZE, dpi)
    ax, counts = fig.subplots(1, 2, width_ratios=(3, 2))
    ax.plot([0, 1], [0, 1], color="grey", linewidth=0.8, label="calibrated")
    for k, (label, bins) in enumerate(curves):
        full = [b for b in bins if b["pairs"]]
        x = np.array([b["mean_predicted"] for b in full])
        y = np.array([b["observed_frequency"] for b in full])
        low = np.array([b["ci95"][0] for b in full])
        high = np.array([b["ci95"][1] for b in full])
        # clipped: a bin with no hit has a Wilson lower end a round-off above 0 (make forecast failed on it)
        ax.errorbar(x + 0.004 * k, y, yerr=np.clip([y - low, high - y], 0.0, None), marker="o", capsize=3, label=label)
        edges = [b["p_low"] for b in bins] + [bins[-1]["p_high"]]
        counts.stairs([b["pairs"] for b in bins], edges, label=label)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("predicted probability of a side")
    ax.set_ylabel("observed frequency (95 % interval)")
    ax.legend(fontsize="small", loc="upper left")
    counts.set_yscale("log")
    counts.set_xlabel("predicted probability of a side")
    counts.set_ylabel("(track, side) pairs per bin")
    if title:
        fig.suptitle(title, fontsize="medium")
    save_figure(fig, png_path, dpi)
    return Path(png_path)


def _series(by_bounce, path):
    """(K, value, low, high) of one entry (``path``: keys into each block) over the blocks that
    have it."""
    rows = []
    for block in by_bounce:
        entry = block
        for key in path:
            entry = entry.get(key) if isinstance(entry, dict) else None
        if isinstance(entry, dict) and entry.get("value") is not None:
            rows.append((block["from_bounce"], entry["value"], *entry["ci95"]))
    return np.array(rows, dtype=float).reshape(-1, 4)


def plot_skill_by_bounce(by_bounce, sides, png_path, *, title=None, dpi=100):
    """How many bounces ahead the die is predictable: the log skill over the uniform forecast
    (nats; 0 = no better than 1/n) of the ensemble, of the deterministic forecast and of the
    recalibrated ensemble; and the share of tracks whose most likely side happened, with 95 %
    intervals, against the flight the forecast starts from."""
    fig = _figure(FORECAST_FIGSIZE, dpi)
    skill, share = fig.subplots(1, 2)
    series = [("ensemble", ("log_skill",)), ("deterministic (floor of the ensemble's size)", ("log_skill_deterministic",)),
              ("recalibrated ensemble", ("recalibrated", "log_skill"))]
    for k, (label, path) in enumerate(series):
        rows = _series(by_bounce, path)
        if not len(rows):
            continue
        skill.errorbar(rows[:, 0] + 0.06 * (k - 1), rows[:, 1], yerr=[rows[:, 1] - rows[:, 2], rows[:, 3] - rows[:, 1]], marker="o",
                       capsize=3, label=label)
    skill.axhline(0.0, color="grey", linewidth=0.8)
    skill.axhline(np.log(sides), color="grey", linewidth=0.8, linestyle=":", label=f"certainty (ln {sides})")
    skill.set_xlabel("forecast from flight K (0 = release)")
    skill.set_ylabel("log score - log score of 1/n (nats)")
    skill.legend(fontsize="small")
    for k, (label, key) in enumerate((("most likely side of the ensemble", "share_correct_most_likely"),
                                      ("deterministic forecast", "share_correct_deterministic"))):
        rows = _series(by_bounce, (key,))
        share.errorbar(rows[:, 0] + 0.06 * k, rows[:, 1], yerr=[rows[:, 1] - rows[:, 2], rows[:, 3] - rows[:, 1]], marker="o",
                       capsize=3, label=label)
    share.axhline(1.0 / sides, color="grey", linewidth=0.8, label=f"chance (1/{sides})")
    share.set_ylim(0, 1)
    share.set_xlabel("forecast from flight K (0 = release)")
    share.set_ylabel("share of held-out tracks right")
    share.legend(fontsize="small")
    for ax in (skill, share):
        ax.set_xticks([b["from_bounce"] for b in by_bounce])
    if title:
        fig.suptitle(title, fontsize="medium")
    save_figure(fig, png_path, dpi)
    return Path(png_path)


def plot_release_map(release, cfg, png_path, *, dpi=120):
    """The final-state map over the release states with the drops on it.

    ``release``: a dict with ``outcome`` (ny, nx), ``x``, ``y`` (cell centres), ``x_label``,
    ``y_label``, ``drops_x``, ``drops_y`` (each drop's release state on the two axes),
    ``drops_side`` (the side it rested on, relabelled as for the folded angle), ``held_out``
    (bool per drop). ``cfg``: the model's config (title). Held-out drops are circles, the others
    small dots; each is filled with its resting side's colour and edged in black.
    """
    fig = _figure(MAP_FIGSIZE, dpi)
    ax = fig.add_subplot()
    sides = cfg.die.sides
    draw_outcome_map(ax, release["outcome"], release["x"], release["y"], release["x_label"], release["y_label"], sides,
                     title=outcome_title(cfg))
    colors = outcome_colors(sides)
    side = np.asarray(release["drops_side"], dtype=int)
    held = np.asarray(release["held_out"], dtype=bool)
    x, y = np.asarray(release["drops_x"]), np.asarray(release["drops_y"])
    ax.scatter(x[~held], y[~held], s=9, c=colors[side[~held]], edgecolors="black", linewidths=0.4, label="selection drops")
    ax.scatter(x[held], y[held], s=26, c=colors[side[held]], edgecolors="black", linewidths=0.8, label="held-out drops")
    ax.legend(fontsize="x-small", loc="upper right", framealpha=0.8)
    save_figure(fig, png_path, dpi)
    return Path(png_path)

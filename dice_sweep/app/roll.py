"""The ``roll`` command: one roll of a config, its result, and its path drawn or animated."""

from __future__ import annotations

from dice_sweep.config import check_computable, check_initial_clear
from dice_sweep.roll import roll_config, sample_path


def roll(cfg, overrides=(), *, png_path=None, gif_path=None):
    """Roll ``cfg`` from its [initial] state (refused if a corner starts inside a surface);
    draw the path to ``png_path`` and animate it to ``gif_path`` if asked.
    Returns (RollReport, pictures written)."""
    check_initial_clear(cfg, overrides)
    check_computable(cfg, overrides)
    report = roll_config(cfg)
    written = []
    if png_path or gif_path:
        from dice_sweep.plotting import animate_roll, plot_roll  # matplotlib: only for a picture (start-up time)
    if png_path:
        written.append(plot_roll(cfg, report, png_path, sample_path))
    if gif_path:
        written.append(animate_roll(cfg, report, gif_path, sample_path))
    return report, written

"""Tests of dice_sweep.plotting.forecast: the reliability diagram, skill by bounce and the release
map, drawn from numbers given to it (the numbers: tests/measured/test_forecast.py; the command:
tests/app/test_forecast.py)."""

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from dice_sweep import plotting
from dice_sweep.config import default_config
from tests.helpers import figure_pixels, map_region, near, png_size, read_png, share

FIRST = to_rgb("C0")  # matplotlib's first series colour


def rising(image, colour, tol=0.1):
    """Whether the pixels of ``colour`` sit lower on the left than on the right (rows count down)."""
    rows, columns = np.nonzero(near(image, colour, tol))
    assert rows.size > 20, "colour not drawn"
    middle = np.median(columns)
    return np.median(rows[columns < middle]) > np.median(rows[columns > middle])


def bin_of(low, high, pairs, predicted=None, observed=None):
    entry = {"p_low": low, "p_high": high, "pairs": pairs}
    if pairs:
        entry.update(mean_predicted=predicted, observed_frequency=observed, ci95=(observed - 0.05, observed + 0.05))
    return entry


def test_reliability_diagram_puts_each_bin_at_its_predicted_and_observed_frequency(tmp_path):
    bins = [bin_of(0.0, 0.2, 40, 0.1, 0.12), bin_of(0.2, 0.6, 0), bin_of(0.6, 1.0, 30, 0.85, 0.8)]  # an empty bin between
    png = plotting.plot_reliability([("ensemble", bins)], tmp_path / "r.png", title="t", dpi=50)
    assert png_size(png) == figure_pixels(plotting.FORECAST_FIGSIZE, 50)
    image = read_png(png)
    left = image[:, : int(0.6 * image.shape[1])]  # the diagram (3 of 5 parts of the width)
    assert rising(left, FIRST)  # from (0.1, 0.12) up to (0.85, 0.8)


def test_a_bin_with_no_hit_is_drawn(tmp_path):
    """Its Wilson interval's lower end is a round-off above 0 (make forecast crashed on it)."""
    empty = {"p_low": 0.0, "p_high": 0.1, "pairs": 3, "mean_predicted": 0.095, "observed_frequency": 0.0, "ci95": (1e-17, 0.56)}
    png = plotting.plot_reliability([("ensemble", [empty, bin_of(0.2, 0.6, 30, 0.4, 0.45)])], tmp_path / "r.png", dpi=50)
    assert png.exists()


def skill_block(k, value):
    entry = lambda v: {"value": v, "ci95": (v - 0.05, v + 0.05)} if v is not None else None
    return {"from_bounce": k, "log_skill": entry(value), "log_skill_deterministic": entry(None),
            "share_correct_most_likely": entry(0.3 + 0.2 * k), "share_correct_deterministic": entry(None)}


def test_skill_by_bounce_draws_the_series_that_have_values(tmp_path):
    by_bounce = [skill_block(0, 0.1), skill_block(1, 0.6), skill_block(2, 1.1)]
    png = plotting.plot_skill_by_bounce(by_bounce, 4, tmp_path / "s.png", dpi=50)
    assert png_size(png) == figure_pixels(plotting.FORECAST_FIGSIZE, 50)
    image = read_png(png)
    half = image.shape[1] // 2
    assert rising(image[:, :half], FIRST)  # the log skill rises with K
    assert rising(image[:, half:], FIRST)  # and so does the share right
    # a block without a value is left out, not drawn at 0 or an error
    by_bounce[1]["log_skill"] = None
    plotting.plot_skill_by_bounce(by_bounce, 4, tmp_path / "gap.png", dpi=50)


def test_release_map_shows_the_map_and_each_drop_in_its_sides_colour(tmp_path):
    cfg = default_config()
    outcome = np.zeros((40, 40), np.int8)  # all side 0 (red)
    release = dict(outcome=outcome, x=np.linspace(0.0, 1.0, 40), y=np.linspace(0.0, 1.0, 40), x_label="a", y_label="b",
                   drops_x=[0.2, 0.4, 0.6, 0.8], drops_y=[0.5] * 4, drops_side=[2] * 4, held_out=[False] * 4)
    png = plotting.plot_release_map(release, cfg, tmp_path / "few.png", dpi=60)
    assert png_size(png) == figure_pixels(plotting.forecast.MAP_FIGSIZE, 60)
    cyan = plotting.outcome_colors(4)[2]
    region = map_region(read_png(png), [plotting.outcome_colors(4)[0], cyan])
    small = share(region, cyan)
    assert small > 0  # the drops, in the colour of the side they rested on
    held = plotting.plot_release_map({**release, "held_out": [True] * 4}, cfg, tmp_path / "held.png", dpi=60)
    assert share(map_region(read_png(held), [plotting.outcome_colors(4)[0], cyan]), cyan) > 2 * small  # held out: larger
    assert share(region, plotting.outcome_colors(4)[0]) > 0.9
    assert share(region, plotting.outcome_colors(4)[0]) == pytest.approx(1.0 - small, abs=0.05)

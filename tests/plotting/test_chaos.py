"""Tests of dice_sweep.plotting.chaos: maps of box entropies, uncertainty curves and control
maps drawn from measures given to it (their numbers: tests/chaos/; the commands writing them:
tests/app/test_chaos.py)."""

import math
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from dice_sweep import plotting
from dice_sweep.chaos import basin_entropy, checkerboard_map, straight_boundary_map, uncertainty_curve
from tests.helpers import figure_pixels, map_region, near, png_size, read_png, share

MAGMA = matplotlib.colormaps["magma"]


def axis(lo, width, num, param, unit):
    return SimpleNamespace(lo=lo, cell_width=width, values=lo + (np.arange(num) + 0.5) * width, param=param, unit=unit)


def test_box_entropy_panel_spans_the_boxes_used_in_the_axes_units():
    outcome = straight_boundary_map((23, 31), 0.0, 11)  # 4 x 6 boxes of 5 pixels; 3 rows, 1 column left out
    entropy = basin_entropy(outcome, 5)
    sweep = SimpleNamespace(x=axis(10.0, 0.5, 31, "omega0", "rad/s"), y=axis(0.02, 0.001, 23, "y0", "m"), sides=4)
    panel = plotting.box_entropy_panel(sweep, entropy)
    assert panel["extent"] == pytest.approx((10.0, 10.0 + 30 * 0.5, 0.02, 0.02 + 20 * 0.001), rel=1e-15)
    assert panel["values"] is entropy.box_entropy
    assert (panel["vmin"], panel["vmax"]) == (0.0, math.log(5))  # n sides and undecided
    assert (panel["x_label"], panel["y_label"], panel["label"], panel["cmap"]) == ("omega0 (rad/s)", "y0 (m)", "nats", "magma")
    assert panel["title"] == f"box entropy, 5 x 5 pixels: Sb = {entropy.sb:.3f}, Sbb = {entropy.sbb:.3f}"
    assert plotting.box_entropy_panel(sweep, entropy, title="mine")["title"] == "mine"


def test_scalar_maps_are_drawn_one_panel_each_in_their_colour_maps(tmp_path):
    values = np.zeros((20, 20))
    values[:, 15:] = math.log(5)  # a quarter at the top of the range
    panel = dict(values=values, x_values=np.arange(20.0), y_values=np.arange(20.0), x_label="x", y_label="y",
                 vmin=0.0, vmax=math.log(5), cmap="magma")
    png = plotting.plot_scalar_maps([panel, {**panel, "values": values[:, ::-1]}], tmp_path / "maps.png", dpi=40)
    width, height = figure_pixels(plotting.PANEL_FIGSIZE, 40)
    assert png_size(png) == (2 * width, height)
    image = read_png(png)
    for k, column in ((0, -1), (1, 0)):  # the top of the range on the right, then on the left
        region = map_region(image[:, k * width : (k + 1) * width])
        assert share(region, MAGMA(1.0)) == pytest.approx(0.25, abs=0.03), k
        assert np.mean(near(region[:, column], MAGMA(1.0))) > 0.9, k


def test_curve_colours_are_distinct_and_start_at_red():
    colours = plotting.curve_colors(3)
    assert len(colours) == 3 and len({tuple(np.round(c, 6)) for c in colours}) == 3
    np.testing.assert_allclose(colours[0], (0.8, 0.08, 0.08))  # HSV (0, 0.9, 0.8)
    assert len(plotting.curve_colors(0)) == 1


def test_uncertainty_curves_draw_each_curve_in_its_colour_falling_to_the_left(tmp_path):
    curves = [uncertainty_curve(straight_boundary_map((200, 200), 0.3, 90.3)), uncertainty_curve(checkerboard_map((200, 200), 10))]
    assert curves[1].fraction[0] > 5 * curves[0].fraction[0]  # apart on the plot
    png = plotting.plot_uncertainty_curves(curves, ["line", "checkerboard"], tmp_path / "f.png", dpi=60)
    assert png_size(png) == figure_pixels(plotting.PANEL_FIGSIZE, 60)
    image = read_png(png)
    for colour in plotting.curve_colors(2):
        rows, columns = np.nonzero(near(image, colour, tol=0.1))
        assert rows.size > 50
        left, right = columns < np.median(columns), columns > np.median(columns)
        assert np.median(rows[left]) > np.median(rows[right])  # f rises with eps; rows count down


def test_control_map_draws_the_side_its_probability_and_the_entropy(tmp_path):
    most_likely = np.zeros((10, 12), np.int8)
    most_likely[:, 6:] = 2
    p_max = np.where(most_likely == 2, 1.0, 0.5)
    control = SimpleNamespace(most_likely=most_likely, p_max=p_max, entropy=np.where(p_max == 1.0, 0.0, math.log(2)),
                              x_values=np.arange(12.0), y_values=np.arange(10.0), sides=4, method="blur",
                              sigmas={"y0": 0.001})
    png = plotting.plot_control_map(control, tmp_path / "c.png", "x (m)", "y (m)", dpi=40)
    width, height = figure_pixels(plotting.PANEL_FIGSIZE, 40)
    assert png_size(png) == (3 * width, height)
    image = read_png(png)
    colours = plotting.outcome_colors(4)
    region = map_region(image[:, :width], [colours[0], colours[2]])
    assert share(region, colours[0]) == pytest.approx(0.5, abs=0.03) and share(region, colours[2]) == pytest.approx(0.5, abs=0.03)
    viridis = matplotlib.colormaps["viridis"]
    assert share(map_region(image[:, width : 2 * width]), viridis(1.0)) == pytest.approx(0.5, abs=0.03)
    assert share(map_region(image[:, 2 * width :]), MAGMA(0.0)) == pytest.approx(0.5, abs=0.03)  # entropy 0

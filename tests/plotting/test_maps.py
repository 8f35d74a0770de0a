"""Tests of dice_sweep.plotting.maps: final-state diagrams - the image's extent and cells,
the colour bar, the --box rectangle and its parsing, titles, a sweep file's figure, the
comparison and refinement pictures."""

import matplotlib
import numpy as np
import pytest

from dice_sweep import config, plotting, storage
from dice_sweep.app.sweep import diagram_title
from dice_sweep.errors import DiceSweepError
from tests.helpers import figure_pixels, map_region, near, pixel_at, pixels_around, png_size, read_png
from tests.plotting.drawn import (
    BLOCK_CONFIG_TOML,
    BLOCK_OUTCOME,
    BLOCK_X,
    BLOCK_Y,
    COLOR_TOLERANCE,
    table_one_config,
    write_block_sweep,
    write_sweep_file,
)


def block_figure(box=None, dpi=50):
    return plotting.outcome_figure(
        BLOCK_OUTCOME, BLOCK_X, BLOCK_Y, "omega0 (rad/s)", "y0 (m)", 4, title="blocks", box=box, dpi=dpi
    )


def test_image_extent_is_the_outer_cell_edges():
    fig = block_figure()
    image = fig.axes[0].images[0]
    np.testing.assert_allclose(image.get_extent(), (0.0, 60.0, 0.02, 0.30))
    assert image.origin == "lower"
    assert image.get_interpolation() == "nearest"


def test_colour_bar_names_every_side_and_undecided():
    fig = block_figure()
    colorbar_axes = fig.axes[1]
    labels = [label.get_text() for label in colorbar_axes.get_yticklabels()]
    assert labels == ["undecided", "side 0", "side 1", "side 2", "side 3"]


@pytest.mark.parametrize(
    "x, y, expected",
    [
        (15.0, 0.09, plotting.outcome_colors(4)[0]),
        (45.0, 0.09, plotting.outcome_colors(4)[1]),
        (15.0, 0.23, plotting.outcome_colors(4)[3]),
        (45.0, 0.23, plotting.UNDECIDED_COLOR),
    ],
)
def test_rendered_cell_has_its_side_colour(tmp_path, x, y, expected):
    png = tmp_path / "map.png"
    fig = block_figure(dpi=60)
    fig.savefig(png, dpi=60)
    np.testing.assert_allclose(pixel_at(fig, x, y, png), expected, atol=COLOR_TOLERANCE)


def test_box_rectangle_is_drawn(tmp_path):
    box = (6.0, 27.0, 0.04, 0.12)  # inside the red block: its white edges stand out
    on_left_edge = (box[0], 0.08)
    with_box, without_box = tmp_path / "box.png", tmp_path / "plain.png"
    fig = block_figure(box=box, dpi=80)
    fig.savefig(with_box, dpi=80)
    plain = block_figure(dpi=80)
    plain.savefig(without_box, dpi=80)
    whitest = pixels_around(fig, *on_left_edge, with_box, reach=2)[:, :3].min(axis=1).max()
    assert whitest > 0.5  # antialiasing may spread the line over two partly covered pixels
    plain_pixels = pixels_around(plain, *on_left_edge, without_box, reach=2)
    np.testing.assert_allclose(plain_pixels, np.tile((1, 0, 0, 1), (25, 1)), atol=COLOR_TOLERANCE)


def test_parse_box_reads_four_numbers_and_rejects_others():
    assert plotting.parse_box("0,1.5,-2,3e-2") == (0.0, 1.5, -2.0, 0.03)
    for bad in ["0,1,2", "0,1,2,x", "1,0,0,1", "0,1,1,1", "0,inf,0,1"]:
        with pytest.raises(DiceSweepError, match="--box"):
            plotting.parse_box(bad)


def test_title_gives_sides_coefficients_walls_and_incompleteness():
    assert plotting.outcome_title(table_one_config()) == (
        "n = 4, beta_normal = 0.2, beta_tangential = -0.35, no walls"
    )
    title = plotting.outcome_title(table_one_config(sides=5, separation=0.2), complete=False)
    assert title == "n = 5, beta_normal = 0.2, beta_tangential = -0.35, walls 0.2 m apart (incomplete)"


@pytest.mark.parametrize("complete", [True, False])
def test_sweep_file_is_drawn_with_axes_title_and_cell_colours(tmp_path, complete):
    h5 = write_block_sweep(tmp_path / "sweep.h5", complete)
    png = tmp_path / "map.png"
    sweep_data = storage.read_sweep(h5)
    fig = plotting.sweep_figure(sweep_data, diagram_title(sweep_data), dpi=60)
    fig.savefig(png, dpi=60)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("omega0 (rad/s)", "y0 (m)")
    assert ax.get_title().startswith("n = 4, beta_normal = 0.2, beta_tangential = -0.35, walls 0.2 m apart")
    assert ax.get_title().endswith("(incomplete)") != complete
    np.testing.assert_allclose(ax.images[0].get_extent(), (0.0, 60.0, 0.02, 0.30))
    np.testing.assert_allclose(pixel_at(fig, 45.0, 0.09, png), plotting.outcome_colors(4)[1], atol=COLOR_TOLERANCE)




def test_a_box_outside_the_map_is_refused_naming_the_allowed_range(tmp_path):
    extent = (0.0, 60.0, 0.02, 0.30)
    assert plotting.check_box((0.0, 60.0, 0.02, 0.30), extent) == extent  # edges included
    with pytest.raises(DiceSweepError, match=r"^--box: 10,70,0.1,0.2 is not inside the map \(allowed: XMIN, XMAX in \[0, 60\]"):
        plotting.check_box((10.0, 70.0, 0.1, 0.2), extent)
    sweep_data = storage.read_sweep(write_block_sweep(tmp_path / "b.h5"))
    with pytest.raises(DiceSweepError, match="--box"):
        plotting.sweep_figure(sweep_data, "t", box=(0.0, 60.0, 0.0, 0.1))  # below the map's 0.02


def test_title_names_every_effect_that_is_on():
    cfg = config.parse_config('[contact]\nmodel = "rigid"\nfriction = 0.5\n[effects]\nair_drag = 0.02\n'
                              'com_offset = [0.001, 0.0]\nspeed_restitution = 0.1\n[world]\ng = 3.7\n')
    first, second = plotting.outcome_title(cfg).split("\n")
    assert first.startswith("n = 4, beta_normal = ")
    assert second == "rigid model, mu = 0.5, drag 0.02/m, loaded (0.001, 0) m, k = 0.1 s/m, g = 3.7"
    scattered = config.parse_config("[scatter]\ncorner = 0.0458\nflat = 0.0938\ndraws = 4\n")
    assert plotting.outcome_title(scattered).split("\n")[1] == "impacts scattered: corner 0.0458, flat 0.0938"
    assert "\n" not in plotting.outcome_title(config.parse_config("[scatter]\ndraws = 4\n"))
    floored = config.parse_config("[scatter]\ncorner = 0.03\ncorner_floor = 0.12\nflat_floor = 0.05\n")
    assert plotting.outcome_title(floored).endswith("corner 0.03, flat 0 (floors 0.12, 0.05 sqrt(gR))")


def test_comparison_draws_each_sweep_in_its_own_panel(tmp_path):
    left = write_block_sweep(tmp_path / "left.h5")
    flipped = write_sweep_file(tmp_path / "right.h5", config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME[::-1].copy(), True)
    sweeps = [storage.read_sweep(left), storage.read_sweep(flipped)]
    png = plotting.plot_comparison(sweeps, ["as is", "flipped"], tmp_path / "both.png", dpi=40)
    width, height = figure_pixels(plotting.OUTCOME_FIGSIZE, 40)
    assert png_size(png) == (2 * width, height)
    image = read_png(png)
    colours = [*plotting.outcome_colors(4), plotting.UNDECIDED_COLOR]
    for panel, outcome in enumerate([BLOCK_OUTCOME, BLOCK_OUTCOME[::-1]]):
        region = map_region(image[:, panel * width : (panel + 1) * width], colours)
        top = region[: region.shape[0] // 4]  # the top rows of the map: outcome's last rows
        top_left, top_right = top[:, : top.shape[1] // 4], top[:, -top.shape[1] // 4 :]
        expected_left, expected_right = outcome[-1, 0], outcome[-1, -1]
        colour = lambda code: plotting.UNDECIDED_COLOR if code < 0 else plotting.outcome_colors(4)[code]
        assert np.mean(near(top_left, colour(expected_left))) > 0.9, panel
        assert np.mean(near(top_right, colour(expected_right))) > 0.9, panel


def test_refinement_picture_has_the_map_and_the_levels(tmp_path):
    sweep_data = storage.read_sweep(write_block_sweep(tmp_path / "b.h5"))
    levels = np.zeros(BLOCK_OUTCOME.shape, int)
    levels[:, :5] = 3  # a quarter of the pixels rolled at the finest level
    png = plotting.plot_refinement(sweep_data, levels, 3, tmp_path / "refine.png", dpi=40)
    width, height = figure_pixels(plotting.PANEL_FIGSIZE, 40)
    assert png_size(png) == (2 * width, height)
    region = map_region(read_png(png)[:, width:])
    viridis = matplotlib.colormaps["viridis"]
    assert np.mean(near(region, viridis(1.0), tol=0.05)) == pytest.approx(0.25, abs=0.05)  # level 3 of 3: yellow
    assert np.mean(near(region, viridis(0.0), tol=0.05)) == pytest.approx(0.75, abs=0.05)


def test_shaded_sides_fade_the_most_likely_colour_to_white_at_equal_shares():
    colors = plotting.outcome_colors(4)[:, :3]
    p = np.zeros((5, 1, 4))
    p[2, 0, 0] = 1.0  # side 2 sure
    p[:, 0, 1] = 0.2  # five outcomes equally likely: white
    p[1, 0, 2], p[3, 0, 2] = 0.6, 0.4  # side 1 at 0.6: half way to white
    p[4, 0, 3] = 1.0  # never a side: black
    rgb = plotting.shaded_sides(p, 4, computed=np.array([[True, True, True, True]]))
    np.testing.assert_allclose(rgb[0, 0], colors[2])
    np.testing.assert_allclose(rgb[0, 1], 1.0)
    np.testing.assert_allclose(rgb[0, 2], 1.0 - 0.5 * (1.0 - colors[1]))
    np.testing.assert_allclose(rgb[0, 3], 0.0)
    grey = plotting.shaded_sides(p, 4, computed=np.array([[False, True, True, True]]))[0, 0]
    np.testing.assert_allclose(grey, plotting.NOT_COMPUTED_COLOR[:3])

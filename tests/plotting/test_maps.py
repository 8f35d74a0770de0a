"""Final-state diagrams and roll pictures: colours, pixel sizes, rendered pixels, GIF frames."""

import subprocess
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.colors import hsv_to_rgb
from PIL import Image

from dice_sweep import config, plotting, storage
from dice_sweep.app.sweep import diagram_title, draw_sweep_file
from dice_sweep.errors import DiceSweepError
from tests.helpers import ROOT, figure_pixels, map_region, near, pixel_at, pixels_around, png_size, read_png

COLOR_TOLERANCE = 1.5 / 255  # PNG stores 8 bits per channel


def table_one_config(sides=4, separation=None):
    """The paper's Table I die with ``sides`` sides, walls ``separation`` m apart or none."""
    walls = "" if separation is None else f"[walls]\nseparation = {separation}\n"
    return config.parse_config(f"[die]\nsides = {sides}\n{walls}")


def fake_report(t_end=0.5, outcome=2, impacts=7):
    return SimpleNamespace(t_end=t_end, outcome=outcome, impacts=impacts)


def falling_path(cfg, report, times):
    """A die falling and spinning onto the table, then resting: (T, 6) states."""
    times = np.asarray(times)
    y = np.maximum(0.15 - 4.905 * times**2, cfg.die.circumradius)
    phi = 12.0 * np.minimum(times, 0.15)
    zeros = np.zeros_like(times)
    return np.column_stack([0.03 * times, y, phi, zeros, zeros, zeros])


def grid_centres(lo, hi, num):
    """Cell centres of the sweep grid convention (docs/dev/architecture.md)."""
    return lo + (np.arange(num) + 0.5) * (hi - lo) / num


# Four uniform 10 x 10 blocks: side 0, side 1 (bottom), side 3, undecided (top).
BLOCK_OUTCOME = np.block(
    [[np.full((10, 10), 0), np.full((10, 10), 1)], [np.full((10, 10), 3), np.full((10, 10), -1)]]
).astype(np.int8)
BLOCK_X = grid_centres(0.0, 60.0, 20)
BLOCK_Y = grid_centres(0.02, 0.30, 20)


def block_figure(box=None, dpi=50):
    return plotting.outcome_figure(
        BLOCK_OUTCOME, BLOCK_X, BLOCK_Y, "omega0 (rad/s)", "y0 (m)", 4, title="blocks", box=box, dpi=dpi
    )


def test_four_sides_are_red_green_cyan_violet():
    colors = plotting.outcome_colors(4)
    np.testing.assert_array_equal(colors[0], (1, 0, 0, 1))
    np.testing.assert_array_equal(colors[1], (0, 0.75, 0, 1))
    np.testing.assert_array_equal(colors[2], (0, 1, 1, 1))
    np.testing.assert_allclose(colors[3], (0.68, 0, 1, 1))


@pytest.mark.parametrize("sides", [3, 5, 20])
def test_rainbow_runs_from_red_to_violet(sides):
    colors = plotting.outcome_colors(sides)
    assert colors.shape == (sides, 4)
    np.testing.assert_array_equal(colors[0], (1, 0, 0, 1))
    np.testing.assert_allclose(colors[-1, :3], hsv_to_rgb((plotting.VIOLET_HUE, 1, 1)))
    assert len({tuple(c) for c in colors}) == sides
    assert tuple(plotting.UNDECIDED_COLOR) == (0, 0, 0, 1)


def test_axis_label_names_parameter_and_unit():
    assert plotting.axis_label("omega0", "rad/s") == "omega0 (rad/s)"


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


def write_sweep_file(path, cfg, outcome, complete, rows=None):
    """A sweep file of ``cfg``'s grid holding ``outcome`` in one tile, through dice_sweep.storage;
    with ``rows``, tiles of that many rows, and only the first tile written."""
    rows = rows or outcome.shape[0]
    outcome = outcome[:rows]
    axes = [
        storage.SweepAxis(
            param=axis.param,
            unit=config.PARAM_UNITS[axis.param],
            values=grid_centres(axis.min, axis.max, axis.num),
            lo=axis.min,
            hi=axis.max,
        )
        for axis in (cfg.grid.x, cfg.grid.y)
    ]
    header = storage.SweepHeader(
        config_toml=config.config_to_toml(cfg),
        sides=cfg.die.sides,
        x=axes[0],
        y=axes[1],
        tile_shape=outcome.shape,  # the first tile
        shard=(0, 1),
        count_columns=("impacts",),
        status_names=("decided",),
    )
    rolls = outcome.size
    maps = storage.rolls_to_maps(
        header.count_columns, outcome.shape, outcome.ravel(), np.zeros(rolls), np.zeros((rolls, 1)), np.zeros(rolls)
    )
    with storage.SweepFile.create(path, header, n_tiles=-(-cfg.grid.y.num // rows)) as sweep_file:
        sweep_file.write_tile(0, slice(0, rows), slice(None), maps)
        if complete:
            sweep_file.mark_complete()
    return path


BLOCK_CONFIG_TOML = """
[die]
sides = 4
[walls]
separation = 0.2
[grid]
x = { param = "omega0", min = 0.0, max = 60.0, num = 20 }
y = { param = "y0", min = 0.02, max = 0.30, num = 20 }
"""


def write_block_sweep(path, complete=True):
    """A sweep file of the four-block map on the grid BLOCK_X x BLOCK_Y."""
    return write_sweep_file(path, config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME, complete)


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


@pytest.mark.parametrize("dpi", [30, 72])
def test_draw_sweep_file_writes_png_of_requested_size(tmp_path, dpi):
    h5 = write_block_sweep(tmp_path / "sweep.h5")
    png = draw_sweep_file(h5, tmp_path / "map.png", box=(10, 20, 0.1, 0.2), dpi=dpi)
    with open(png, "rb") as file:
        assert file.read(8) == b"\x89PNG\r\n\x1a\n"
    assert png_size(png) == figure_pixels(plotting.OUTCOME_FIGSIZE, dpi)
    # the --box rectangle: white (no side's colour) on the map, where the box is: omega0 10 to
    # 20 of 0 to 60, y0 0.1 to 0.2 of 0.02 to 0.30 (rows count down from 0.30)
    block_colours = [*plotting.outcome_colors(4), plotting.UNDECIDED_COLOR]
    region = map_region(read_png(png), block_colours, inset=0)
    rows, columns = np.nonzero(near(region, (1.0, 1.0, 1.0), tol=0.45))  # every channel > 0.55: no block's colour
    assert rows.size > 0, "no rectangle drawn"
    height, width = region.shape[:2]
    reach = 2.5 / width, 2.5 / height  # the frame's line, antialiased
    assert columns.min() / width == pytest.approx(10 / 60, abs=reach[0])
    assert columns.max() / width == pytest.approx(20 / 60, abs=reach[0])
    assert rows.min() / height == pytest.approx((0.30 - 0.2) / 0.28, abs=reach[1])
    assert rows.max() / height == pytest.approx((0.30 - 0.1) / 0.28, abs=reach[1])


def test_cells_not_computed_have_their_own_colour_legend_entry_and_warning(tmp_path):
    """Issue 16: an incomplete sweep was drawn with its cells not computed in the black of
    'undecided', and without a word."""
    half = write_sweep_file(tmp_path / "half.h5", config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME, False, rows=10)
    warnings = []
    png = draw_sweep_file(half, tmp_path / "half.png", dpi=60, warn=warnings.append)
    assert len(warnings) == 1 and warnings[0].startswith(f"{half}: 200 of 400 cells not computed yet")
    sweep_data = storage.read_sweep(half)
    fig = plotting.sweep_figure(sweep_data, diagram_title(sweep_data), dpi=60)
    fig.savefig(png, dpi=60)
    for x, y, expected in [(15.0, 0.09, plotting.outcome_colors(4)[0]), (45.0, 0.09, plotting.outcome_colors(4)[1]),
                           (15.0, 0.23, plotting.NOT_COMPUTED_COLOR), (45.0, 0.23, plotting.NOT_COMPUTED_COLOR)]:
        np.testing.assert_allclose(pixel_at(fig, x, y, png), expected, atol=COLOR_TOLERANCE)
    labels = [label.get_text() for label in fig.axes[1].get_yticklabels()]
    assert labels == ["not computed", "undecided", "side 0", "side 1", "side 2", "side 3"]
    assert fig.axes[0].get_title().endswith("(incomplete)")
    whole = write_block_sweep(tmp_path / "whole.h5")
    draw_sweep_file(whole, tmp_path / "whole.png", dpi=30, warn=warnings.append)
    assert len(warnings) == 1  # nothing to say about a complete sweep


@pytest.mark.parametrize("dpi", [0, 9, 1001, 100000])
def test_dpi_outside_its_range_is_refused_before_drawing(tmp_path, dpi):
    """Issue 16: --dpi 100000 ended in a MemoryError traceback."""
    with pytest.raises(DiceSweepError, match=r"--dpi: .* allowed range \[10, 1000\]"):
        draw_sweep_file(write_block_sweep(tmp_path / "sweep.h5"), tmp_path / "map.png", dpi=dpi)
    assert not (tmp_path / "map.png").exists()


def test_image_formats_are_those_of_the_agg_canvas():
    formats = plotting.image_formats()
    assert {".png", ".pdf", ".svg", ".jpg"} <= set(formats) and ".h5" not in formats and ".xyz" not in formats


def test_plot_roll_draws_die_with_side_zero_in_red(tmp_path):
    png = plotting.plot_roll(
        table_one_config(separation=0.2), fake_report(), tmp_path / "roll.png", frames=6, dpi=60,
        path_sampler=falling_path,
    )
    image = read_png(png)
    assert png_size(png) == figure_pixels(plotting.ROLL_FIGSIZE, 60)
    red = (image[..., 0] > 0.9) & (image[..., 1] < 0.2) & (image[..., 2] < 0.2)
    assert red.sum() > 20


@pytest.mark.parametrize("radius", [0.0, 0.004])
def test_roll_draws_the_rounded_outline_and_the_sharp_one_unchanged(tmp_path, radius):
    from matplotlib.figure import Figure

    from dice_sweep.geometry import corners
    from dice_sweep.plotting.roll import _add_die

    cfg = config.parse_config(f"[effects]\ncorner_radius = {radius}")
    state = (0.01, 0.05, 0.3)
    shape, side0 = _add_die(Figure().add_subplot(), cfg, state)
    xy = shape.get_xy()[:-1]  # the patch repeats its first point to close the path
    side = np.column_stack(side0.get_data())
    R = cfg.die.circumradius
    if radius == 0.0:
        np.testing.assert_array_equal(xy, corners(4, R, *state))
        np.testing.assert_array_equal(side, xy[:2])
    else:
        # arcs about the core's corners, sqrt(2) (a - r) from the centre: side 0's straight part
        # is the core's side, 2 (a - r) long, at the apothem a = R / sqrt(2)
        core = np.sqrt(2.0) * (R / np.sqrt(2.0) - radius)
        assert len(xy) > 4 * 2 and np.hypot(xy[:, 0] - 0.01, xy[:, 1] - 0.05).max() <= R
        assert np.linalg.norm(side[1] - side[0]) == pytest.approx(np.sqrt(2.0) * core, rel=1e-12)
        normal = [np.cos(0.3 + np.pi / 4), np.sin(0.3 + np.pi / 4)]
        np.testing.assert_allclose((side - [0.01, 0.05]) @ normal, R / np.sqrt(2.0), rtol=1e-12)
    plotting.plot_roll(cfg, fake_report(), tmp_path / "roll.png", frames=3, dpi=40, path_sampler=falling_path)


@pytest.mark.parametrize(
    "t_end, fps, max_frames, frames",
    [(0.5, 20, 300, 11), (0.51, 20, 300, 12), (2.0, 30, 7, 7)],
)
def test_gif_has_one_frame_per_tick_of_simulated_time(tmp_path, t_end, fps, max_frames, frames):
    gif = plotting.animate_roll(
        table_one_config(), fake_report(t_end=t_end), tmp_path / "roll.gif", fps=fps, max_frames=max_frames,
        path_sampler=falling_path,
    )
    with Image.open(gif) as image:
        assert image.n_frames == frames


def test_plotting_never_imports_pyplot(tmp_path):
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        from tests.test_plotting import table_one_config, fake_report, falling_path, write_block_sweep
        from dice_sweep import plotting
        tmp = {str(tmp_path)!r}
        from dice_sweep.app.sweep import draw_sweep_file
        draw_sweep_file(write_block_sweep(tmp + "/sweep.h5"), tmp + "/map.png", dpi=20)
        plotting.plot_roll(table_one_config(), fake_report(), tmp + "/roll.png", path_sampler=falling_path)
        plotting.animate_roll(table_one_config(), fake_report(t_end=0.1), tmp + "/roll.gif",
                              path_sampler=falling_path)
        print("matplotlib.pyplot" in sys.modules)
        """
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False"

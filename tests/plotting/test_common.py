"""Tests of dice_sweep.plotting.common: the paper's colours, labels, sizes and formats, the
--dpi check, cell edges, panels and scalar maps; and that plotting never imports pyplot."""

import subprocess
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.colors import hsv_to_rgb

from dice_sweep import plotting
from dice_sweep.errors import DiceSweepError
from tests.helpers import ROOT


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


def test_image_formats_are_those_of_the_agg_canvas():
    formats = plotting.image_formats()
    assert {".png", ".pdf", ".svg", ".jpg"} <= set(formats) and ".h5" not in formats and ".xyz" not in formats


def test_plotting_never_imports_pyplot(tmp_path):
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        from tests.plotting.drawn import table_one_config, fake_report, falling_path, write_block_sweep
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



@pytest.mark.parametrize("dpi", [10, 150, 1000])
def test_dpi_in_range_is_returned(dpi):
    assert plotting.check_dpi(dpi) == dpi


def test_dpi_out_of_range_names_the_option_and_the_largest_picture():
    with pytest.raises(DiceSweepError) as error:
        plotting.check_dpi(1001, option="--png-dpi")
    assert str(error.value) == ("--png-dpi: 1001 is outside the allowed range [10, 1000] "
                                "(a 7 x 5 inch figure: at most 7000 x 5000 pixels)")


def test_cell_extent_is_half_a_cell_beyond_the_outer_centres():
    assert plotting.cell_extent([1.0, 3.0, 5.0]) == (0.0, 6.0)
    assert plotting.cell_extent(np.array([0.25, 0.75])) == (0.0, 1.0)
    assert plotting.cell_extent([7.0]) == (6.5, 7.5)  # one cell: width 1 in the axis unit


def test_axis_labels_of_a_sweep_name_parameter_and_unit():
    sweep = SimpleNamespace(x=SimpleNamespace(param="omega0", unit="rad/s"), y=SimpleNamespace(param="y0", unit="m"))
    assert plotting.axis_labels(sweep) == ("omega0 (rad/s)", "y0 (m)")


def test_panel_figure_is_a_row_of_panels_of_the_given_size():
    fig, axes = plotting.panel_figure(3, 50)
    assert len(axes) == 3 and len(fig.axes) == 3
    assert tuple(fig.get_size_inches()) == (3 * plotting.PANEL_FIGSIZE[0], plotting.PANEL_FIGSIZE[1])
    lefts = [ax.get_position().x0 for ax in axes]
    assert lefts == sorted(lefts)  # left to right
    fig, axes = plotting.panel_figure(2, 50, (4, 3))
    assert tuple(fig.get_size_inches()) == (8, 3)


def test_scalar_map_spans_the_cells_with_its_colour_range_and_labels():
    fig, (ax,) = plotting.panel_figure(1, 50)
    values = np.arange(6.0).reshape(2, 3)
    image = plotting.draw_scalar_map(ax, values, [0.5, 1.5, 2.5], [10.0, 20.0], "a (m)", "b (s)", title="t",
                                     label="nats", vmin=0.0, vmax=10.0, cmap="magma")
    np.testing.assert_allclose(image.get_extent(), (0.0, 3.0, 5.0, 25.0))
    assert image.origin == "lower" and image.get_clim() == (0.0, 10.0) and image.get_cmap().name == "magma"
    np.testing.assert_array_equal(image.get_array(), values)
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_title()) == ("a (m)", "b (s)", "t")
    assert fig.axes[1].get_ylabel() == "nats"  # the colour bar's label

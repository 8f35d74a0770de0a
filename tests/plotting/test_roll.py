"""Tests of dice_sweep.plotting.roll: a roll's picture (the die's outline along its path, side 0
in red) and its animation (one frame per tick of simulated time)."""

import numpy as np
import pytest
from PIL import Image

from dice_sweep import config, plotting
from tests.helpers import figure_pixels, near, png_size, read_png
from tests.plotting.drawn import fake_report, falling_path, table_one_config


def test_plot_roll_draws_die_with_side_zero_in_red(tmp_path):
    png = plotting.plot_roll(
        table_one_config(separation=0.2), fake_report(), tmp_path / "roll.png", frames=6, dpi=60,
        path_sampler=falling_path,
    )
    image = read_png(png)
    assert png_size(png) == figure_pixels(plotting.ROLL_FIGSIZE, 60)
    red = (image[..., 0] > 0.9) & (image[..., 1] < 0.2) & (image[..., 2] < 0.2)
    assert red.sum() > 20


def side_zero_length(png):
    """Length in pixels of the red (side 0) line in a picture: its extent along its direction."""
    image = read_png(png)
    rows, columns = np.nonzero(near(image, (1.0, 0.0, 0.0), tol=0.1))
    points = np.column_stack([columns, rows]).astype(float)
    points -= points.mean(axis=0)
    direction = np.linalg.svd(points, full_matrices=False)[2][0]
    along = points @ direction
    return along.max() - along.min()


def test_rounded_corners_shorten_side_zero_to_the_cores_side(tmp_path):
    """Side 0's straight part of a die with corner radius r is the core's side, 2 (a - r) of
    2 a: in two pictures of one scale (the same path, the same circumradius) its red line is
    that much shorter; a picture ignoring the radius, or rounding a sharp die, draws them alike."""
    def at_rest(cfg, report, times):
        return np.tile([0.0, 0.02, 0.3, 0.0, 0.0, 0.0], (len(times), 1))

    lengths = {}
    for radius in (0.0, 0.004):
        cfg = config.parse_config(f"[effects]\ncorner_radius = {radius}")
        png = plotting.plot_roll(cfg, fake_report(), tmp_path / f"roll_{radius}.png", at_rest, frames=1, dpi=200)
        lengths[radius] = side_zero_length(png)
    apothem = cfg.die.circumradius / np.sqrt(2.0)
    assert lengths[0.0] > 150  # pixels: a scale fine enough for the ratio below
    assert lengths[0.004] / lengths[0.0] == pytest.approx((apothem - 0.004) / apothem, rel=0.04)


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

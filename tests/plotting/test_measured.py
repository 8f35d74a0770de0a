"""Tests of dice_sweep.plotting.measured: the pose error against time of fits and the histograms
of calibrate's coefficients, drawn from numbers given to it (the numbers: tests/measured/; the
commands: tests/app/test_measured.py)."""

from types import SimpleNamespace

import numpy as np
from matplotlib.colors import to_rgb

from dice_sweep import plotting
from tests.helpers import figure_pixels, near, png_size, read_png


def test_residual_curves_rise_where_the_error_rises(tmp_path):
    times = np.linspace(-0.02, 0.1, 600)
    errors = np.where(times < 0, 1e-4, 1e-4 + 0.02 * times)  # mm-sized, growing after the first impact
    png = plotting.plot_residual_curves([("fit", times, errors), ("flat", times, np.full_like(times, 1e-4))],
                                        tmp_path / "r.png", dpi=50)
    assert png_size(png) == figure_pixels((7, 4), 50)
    image = read_png(png)
    for colour, grows in ((to_rgb("C0"), True), (to_rgb("C1"), False)):
        rows, columns = np.nonzero(near(image, colour, tol=0.1))
        assert rows.size > 20
        right = columns > np.percentile(columns, 75)
        left = columns < np.percentile(columns, 25)
        assert (np.median(rows[left]) - np.median(rows[right]) > 20) == grows  # rows count down


def calibration(values_by_name):
    coefficients = {name: f"meaning of {name}" for name in values_by_name}
    return SimpleNamespace(coefficients=coefficients, path="/data/drops.csv",
                           values=lambda name, group: np.asarray(values_by_name[name][group], float))


def test_calibration_has_a_panel_per_coefficient_filled_with_the_first_impacts(tmp_path):
    rng = np.random.default_rng(0)
    every = rng.normal(0.5, 0.1, 400)
    result = calibration({"beta_normal": {"all": every, "first": every[:100]},
                          "beta_tangential": {"all": every - 1, "first": every[:100] - 1},
                          "corner_normal": {"all": every, "first": every[:100]},
                          "corner_tangential": {"all": [], "first": []}})  # no clean impact
    png = plotting.plot_calibration(result, tmp_path / "c.png", dpi=40)
    assert png_size(png) == figure_pixels(plotting.CALIBRATION_FIGSIZE, 40)
    image = read_png(png)
    height, width = image.shape[:2]
    blue = near(image, 0.6 * np.array(to_rgb("tab:blue")) + 0.4, tol=0.08)  # tab:blue at alpha 0.6 on white
    quadrants = [blue[: height // 2, : width // 2], blue[: height // 2, width // 2 :],
                 blue[height // 2 :, : width // 2], blue[height // 2 :, width // 2 :]]
    assert [q.sum() > 100 for q in quadrants] == [True, True, True, False]
